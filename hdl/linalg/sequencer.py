"""The program store (one ROM per issuing unit) and its fetch: an instruction leaves its
stream the cycle before it starts."""

from __future__ import annotations

from amaranth.hdl import Array, C, Module, Mux, Signal, unsigned
from amaranth.lib import data, memory, wiring
from amaranth.lib.wiring import In, Out

from .banks import addr_layout

__all__ = ["instruction_layout", "InstructionStream"]


def instruction_layout(unit: str, geometry, widths, mirror: bool = True) -> data.StructLayout:
    """A stream's instruction word (fields of :mod:`.microcode`); without ``mirror`` (no
    instruction of the stream writes a second address) no ``mirror`` and ``dst1``."""
    addr = addr_layout(geometry)
    fields = {"delta": unsigned(widths["delta"]), "a": addr, "b": addr, "dst": addr, "check": 2}
    if mirror:
        fields.update({"dst1": addr, "mirror": 1})
    if unit == "fma":
        fields.update({"count": unsigned(widths["count"]), "sa": addr, "sb": addr, "neg": 1,
                       "first": 1, "init_en": 1, "init": addr, "last": 1})
    if unit in ("sqrt", "copy", "exp"):
        del fields["b"]
    return data.StructLayout(fields)


class InstructionStream(wiring.Component):
    """One unit's instructions: a ROM holding every step, and its fetch.

    ``start`` (one cycle, while the stream is idle) selects step ``step``; the following
    cycle is the step's cycle ``-1``. An instruction whose step cycle is ``t`` (``delta``
    after the previous one's, the first after cycle 0) leaves the stream at cycle ``t - 1``:
    ``fire`` is high and ``ins`` holds it. The ROM is read one instruction ahead (read latency
    1), so instructions may start on consecutive cycles.

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

    def __init__(self, image, layout):
        self._image = image
        steps = len(image.bases)
        super().__init__({"start": In(1), "step": In(range(max(2, steps))),
                          "fire": Out(1), "ins": Out(layout)})

    def elaborate(self, platform):
        m = Module()
        img = self._image
        layout = self.ins.shape()
        depth = max(1, len(img.words))
        words = [{k: v for k, v in w.items() if k in layout.members} for w in img.words] or [{}]
        m.submodules.rom = rom = memory.Memory(shape=layout, depth=depth, init=words)
        rp = rom.read_port()
        idx = Signal(range(depth + 1))
        end = Signal(range(depth + 1))
        elapsed = Signal(layout.members["delta"])
        pad = (1 << len(self.step)) - len(img.bases)  # every step index covered
        bases = Array(C(b, range(depth + 1)) for b in img.bases + img.bases[-1:] * pad)
        ends = Array(C(e, range(depth + 1)) for e in img.ends + img.ends[-1:] * pad)
        m.d.comb += [
            self.ins.eq(rp.data),
            self.fire.eq((idx != end) & (elapsed == rp.data.delta)),
        ]
        with m.If(self.start):
            m.d.comb += rp.addr.eq(bases[self.step])
            m.d.sync += [idx.eq(bases[self.step]), end.eq(ends[self.step]), elapsed.eq(0)]
        with m.Else():
            m.d.comb += rp.addr.eq(idx + self.fire)
            m.d.sync += idx.eq(idx + self.fire)
            # after the stream's last instruction (idx == end) elapsed may wrap: it is unused
            m.d.sync += elapsed.eq(Mux(self.fire, 1, elapsed + 1))
        return m
