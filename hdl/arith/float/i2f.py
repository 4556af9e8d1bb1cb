"""Conversion of a signed 32-bit integer to floating point, one operation per clock."""

from __future__ import annotations

from amaranth.hdl import C, Cat, Mux, signed
from amaranth.lib.wiring import In, Out

from .timing import StagePlans, carry_delay, lut_delay, round_delays
from .format import FloatFormat
from .round import ROUND_BOUNDARIES, FloatUnit, round_pack

__all__ = ["IntToFloat"]


class IntToFloat(FloatUnit):
    """A two's complement int32 rounded to ``fmt`` (nearest, ties to even).

    The magnitude (``2**31`` included) is the significand of a raw result whose top bit weighs
    ``2**31``; the shared rounding stage (:func:`~.round.round_pack`) counts its leading zeros,
    normalises and rounds it. NX when bits are rounded off (``|i| > 2**p``), OF|NX when the
    result overflows the format (binary16: ``|i| > 65519``). Zero is ``+0``. The results are
    never subnormal, so ``subnormals`` has no effect (it is accepted like every unit's).

    Parameters
    ----------
    fmt : FloatFormat or str
        Result format (default ``binary32``).
    subnormals : "ieee" or "ftz"
    stages : int or None
        Register stages, 0 to 6: the latency in cycles, registers placed to balance the
        stages by a delay model. ``None`` is the fewest stages whose logic fits 100 MHz on an
        ECP5 by the model.

    Members
    -------
    i_valid : In(1)
    i_a : In(32)
        The integer, two's complement.
    o_valid : Out(1)
        ``i_valid`` delayed by ``latency`` cycles.
    o_y : Out(fmt.width)
    o_flags : Out(5)
        NX, UF, OF, DZ, NV from bit 0 (only NX and OF occur).

    Raises
    ------
    ValueError
        On a bad format, subnormal mode or stage count.

    Latency ``stages`` cycles; one operation per clock.
    """

    def __init__(self, fmt: FloatFormat | str = FloatFormat(), *, subnormals: str = "ieee",
                 stages: int | None = None):
        super().__init__(fmt, subnormals, stages, lambda f: {
            "i_valid": In(1), "i_a": In(32),
            "o_valid": Out(1), "o_y": Out(f.width), "o_flags": Out(5),
        })

    def stage_plans(self, fmt, subnormals):
        width = max(32, fmt.precision + 2)
        plans = StagePlans([("in", 0.0), ("abs", carry_delay(32) + lut_delay(1))]
                           + list(zip(ROUND_BOUNDARIES + ("out",), round_delays(fmt, width, False))))
        return plans, plans.default()

    def datapath(self, m, cuts):
        fmt = self.fmt
        v = cuts("in", a=self.i_a)
        sign = v.a[31]
        v = cuts("abs", sign=sign, mag=Mux(sign, -v.a, v.a)[:32])  # 2**31 fits unsigned
        # At least two bits under a binary64 significand: pad the magnitude below (exactly).
        pad = max(0, fmt.precision + 2 - 32)
        return round_pack(cuts, fmt, sign=v.sign, exp=C(31, signed(7)),
                          sig=Cat(C(0, pad), v.mag), subnormals=self.subnormals,
                          denormalise=False)
