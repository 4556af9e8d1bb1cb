"""The engine's operand memory: ``banks`` dual-port RAMs behind a crossbar of read and write
lanes."""

from __future__ import annotations

from amaranth.hdl import Array, Module, Mux, Signal, unsigned
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


class BankedMemory(wiring.Component):
    """Word ``a`` in bank ``a % banks`` at row ``a // banks``; each bank a RAM of two ports a
    cycle, each port one read or one write (a true dual-port block RAM: a port's read and write
    share its address).

    The crossbar gives a bank's port 0 to the first lane (in the order reads, then writes,
    the last read and the last write lane lowest of all: the bus) that addresses it, and
    port 1 to the next lane that is not a read of the word port 0 reads (reads of one word
    share a port). The scheduler never asks more of a bank than its two ports; lanes beyond
    them get nothing (a read returns another port's word, a write is lost).

    Parameters
    ----------
    geometry : microcode.Geometry
    width : int
        Word width.
    init : list of int
        The memory's words at configuration (``geometry.size`` of them).
    reads, writes : int
        Lanes; the last of each is the lowest priority.

    Members
    -------
    rd : In(ReadLane).array(reads)
        Read latency 1: the word addressed in one cycle is on ``data`` the next. A read and a
        write of the same word in one cycle read the old word.
    wr : In(WriteLane).array(writes)
    """

    def __init__(self, geometry, width, init, reads, writes):
        self._g, self._width, self._init = geometry, width, list(init)
        super().__init__({"rd": In(ReadLane(geometry, width)).array(reads),
                          "wr": In(WriteLane(geometry, width)).array(writes)})

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
        for b in range(g.banks):
            words = self._init[b::g.banks]
            mem = memory.Memory(shape=unsigned(self._width), depth=g.rows,
                                init=words + [0] * (g.rows - len(words)))
            m.submodules[f"bank{b}"] = mem
            hits = [lane.en & (lane.addr.bank == b) for lane, _ in order]
            p0_hit = Signal(name=f"b{b}_p0")
            p0_row = Signal(g.row_bits, name=f"b{b}_p0_row")
            p0_write = Signal(name=f"b{b}_p0_write")
            m.d.comb += [
                p0_hit.eq(_first(hits, [1] * len(hits))),
                p0_row.eq(_first(hits, [lane.addr.row for lane, _ in order])),
                p0_write.eq(_first(hits, [int(w) for _, w in order])),
            ]
            shared = []  # served by port 0
            for (lane, w), hit, k in zip(order, hits, range(len(order))):
                if w:
                    first = hit
                    for h in hits[:k]:
                        first = first & ~h
                    shared.append(first)
                else:
                    shared.append(hit & ~p0_write & (lane.addr.row == p0_row))
            hits1 = [h & ~s for h, s in zip(hits, shared)]
            p1_hit = Signal(name=f"b{b}_p1")
            m.d.comb += p1_hit.eq(_first(hits1, [1] * len(hits1)))
            datas = []
            for port, (hit, hs) in enumerate(((p0_hit, hits), (p1_hit, hits1))):
                rp = mem.read_port()
                wp = mem.write_port()
                row = p0_row if port == 0 else _first(hs, [lane.addr.row for lane, _ in order])
                write = p0_write if port == 0 else _first(hs, [int(w) for _, w in order])
                m.d.comb += [
                    rp.addr.eq(row), wp.addr.eq(row),
                    wp.en.eq(hit & write),
                    wp.data.eq(_first([h & w for h, (_, w) in zip(hs, order)],
                                      [lane.data if w else 0 for lane, w in order])),
                ]
                datas.append(rp.data)
            port_data.append(Array(datas))
            for (lane, w), s, i in zip(order, shared, read_index):
                if not w:
                    with m.If(lane.en & (lane.addr.bank == b)):
                        m.d.sync += selects[i][1].eq(~s)
        port_data = Array(port_data)
        for lane, (bank, port) in zip(rd, selects):
            m.d.sync += bank.eq(lane.addr.bank)
            m.d.comb += lane.data.eq(port_data[bank][port])
        return m
