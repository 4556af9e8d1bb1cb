"""Fixed-point building blocks shared by the cores: rounding shifts and saturation.

They mirror ``kfgen.sim.castella.rsr`` and ``sat`` exactly; ``tests/test_arith_fixed.py``
checks each against the model in Amaranth's simulator.
"""

from __future__ import annotations

from amaranth.hdl import Mux, Shape, signed, unsigned

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
    hi = v > fmt.max
    lo = v < fmt.min
    return Mux(hi, fmt.max, Mux(lo, fmt.min, v)), hi | lo
