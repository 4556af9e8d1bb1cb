"""Floating-point addition and subtraction, one operation per clock."""

from __future__ import annotations

from amaranth.hdl import C, Cat, Mux
from amaranth.lib.wiring import In, Out

from .format import FloatFormat
from .timing import carry_delay, lut_delay, prepare_delay, round_delays, shifter_delay, tree_levels
from .round import ROUND_BOUNDARIES, FloatUnit, prepare_exponent, round_pack, unpack

__all__ = ["FloatAdd", "FloatSub"]

_R = ROUND_BOUNDARIES  # round.shift, round.round, round.select


class FloatAdd(FloatUnit):
    """``a + b`` (or ``a - b`` with ``subtract``) rounded to nearest even.

    Single path: the operands are swapped so the larger magnitude comes first, the smaller is
    aligned to it with two guard bits and a sticky bit (worked out beside the shift), the two
    are added or subtracted in ``precision + 4`` bits, and :func:`~.round.round_pack`
    normalises (counting the leading zeros a cancellation leaves) and rounds. A cancellation
    of more than one bit only happens when the exponents differ by at most one, where no bit
    was lost, so the sum is exact there.

    Parameters
    ----------
    fmt : FloatFormat or str
        Operand and result format (default ``binary32``).
    subnormals : "ieee" or "ftz"
    stages : int or None
        Register stages, 0 to 8: the latency in cycles. ``None`` is 6 (over 125 MHz on an
        ECP5-85 for binary32, 130-145 over placer seeds: registers before the alignment shift,
        before the add, after it, before the normalising shift, before the rounding
        increment, and at the output); 7 adds one before the final selects (over 140 MHz).
    subtract : bool
        Compute ``a - b`` (``b``'s sign inverted before anything else, NaNs included).

    Members
    -------
    i_valid : In(1)
    i_a, i_b : In(fmt.width)
    o_valid : Out(1)
        ``i_valid`` delayed by ``latency`` cycles.
    o_y : Out(fmt.width)
    o_flags : Out(5)
        NX, UF, OF, DZ, NV from bit 0.

    Raises
    ------
    ValueError
        On a bad format, subnormal mode or stage count.

    Latency ``stages`` cycles; one operation per clock.
    """

    PLANS = {
        0: (),
        1: ("out",),
        2: ("norm", "out"),
        3: ("add", _R[0], "out"),
        4: ("align", "norm", _R[1], "out"),
        5: ("align", "add", _R[0], _R[1], "out"),
        6: ("align", "add", "norm", _R[0], _R[1], "out"),
        7: ("align", "add", "norm", _R[0], _R[1], _R[2], "out"),
        8: ("in", "align", "add", "norm", _R[0], _R[1], _R[2], "out"),
    }
    DEFAULT_STAGES = 6

    def __init__(self, fmt: FloatFormat | str = FloatFormat(), *, subnormals: str = "ieee",
                 stages: int | None = None, subtract: bool = False):
        self._subtract = bool(subtract)
        super().__init__(fmt, subnormals, stages, lambda f: {
            "i_valid": In(1), "i_a": In(f.width), "i_b": In(f.width),
            "o_valid": Out(1), "o_y": Out(f.width), "o_flags": Out(5),
        })

    def stage_segments(self, fmt, subnormals):
        """In order: the magnitude compare beside the exponent differences and their cap, the
        operand selects; the alignment shift beside its lost bits and the exponent's
        preparation; the adder; the rounding (prepared, not denormalising)."""
        p, e = fmt.precision, fmt.exp_bits
        return [("in", 0.0),
                ("align", lut_delay(2) + max(carry_delay(fmt.width - 1), carry_delay(e + 1) + lut_delay(1))),
                ("add", max(shifter_delay(p + 2), lut_delay(1 + tree_levels(p, 4)),
                            prepare_delay(fmt, from_room=True))),
                ("norm", carry_delay(p + 4) + lut_delay(1)),
                *zip(_R + ("out",), round_delays(fmt, p + 4, denormalise=False, prepared=True))]

    @property
    def subtract(self) -> bool:
        return self._subtract

    def datapath(self, m, cuts):
        fmt, p = self.fmt, self.fmt.precision
        v = cuts("in", a=self.i_a, b=self.i_b)
        a = unpack(fmt, v.a, self.subnormals)
        b = unpack(fmt, v.b, self.subnormals)
        b_sign = b.sign ^ self._subtract
        # Magnitude order from the words (monotonic for finite values); a flushed subnormal
        # only ever faces a smaller-or-equal operand as the larger one when both are zero.
        mag = fmt.width - 1
        swap = cuts.wire("swap", v.b[:mag] > v.a[:mag])
        big_sig, small_sig = Mux(swap, b.sig, a.sig), Mux(swap, a.sig, b.sig)
        # Both exponent differences beside the magnitude compare, which picks one. From p + 2
        # places on every bit of the smaller operand is sticky: a difference with a bit set
        # above those counting to p + 2 becomes the largest shift they count to.
        bits = (p + 2).bit_length()
        a_b = cuts.wire("exp_a_b", a.biased - b.biased)
        b_a = cuts.wire("exp_b_a", b.biased - a.biased)

        def capped(d):  # (garbage when negative: then the other one is picked)
            return Mux(d[bits:].any(), (1 << bits) - 1, d[:bits])

        inf_inf = cuts.wire("inf_inf", a.is_inf & b.is_inf & (a.sign ^ b_sign))
        v = cuts("align", big_sig=big_sig, small_sig=small_sig,
                 diff=Mux(swap, capped(b_a), capped(a_b)),
                 # The sum's top (carry) bit weighs 2**(e + 1) for the larger exponent e: its
                 # room above emin is e + 1 - emin, the larger biased exponent.
                 room=Mux(swap, b.biased, a.biased),
                 sub=a.sign ^ b_sign,
                 sign=Mux(a.is_inf, a.sign, Mux(b.is_inf, b_sign, Mux(swap, b_sign, a.sign))),
                 zero_sign=a.sign & b_sign,
                 is_nan=a.is_nan | b.is_nan | inf_inf,
                 is_inf=a.is_inf | b.is_inf,
                 invalid=a.is_snan | b.is_snan | inf_inf)

        # Sum layout (p + 4 bits): carry | significand (p) | two guard bits | sticky.
        # The bits shifted out are found beside the shift, not after it: bit i of the smaller
        # significand falls under the guard bits when the shift is at least i + 3.
        aligned = cuts.wire("aligned", Cat(C(0, 2), v.small_sig) >> v.diff)
        lost = Cat(v.small_sig[i] & (v.diff >= i + 3) for i in range(p)).any()
        small = Cat(lost, aligned)
        big = Cat(C(0, 3), v.big_sig)
        exp = prepare_exponent(cuts, fmt, None, p + 4, denormalise=False, room=v.room)
        v = cuts("add", big=big, small=small, sub=v.sub, exp=exp, sign=v.sign,
                 zero_sign=v.zero_sign, is_nan=v.is_nan, is_inf=v.is_inf, invalid=v.invalid)

        # The larger magnitude comes first, so the difference is never negative; the sticky
        # bit as the lowest bit makes the borrow of a subtraction come out right.
        total = Mux(v.sub, v.big - v.small, v.big + v.small)[:p + 4]
        v = cuts("norm", total=total, exp=v.exp, sign=v.sign, zero_sign=v.zero_sign,
                 is_nan=v.is_nan, is_inf=v.is_inf, invalid=v.invalid)

        return round_pack(cuts, fmt, sign=v.sign, exp=v.exp, sig=v.total, zero_sign=v.zero_sign,
                          is_nan=v.is_nan, is_inf=v.is_inf, invalid=v.invalid,
                          subnormals=self.subnormals, denormalise=False)


class FloatSub(FloatAdd):
    """``a - b``: :class:`FloatAdd` with ``subtract=True`` (same parameters and members)."""

    def __init__(self, fmt: FloatFormat | str = FloatFormat(), *, subnormals: str = "ieee",
                 stages: int | None = None):
        super().__init__(fmt, subnormals=subnormals, stages=stages, subtract=True)
