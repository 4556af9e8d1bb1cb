"""The engine's operand memory: ``banks`` dual-port RAMs behind a crossbar of read and write
lanes."""

from __future__ import annotations

from types import SimpleNamespace

from amaranth.hdl import Array, C, Cat, Module, Mux, Signal, unsigned
from amaranth.lib import data, memory, wiring
from amaranth.lib.wiring import In, Out

__all__ = ["addr_layout", "ReadLane", "WriteLane", "BankedMemory", "BUS_READ_LATENCY"]

#: Cycles from the bus's read request to its word on ``data``: the block RAM, then the port's
#: register behind it (the engine's lanes read through the same registers).
BUS_READ_LATENCY = 2


def addr_layout(geometry) -> data.StructLayout:
    """A word's place: ``a = bank + banks * row``."""
    return data.StructLayout({"bank": unsigned(geometry.bank_bits),
                              "row": unsigned(geometry.row_bits)})


class ReadLane(wiring.Signature):
    """A reader's lane: ``en``, ``addr`` and the memory ``port`` it uses in one cycle,
    ``data`` a read latency later (:class:`BankedMemory`)."""

    def __init__(self, geometry, width):
        super().__init__({"en": Out(1), "addr": Out(addr_layout(geometry)), "port": Out(1),
                          "data": In(width)})


class WriteLane(wiring.Signature):
    """A writer's lane: ``en``, ``addr``, the memory ``port`` and ``data`` in one cycle
    (:class:`BankedMemory` says when the RAM takes it)."""

    def __init__(self, geometry, width):
        super().__init__({"en": Out(1), "addr": Out(addr_layout(geometry)), "port": Out(1),
                          "data": Out(width)})


def _any(bits):
    return Cat(*bits).any() if bits else C(0, 1)


class BankedMemory(wiring.Component):
    """Word ``a`` in bank ``a % banks`` at row ``a // banks``; each bank a RAM of two ports
    a cycle, each port one read or one write (a true dual-port block RAM: a port's read and
    write share its address).

    **The engine's lanes** (every lane but the last read and the last write) name their
    port: the scheduler assigned it (:mod:`.schedule`), so that no port is asked for two
    things in a cycle, except reads of one word. The crossbar therefore has no arbitration:
    a port's address is the OR of the addresses of the lanes that name it. It is pipelined:
    a lane's request (``en``, ``addr``, ``port``, a write's ``data``) is registered, the
    block RAM is read or written the next cycle, and each port's word is registered right
    behind the RAM; a read lane's ``data`` is its port's register, selected by a
    multiplexer, :data:`~.microcode.LANE_READ_LATENCY` (3) cycles after the request (a
    combinational output: the lane's reader registers it, or computes from it, in that
    cycle). A write reaches the RAM one cycle after its request.

    **The bus's lanes** (the last read and the last write) take a port that the engine's
    lanes leave free in the RAM cycle: the write port 0, the read port 1, else port 0. The
    bus's write is registered as the engine's lanes are (it reaches the RAM the next
    cycle); a bus write whose port is taken then is lost (the bus front end refuses writes
    while a step runs). The bus's read skips the request register: it reaches the RAM in the
    cycle of the request, and its word, from its port's register, is on ``data`` two cycles
    later (:data:`BUS_READ_LATENCY`) when ``rd_ok`` was high with the request.

    A read and a write of one word in one cycle (on the two ports of its bank) read an
    undefined word, and the RAM says so to synthesis (``no_rw_check``): Xilinx's block RAM
    returns the old word across ports, but Lattice ECP5's (DP16KD) does not, and a RAM that
    promised it would be built from flip-flops there. No lane ever takes such a word: the
    scheduler writes a word only after its last read and reads it from the cycle after the
    write on, and the bus's read is not served in a RAM cycle in which an engine lane writes
    its bank (a bank, not the word: a registered bit a bank keeps that decision short) or
    the bus's write its word (``rd_ok`` low; it retries, and reads the new word). Simulators
    return the old word there.

    Parameters
    ----------
    geometry : microcode.Geometry
    width : int
        Word width.
    init : list of int
        The memory's words at configuration (``geometry.size`` of them).
    reads, writes : int
        Lanes; the last of each is the bus's.
    groups : list of int or None
        Per write lane, its data source: lanes of one group always carry the same word (a
        unit's result and its mirror), so the word is registered once and a port muxes
        groups, not lanes. ``None``: a group per lane.

    Members
    -------
    rd : In(ReadLane).array(reads)
    wr : In(WriteLane).array(writes)
    rd_ok : Out(1)
        The bus's read is served this cycle: a port of its bank is free of the engine's
        lanes (and of the bus's write), no engine lane writes that bank and the bus's write
        does not write the word in this RAM cycle. When
        it is not, its ``data`` next cycle is some other word, and the reader retries.
    flush : In(1)
        The engine's writes asked for in this cycle and in the one before are dropped (a
        soft reset registered on its way to the units: nothing more is written).
    """

    def __init__(self, geometry, width, init, reads, writes, groups=None):
        self._g, self._width, self._init = geometry, width, list(init)
        self._groups = list(range(writes)) if groups is None else list(groups)
        if len(self._groups) != writes:
            raise ValueError(f"groups must name one group per write lane ({writes}), not {groups!r}")
        super().__init__({"rd": In(ReadLane(geometry, width)).array(reads),
                          "wr": In(WriteLane(geometry, width)).array(writes),
                          "rd_ok": Out(1), "flush": In(1)})

    def elaborate(self, platform):
        m = Module()
        g, banks = self._g, self._g.banks
        rd, wr = list(self.rd), list(self.wr)
        bus_rd, bus_wr = rd[-1], wr[-1]

        def register(lane, name, write):
            """The lane's request, registered: ``hit[bank][port]``, the row, and a read's
            bank and port (for its data)."""
            en = lane.en & ~self.flush
            r = SimpleNamespace(row=Signal(g.row_bits, name=f"{name}_row"),
                                hit=[[Signal(name=f"{name}_b{b}p{p}") for p in range(2)]
                                     for b in range(banks)])
            m.d.sync += r.row.eq(lane.addr.row)
            if not write:
                r.bank, r.port = Signal(g.bank_bits, name=f"{name}_bank"), Signal(name=f"{name}_port")
                m.d.sync += [r.bank.eq(lane.addr.bank), r.port.eq(lane.port)]
            for b in range(banks):
                for p in range(2):
                    m.d.sync += r.hit[b][p].eq(en & (lane.addr.bank == b) & (lane.port == p))
            return r

        reads = [register(lane, f"rd{i}", False) for i, lane in enumerate(rd[:-1])]
        writes = [register(lane, f"wr{i}", True) for i, lane in enumerate(wr[:-1])]
        # a group's word, registered once
        group_data = {}
        for lane, grp in zip(wr[:-1], self._groups[:-1]):
            if grp not in group_data:
                group_data[grp] = Signal(self._width, name=f"group{grp}_data")
                m.d.sync += group_data[grp].eq(lane.data)

        # the bus: a port the engine leaves free, the write port 0, the read port 1 or 0; its
        # write registered
        bus_wr_lane = bus_wr
        bus_wr = SimpleNamespace(en=Signal(name="bus_wr_en"),
                                 addr=Signal.like(bus_wr_lane.addr, name="bus_wr_addr"),
                                 data=Signal(self._width, name="bus_wr_data"))
        m.d.sync += [bus_wr.en.eq(bus_wr_lane.en), bus_wr.addr.eq(bus_wr_lane.addr),
                     bus_wr.data.eq(bus_wr_lane.data)]
        # the ports the engine's lanes take in the RAM cycle, and the banks its lanes write,
        # registered as one bit each (not an OR of every lane's registered hit): the bus
        # read's rd_ok, and the AXI front end's issue behind it, follow, so the bus's address
        # only selects a bank's bit
        def per_bank(lanes, port=None):
            return [_any([lane.en & ~self.flush & (lane.addr.bank == b)
                          & (1 if port is None else lane.port == port) for lane in lanes])
                    for b in range(banks)]

        taken = [[Signal(name=f"taken_b{b}p{p}") for p in range(2)] for b in range(banks)]
        engine_writes = [Signal(name=f"written_b{b}") for b in range(banks)]
        for p in range(2):
            m.d.sync += [taken[b][p].eq(v) for b, v in enumerate(per_bank(rd[:-1] + wr[:-1], p))]
        m.d.sync += [w.eq(v) for w, v in zip(engine_writes, per_bank(wr[:-1]))]
        bus_w = [bus_wr.en & (bus_wr.addr.bank == b) & ~taken[b][0] for b in range(banks)]
        bus_r = [[None, None] for _ in range(banks)]
        readable = []  # a bank the bus may read in this RAM cycle: a port free, nothing written
        for b in range(banks):
            want = bus_rd.en & (bus_rd.addr.bank == b)
            bus_r[b][1] = want & ~taken[b][1]
            bus_r[b][0] = want & taken[b][1] & ~taken[b][0] & ~bus_w[b]
            readable.append((~taken[b][1] | (~taken[b][0] & ~bus_w[b])) & ~engine_writes[b])
        readable = Array(readable + readable[-1:] * ((1 << g.bank_bits) - banks))
        m.d.comb += self.rd_ok.eq(bus_rd.en & readable[bus_rd.addr.bank] &
                                  ~(bus_wr.en & (bus_wr.addr.as_value() == bus_rd.addr.as_value())))

        port_data = []
        for b in range(banks):
            words = self._init[b::banks]
            # no_rw_check: a read and a write of one word in a cycle read an undefined word
            # (a true dual-port block RAM on either vendor; see the class docstring)
            mem = memory.Memory(shape=unsigned(self._width), depth=g.rows,
                                init=words + [0] * (g.rows - len(words)), attrs={"no_rw_check": 1})
            m.submodules[f"bank{b}"] = mem
            datas = []
            for p in range(2):
                rp, wp = mem.read_port(), mem.write_port()
                row = 0
                for r in reads + writes:
                    row = row | Mux(r.hit[b][p], r.row, 0)
                if p == 0:
                    row = row | Mux(bus_w[b], bus_wr.addr.row, 0)
                row = row | Mux(bus_r[b][p], bus_rd.addr.row, 0)
                wdata = 0
                for grp, word in group_data.items():
                    sel = _any([w.hit[b][p] for w, lg in zip(writes, self._groups[:-1]) if lg == grp])
                    wdata = wdata | Mux(sel, word, 0)
                we = _any([w.hit[b][p] for w in writes]) & ~self.flush
                if p == 0:
                    wdata = wdata | Mux(bus_w[b], bus_wr.data, 0)
                    we = we | bus_w[b]
                m.d.comb += [rp.addr.eq(row), wp.addr.eq(row), wp.en.eq(we), wp.data.eq(wdata)]
                datas.append(rp.data)
            port_data.append(Array(datas))
        # the engine's reads: each port's word registered right behind its RAM (a block RAM's
        # clock-to-output is most of a cycle: nothing may follow it but a wire to a register),
        # then the lane's port selected from those registers by its (bank, port), which follow
        # the request
        held = [Array(Signal(self._width, name=f"bank{b}_p{p}_word") for p in range(2)) for b in range(banks)]
        for b in range(banks):
            m.d.sync += [held[b][p].eq(port_data[b][p]) for p in range(2)]
        pad = (1 << g.bank_bits) - banks  # every index covered: Verilator -Wall wants complete cases
        held = Array(held + held[-1:] * pad)
        for lane, r in zip(rd[:-1], reads):
            sel_bank, sel_port = Signal.like(r.bank), Signal.like(r.port)
            sel_bank2, sel_port2 = Signal.like(r.bank), Signal.like(r.port)
            m.d.sync += [sel_bank.eq(r.bank), sel_port.eq(r.port), sel_bank2.eq(sel_bank),
                         sel_port2.eq(sel_port)]
            m.d.comb += lane.data.eq(held[sel_bank2][sel_port2])
        # the bus's read: from its port's register, like the lanes' (latency 2)
        sel_bank, sel_port = Signal(g.bank_bits), Signal()
        sel_bank2, sel_port2 = Signal.like(sel_bank), Signal.like(sel_port)
        m.d.sync += [sel_bank.eq(bus_rd.addr.bank),
                     sel_port.eq(~_any([bus_r[b][0] for b in range(banks)])),
                     sel_bank2.eq(sel_bank), sel_port2.eq(sel_port)]
        m.d.comb += bus_rd.data.eq(held[sel_bank2][sel_port2])
        return m
