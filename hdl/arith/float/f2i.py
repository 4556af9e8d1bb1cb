"""Conversion of a float to a signed 32-bit integer, one operation per clock."""

from __future__ import annotations

from amaranth.hdl import C, Cat, Mux
from amaranth.lib.wiring import In, Out

from .timing import StagePlans, carry_delay, lut_delay, shifter_delay
from .format import FloatFormat
from .round import FloatUnit, leading_zeros, unpack

__all__ = ["FloatToInt"]

INT32_MAX, INT32_MIN = (1 << 31) - 1, 1 << 31  # (the latter as a 32-bit word)


class FloatToInt(FloatUnit):
    """A float rounded to a two's complement int32 (nearest, ties to even), as RISC-V
    ``fcvt.w`` with ``rm = RNE``.

    The significand is placed with its top bit at the integer's bit 31 (and fraction bits
    below, enough to hold it all) and shifted right by ``31 - exponent`` to give the integer
    and the round bit; the sticky bit compares the shift with the significand's trailing
    zeros. The increment and the negation share one adder (``-(i + inc) = ~i + ~inc``).
    NX when inexact; a NaN gives ``2**31 - 1``, ``+inf`` or a value rounding above
    ``2**31 - 1`` gives ``2**31 - 1``, ``-inf`` or a value rounding below ``-2**31`` gives
    ``-2**31``, all with NV alone. With ``subnormals="ftz"`` a subnormal is
    a zero (0, no flag) instead of a tiny inexact value (0 with NX).

    Parameters
    ----------
    fmt : FloatFormat or str
        Operand format (default ``binary32``).
    subnormals : "ieee" or "ftz"
    stages : int or None
        Register stages, 0 to 4: the latency in cycles, registers placed to balance the
        stages by a delay model. ``None`` is the fewest stages whose logic fits 100 MHz on an
        ECP5 by the model.

    Members
    -------
    i_valid : In(1)
    i_a : In(fmt.width)
    o_valid : Out(1)
        ``i_valid`` delayed by ``latency`` cycles.
    o_y : Out(32)
        The integer, two's complement.
    o_flags : Out(5)
        NX, UF, OF, DZ, NV from bit 0 (only NX and NV occur).

    Raises
    ------
    ValueError
        On a bad format, subnormal mode or stage count.

    Latency ``stages`` cycles; one operation per clock.
    """

    def __init__(self, fmt: FloatFormat | str = FloatFormat(), *, subnormals: str = "ieee",
                 stages: int | None = None):
        super().__init__(fmt, subnormals, stages, lambda f: {
            "i_valid": In(1), "i_a": In(f.width),
            "o_valid": Out(1), "o_y": Out(32), "o_flags": Out(5),
        })

    def stage_plans(self, fmt, subnormals):
        window = 32 + self._fraction_bits(fmt)
        plans = StagePlans([
            ("in", 0.0),
            ("unpack", lut_delay(3) + 2 * carry_delay(fmt.exp_bits + 2)),
            ("shift", shifter_delay(window) + lut_delay(1)),
            ("out", lut_delay(3) + carry_delay(33)),
        ])
        return plans, plans.default()

    @staticmethod
    def _fraction_bits(fmt):
        """Bits under the integer's LSB in the window: the whole significand fits when its top
        bit is at bit 31, and there are at least the round bit and one below."""
        return max(fmt.precision - 32, 0) + 2

    def datapath(self, m, cuts):
        fmt, p = self.fmt, self.fmt.precision
        frac = self._fraction_bits(fmt)
        window = 32 + frac
        v = cuts("in", a=self.i_a)
        a = unpack(fmt, v.a, self.subnormals)
        sig = cuts.wire("sig", a.sig)
        # (Reversed onto a wire of its own, so that the counter's slices are not of 53 parts.)
        tail = leading_zeros(cuts, cuts.wire("sig_reversed", sig[::-1]), "tz")
        distance = 31 - a.exp  # right shift that puts the top bit's weight at 2**0
        # Significand bit k ends up under the round bit when k < distance + p - 33: the sticky
        # bit is a compare with the trailing-zero count, beside the shifter, not an OR of the
        # bits it shifts out.
        v = cuts("unpack", sig=sig, sign=a.sign, is_nan=a.is_nan, is_inf=a.is_inf,
                 big=distance < 0,  # |a| >= 2**32: out of range whatever the sign
                 distance=Mux(distance > window, window, distance)[:window.bit_length()],
                 low=tail + (33 - p), nonzero=~a.is_zero)

        # ``sig`` at the top of the window; only the integer and the round bit are kept.
        top = Cat(C(0, window - p), v.sig)
        wide = (Cat(C(0, window), top) >> v.distance)[window + frac - 1:2 * window]
        v = cuts("shift", integer=wide[1:], round_bit=wide[0],
                 sticky=v.nonzero & (v.low < v.distance), sign=v.sign, is_nan=v.is_nan,
                 is_inf=v.is_inf, big=v.big)

        inexact = v.round_bit | v.sticky
        inc = v.round_bit & (v.sticky | v.integer[0])
        # Out of range after rounding: above 2**31 - 1, or below -2**31.
        limit = Mux(v.sign, INT32_MIN, INT32_MAX)
        over = v.big | v.is_inf | (v.integer > limit) | (v.integer == limit) & inc
        result = ((v.integer ^ v.sign.replicate(32)) + (inc ^ v.sign))[:32]
        word = Mux(v.is_nan, INT32_MAX, Mux(over, Mux(v.sign, INT32_MIN, INT32_MAX), result))
        invalid = v.is_nan | over
        return word, Cat(inexact & ~invalid, C(0, 3), invalid)
