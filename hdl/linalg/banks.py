"""The engine's operand memory: ``banks`` dual-port RAMs behind a crossbar of read and write
lanes."""

from __future__ import annotations

from amaranth.hdl import Array, Cat, Module, Mux, Signal, unsigned
from amaranth.lib import data, memory, wiring
from amaranth.lib.wiring import In, Out

__all__ = ["addr_layout", "ReadLane", "WriteLane", "BankedMemory"]


def addr_layout(geometry) -> data.StructLayout:
    """A word's place: ``a = bank + banks * row``."""
    return data.StructLayout({"bank": unsigned(geometry.bank_bits),
                              "row": unsigned(geometry.row_bits)})


class ReadLane(wiring.Signature):
    """A reader's lane: ``en`` and ``addr`` in one cycle, ``data`` the next (read latency 1)."""

    def __init__(self, geometry, width):
        super().__init__({"en": Out(1), "addr": Out(addr_layout(geometry)), "data": In(width)})


class WriteLane(wiring.Signature):
    """A writer's lane: the word is written at the end of the cycle ``en`` is high."""

    def __init__(self, geometry, width):
        super().__init__({"en": Out(1), "addr": Out(addr_layout(geometry)), "data": Out(width)})


def _first(hits, values, default=0):
    """The value of the first lane whose hit is set (priority to the lowest index)."""
    v = default
    for h, x in reversed(list(zip(hits, values))):
        v = Mux(h, x, v)
    return v


def _signals(m, name, exprs):
    """One signal per expression (so that each is built once, however often it is used)."""
    sigs = [Signal(name=f"{name}{i}") for i in range(len(exprs))]
    m.d.comb += [s.eq(e) for s, e in zip(sigs, exprs)]
    return sigs


def _prefix_or(m, bank, hits):
    """For each lane, whether a lane before it hits."""
    out = [Signal(name=f"b{bank}_prior{i}") for i in range(len(hits))]
    for i, o in enumerate(out):
        m.d.comb += o.eq(0 if i == 0 else out[i - 1] | hits[i - 1])
    return out


class BankedMemory(wiring.Component):
    """Word ``a`` in bank ``a % banks`` at row ``a // banks``; each bank a RAM of two ports a
    cycle, each port one read or one write (a true dual-port block RAM: a port's read and write
    share its address).

    The crossbar gives a bank's port 0 to the first lane (in the order reads, then writes,
    the last read and the last write lane lowest of all: the bus) that addresses it, and
    port 1 to the next lane that is not a read of the word port 0 reads (reads of one word
    share a port). The scheduler never asks more of a bank than its two ports; lanes beyond
    them get nothing (a read returns another port's word, a write is lost).

    A read and a write of one word in one cycle (on the two ports of its bank) read an
    undefined word, and the RAM says so to synthesis (``no_rw_check``): Xilinx's block RAM
    returns the old word across ports, but Lattice ECP5's (DP16KD) does not, and a RAM that
    promised it would be built from flip-flops there. No lane ever takes such a word: the
    scheduler writes a word only after its last read and reads it from the cycle after the
    write on, and the bus's read in such a cycle is not served (``rd_ok`` low; it retries,
    and reads the new word). Simulators return the old word there.

    Parameters
    ----------
    geometry : microcode.Geometry
    width : int
        Word width.
    init : list of int
        The memory's words at configuration (``geometry.size`` of them).
    reads, writes : int
        Lanes; the last of each is the lowest priority.
    groups : list of int or None
        Per write lane, its data source: lanes of one group always carry the same word (a
        unit's result and its mirror), so a port muxes groups, not lanes. ``None``: a group
        per lane.

    Members
    -------
    rd : In(ReadLane).array(reads)
        Read latency 1: the word addressed in one cycle is on ``data`` the next.
    wr : In(WriteLane).array(writes)
    rd_ok : Out(1)
        The last read lane (the bus's, lowest priority) is served this cycle: a port is free
        for it or already reads its word, and no lane writes its word. When it is not, its
        ``data`` next cycle is some other word, and the reader retries.
    """

    def __init__(self, geometry, width, init, reads, writes, groups=None):
        self._g, self._width, self._init = geometry, width, list(init)
        self._groups = list(range(writes)) if groups is None else list(groups)
        if len(self._groups) != writes:
            raise ValueError(f"groups must name one group per write lane ({writes}), not {groups!r}")
        super().__init__({"rd": In(ReadLane(geometry, width)).array(reads),
                          "wr": In(WriteLane(geometry, width)).array(writes),
                          "rd_ok": Out(1)})

    def elaborate(self, platform):
        m = Module()
        g = self._g
        rd, wr = list(self.rd), list(self.wr)
        # (lane, is_write) by priority, the bus lanes last
        order = [(r, False) for r in rd[:-1]] + [(w, True) for w in wr[:-1]] + \
            [(rd[-1], False), (wr[-1], True)]
        read_index = [i for i in range(len(rd) - 1)] + [None] * (len(wr) - 1) + [len(rd) - 1, None]
        port_data = []
        selects = [(Signal(g.bank_bits, name=f"rd{i}_bank"), Signal(name=f"rd{i}_port"))
                   for i in range(len(rd))]
        rows = [lane.addr.row for lane, _ in order]
        is_write = [int(w) for _, w in order]
        # each write lane's group (its data source), in ``order``
        wgroup = iter(self._groups[:-1])
        order_group = [None if not w else (self._groups[-1] if lane is wr[-1] else next(wgroup))
                       for lane, w in order]
        group_data = {}
        for (lane, w), grp in zip(order, order_group):
            if w:
                group_data.setdefault(grp, lane.data)
        bus_read = len(rd) - 1 + len(wr) - 1  # the bus's read lane, in ``order``
        served = []
        for b in range(g.banks):
            words = self._init[b::g.banks]
            # no_rw_check: a read and a write of one word in a cycle read an undefined word
            # (a true dual-port block RAM on either vendor; see the class docstring)
            mem = memory.Memory(shape=unsigned(self._width), depth=g.rows,
                                init=words + [0] * (g.rows - len(words)), attrs={"no_rw_check": 1})
            m.submodules[f"bank{b}"] = mem
            hits = _signals(m, f"b{b}_hit", [lane.en & (lane.addr.bank == b) for lane, _ in order])
            ports = []  # (hit, row, write, grants) of port 0, then port 1
            for port in range(2):
                hit = Signal(name=f"b{b}_p{port}")
                row = Signal(g.row_bits, name=f"b{b}_p{port}_row")
                write = Signal(name=f"b{b}_p{port}_write")
                m.d.comb += [hit.eq(_first(hits, [1] * len(hits))),
                             row.eq(_first(hits, rows)), write.eq(_first(hits, is_write))]
                ports.append((hit, row, write, hits))
                if port == 0:
                    # port 0 serves its own lane and every read of the word it reads
                    shared = _signals(m, f"b{b}_shared", [
                        h & ~write & (r == row) if not w else h & ~prior
                        for h, r, w, prior in zip(hits, rows, is_write, _prefix_or(m, b, hits))])
                    hits = _signals(m, f"b{b}_hit1", [h & ~s for h, s in zip(hits, shared)])
            datas = []
            for port, (hit, row, write, hs) in enumerate(ports):
                rp = mem.read_port()
                wp = mem.write_port()
                # the port's write lane (if its first hit is a write), then its group's word
                prior = _prefix_or(m, f"{b}_w{port}", hs)
                if port == 1:  # the bus read: served by port 0 (its word) or port 1, or not at all
                    k = bus_read
                    served.append(shared[k] | (hs[k] & ~prior[k]))
                sel = {}
                for h, pr, grp in zip(hs, prior, order_group):
                    if grp is not None:
                        sel[grp] = sel.get(grp, 0) | (h & ~pr)
                wdata = 0
                for grp, sg in sel.items():
                    wdata = wdata | Mux(sg, group_data[grp], 0)
                m.d.comb += [
                    rp.addr.eq(row), wp.addr.eq(row),
                    wp.en.eq(hit & write),
                    wp.data.eq(wdata),
                ]
                datas.append(rp.data)
            port_data.append(Array(datas))
            for (lane, w), s, i, h in zip(order, shared, read_index, ports[0][3]):
                if not w:
                    with m.If(h):
                        m.d.sync += selects[i][1].eq(~s)
        bus = rd[-1].addr.as_value()
        written = Cat(w.en & (w.addr.as_value() == bus) for w in wr).any()  # undefined: retry
        m.d.comb += self.rd_ok.eq(Cat(served).any() & ~written)
        # every index covered: Verilator -Wall wants complete cases
        port_data = Array(port_data + port_data[-1:] * ((1 << g.bank_bits) - g.banks))
        for lane, (bank, port) in zip(rd, selects):
            m.d.sync += bank.eq(lane.addr.bank)
            m.d.comb += lane.data.eq(port_data[bank][port])
        return m
