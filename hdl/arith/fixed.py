"""Fixed-point building blocks shared by the cores: rounding shifts and saturation.

They mirror ``kfgen.sim.castella.model.rsr`` and ``sat`` exactly; ``tests/castella/test_castella_blocks.py``
checks each against the model in Amaranth's simulator.
"""

from __future__ import annotations

from amaranth.hdl import C, Mux, Shape, Value, signed, unsigned

__all__ = ["rsr", "saturate", "fmt_shape"]


def fmt_shape(fmt) -> Shape:
    """The Amaranth shape of a :class:`~kfgen.hdl.castella.params.Fmt`."""
    return signed(fmt.width) if fmt.signed else unsigned(fmt.width)


def rsr(v, s: int):
    """Shift right by ``s`` rounding half up; ``s <= 0`` shifts left (exact)."""
    if s > 0:
        return (v + (1 << (s - 1))) >> s
    return v << (-s)


def saturate(v, fmt):
    """``(value, overflowed)``: ``v`` clamped into ``fmt``'s range, and whether it had to be."""
    v = Value.cast(v)
    shape = v.shape()
    lo_v = -(1 << (shape.width - 1)) if shape.signed else 0
    hi_v = (1 << (shape.width - 1)) - 1 if shape.signed else (1 << shape.width) - 1
    # Compare only where the operand's range reaches past the format's (no constant compares).
    hi = v > fmt.max if hi_v > fmt.max else C(0, 1)
    lo = v < fmt.min if lo_v < fmt.min else C(0, 1)
    return Mux(hi, fmt.max, Mux(lo, fmt.min, v)), hi | lo
