"""The program store (one ROM per issuing unit) and its fetch: an instruction leaves its
stream the cycle before it starts."""

from __future__ import annotations

from amaranth.hdl import Array, C, Module, Mux, Signal, unsigned
from amaranth.lib import data, memory, wiring
from amaranth.lib.wiring import In, Out

from . import isa
from .banks import addr_layout
from .isa import CHECK_BITS

__all__ = ["instruction_layout", "InstructionStream"]


def instruction_layout(unit: str, geometry, widths, mirror: bool = True) -> data.StructLayout:
    """A stream's instruction word (fields of :mod:`.microcode`); without ``mirror`` (no
    instruction of the stream writes a second address) no ``mirror`` and ``dst1``."""
    addr = addr_layout(geometry)
    fields = {"delta": unsigned(widths["delta"]), "a": addr, "pa": 1, "b": addr, "pb": 1,
              "dst": addr, "pd0": 1, "check": CHECK_BITS}
    if mirror:
        fields.update({"dst1": addr, "pd1": 1, "mirror": 1})
    if unit == "fma":
        fields.update({"count": unsigned(widths["count"]), "sa": addr, "sb": addr, "neg": 1,
                       "first": 1, "init_en": 1, "init": addr, "pi": 1, "last": 1})
    if "b" not in isa.unit(unit).operands:
        del fields["b"], fields["pb"]
    return data.StructLayout(fields)


class InstructionStream(wiring.Component):
    """One unit's instructions: a ROM holding every step, and its fetch.

    ``start`` (one cycle, while the stream is idle) selects step ``step``; the step's cycle
    0 is :data:`LEAD` cycles after that one. An instruction whose step cycle is ``t``
    (``delta`` after the previous one's, the first's after cycle 0) leaves the stream at
    cycle ``t - 1``: ``fire`` is high and ``ins`` holds it. Both are registers.

    The fetch is pipelined so that no path runs from the ROM's output back to its address:
    the ROM (read latency 1) holds the next instruction but one, a register the next one,
    and a counter of the cycles since the last issue decides, from registers alone, when the
    next one leaves (instructions may leave on consecutive cycles).

    Parameters
    ----------
    image : microcode.StreamImage
    layout : data.StructLayout
        :func:`instruction_layout` of the stream's unit.

    Members
    -------
    start : In(1)
    step : In(range(steps))
    fire : Out(1)
    ins : Out(layout)
        Valid while ``fire``.
    """

    #: Cycles from the one ``start`` is high in to the step's cycle 0: the ROM's first read,
    #: the next-instruction register, the issue decision and the output register.
    LEAD = 4

    @staticmethod
    def rom_depth(image) -> int:
        """Words of the ROM holding ``image`` (every step's instructions; one at least)."""
        return max(1, len(image.words))

    def __init__(self, image, layout):
        self._image = image
        steps = len(image.bases)
        super().__init__({"start": In(1), "step": In(range(max(2, steps))),
                          "fire": Out(1), "ins": Out(layout)})

    def elaborate(self, platform):
        m = Module()
        img = self._image
        layout = self.ins.shape()
        depth = self.rom_depth(img)
        words = [{k: v for k, v in w.items() if k in layout.members} for w in img.words] or [{}]
        m.submodules.rom = rom = memory.Memory(shape=layout, depth=depth, init=words)
        rp = rom.read_port()
        pad = (1 << len(self.step)) - len(img.bases)  # every step index covered
        bases = Array(C(b, range(depth + 1)) for b in img.bases + img.bases[-1:] * pad)
        ends = Array(C(e, range(depth + 1)) for e in img.ends + img.ends[-1:] * pad)
        idx = Signal(range(depth + 1))  # the ROM's next read
        end = Signal(range(depth + 1))
        a_valid = Signal()  # the ROM's output is an instruction of the step not yet taken
        nxt = Signal(layout)  # the next instruction to leave
        nxt_valid = Signal()
        elapsed = Signal(layout.members["delta"])  # cycles since the last one left
        go = Signal()
        m.d.comb += go.eq(nxt_valid & (elapsed == nxt.delta))
        take = Signal()
        m.d.comb += take.eq((go | ~nxt_valid) & a_valid)
        m.d.sync += self.fire.eq(go)
        with m.If(go):
            m.d.sync += self.ins.eq(nxt)
        with m.If(self.start):
            m.d.comb += [rp.addr.eq(bases[self.step]), rp.en.eq(1)]
            m.d.sync += [idx.eq(bases[self.step] + 1), end.eq(ends[self.step]),
                         a_valid.eq(bases[self.step] != ends[self.step]), nxt_valid.eq(0)]
        with m.Else():
            m.d.comb += [rp.addr.eq(idx), rp.en.eq(take)]
            with m.If(take):
                m.d.sync += [nxt.eq(rp.data), idx.eq(idx + 1), a_valid.eq(idx != end)]
            with m.If(go | ~nxt_valid):
                m.d.sync += nxt_valid.eq(a_valid)
            # the first instruction counts from the cycle after it is taken; the others from
            # the cycle after the previous one left (after the last one, elapsed may wrap)
            m.d.sync += elapsed.eq(Mux(go, 1, Mux(nxt_valid, elapsed + 1, 0)))
        return m
