"""Floating-point square root: a radix-2 digit recurrence, pipelined or iterative."""

from __future__ import annotations

from amaranth.hdl import C, Cat, Mux
from amaranth.lib.wiring import In, Out

from .div import RecurrenceUnit, add_sub, sum_is_zero
from .format import FloatFormat
from .round import leading_zeros, unpack
from .timing import carry_delay, lut_delay

__all__ = ["FloatSqrt"]


class FloatSqrt(RecurrenceUnit):
    """``sqrt(a)`` rounded to nearest even, by radix-2 non-restoring square root.

    A subnormal operand is normalised first (leading-zero count and shift). The significand
    ``m`` in ``[2**(p-1), 2**p)`` is doubled when the exponent is odd, so the radicand ``M``
    (``p + 1`` bits) has an even exponent that halves exactly. The root of ``M * 2**(p+3)`` is
    found one bit per step, two radicand bits at a time: the first bit is always one, and
    each of the ``p + 1`` further steps is one adder, ``r = 4r + pair - (4Q + 1)`` after a
    nonnegative remainder and ``4r + pair + (4Q + 3)`` after a negative one, the new bit
    being ``r >= 0``. The ``p + 2`` root bits hold the significand, a round bit and one more;
    the remainder (``r``, or ``r + 2Q + 1`` when negative) is zero or not, the sticky bit.
    The result goes through the shared rounding stage (:func:`~.round.round_pack`); it cannot
    overflow, and it is never below ``2**emin`` in the preset formats (their right shifter
    is left out).

    Special cases: ``sqrt(-0) = -0``, ``sqrt(+inf) = +inf``; a negative nonzero operand (or
    ``-inf``) gives the canonical NaN with NV; a quiet NaN the canonical NaN without a flag, a
    signalling one with NV.

    Parameters
    ----------
    fmt : FloatFormat or str
        Operand and result format (default ``binary32``).
    subnormals : "ieee" or "ftz"
    stages : int or None
        Register stages, the latency in cycles. Pipelined: 0 to ``p + 9`` (33 for
        binary32), registers placed to balance the stages. ``None`` is the fewest stages whose
        logic fits 100 MHz on an ECP5 by the delay model of :mod:`.timing`: a register after
        every recurrence step (29 for binary32, 16 for binary16, 60 for binary64; one or two
        fewer with ``ftz``). Iterative: ``cycles_per_op + 1`` to ``cycles_per_op + 8``;
        ``None`` is ``cycles_per_op + 2`` (binary32, K <= 12) or ``+ 4``. See
        :class:`~.div.RecurrenceUnit`.
    cycles_per_op : int
        1 for one operation per clock (the recurrence unrolled), or K from 2 to ``p + 1``: one
        block of ``ceil((p + 1) / K)`` steps reused for K cycles, one operation accepted every
        K cycles.

    Members
    -------
    i_valid : In(1)
    i_ready : Out(1), only when ``cycles_per_op > 1``
        High when an operation is accepted this cycle (``i_valid & i_ready``); it does not
        depend on ``i_valid``.
    i_a : In(fmt.width)
    o_valid : Out(1)
        The accepted ``i_valid`` delayed by ``latency`` cycles.
    o_y : Out(fmt.width)
    o_flags : Out(5)
        NX, UF, OF, DZ, NV from bit 0 (only NX, and UF in tiny custom formats, and NV occur).

    Raises
    ------
    ValueError
        On a bad format, subnormal mode, stage count or ``cycles_per_op``.

    Latency ``stages`` cycles from the accepting cycle to ``o_valid``; initiation interval
    ``cycles_per_op``. On an LFE5U-85F (nextpnr, median of three placer seeds) the default
    binary32 pipeline runs at about 146 MHz, binary16 at 174 and binary64 at 127.
    Iterative, the block of steps sets the clock: about 100 MHz with two steps a cycle
    (binary32 K = 13), 131 MHz with one (K = 25).
    """

    OP = "sqrt"

    def __init__(self, fmt: FloatFormat | str = FloatFormat(), *, subnormals: str = "ieee",
                 stages: int | None = None, cycles_per_op: int = 1):
        super().__init__(fmt, subnormals, stages, cycles_per_op, lambda f: {
            "i_valid": In(1), "i_a": In(f.width),
            "o_valid": Out(1), "o_y": Out(f.width), "o_flags": Out(5),
        })

    @classmethod
    def iterations(cls, fmt):
        return fmt.precision + 1

    def denormalise(self, fmt, ieee):
        # The smallest operand, 2**(emin - frac_bits) (2**emin with ftz), has a root whose
        # exponent is the floor of half of that.
        return ((fmt.emin - fmt.frac_bits if ieee else fmt.emin) >> 1) < fmt.emin

    def first_delay(self, fmt):
        return lut_delay(1)

    def step_delay(self, fmt, i):
        return lut_delay(2) + carry_delay(i + 4)

    def operands(self, cuts, v):
        fmt, p, ieee = self.fmt, self.fmt.precision, self.subnormals == "ieee"
        a = unpack(fmt, v.i_a, self.subnormals)
        negative = a.sign & ~a.is_zero  # -inf included; -0 is not
        zeros = leading_zeros(cuts, a.sig) if ieee else C(0, 1)
        v = cuts("unpack", sig=a.sig, exp=a.exp, zeros=zeros, sign=a.sign,
                 is_nan=a.is_nan | negative, is_inf=a.is_inf & ~a.sign, is_zero=a.is_zero,
                 invalid=a.is_snan | negative & ~a.is_nan)
        exp = v.exp - v.zeros
        m = (v.sig << v.zeros)[:p]
        odd = exp[0]
        return cuts("normalise", radicand=Mux(odd, Cat(C(0, 1), m), m), exp=exp >> 1,
                    sign=v.sign, is_nan=v.is_nan, is_inf=v.is_inf, is_zero=v.is_zero,
                    invalid=v.invalid)

    def first(self, cuts, v):
        p, M = self.fmt.precision, v.radicand
        # The top radicand pair is 1..3 (M >= 2**(p-1)): the first root bit is one.
        r = Cat((M[p - 1:p + 1] - 1)[:2], C(0, 2)).as_signed()
        q = C(1, 1)
        # The radicand bits still to come, top first, padded to whole pairs.
        rad = Cat(C(0, (p - 1) % 2), M[:p - 1])
        if self._cycles > 1:  # the iterative core's registers hold the final widths
            r = Cat(r, C(0, self._steps))
            q = C(1, self._steps + 1)  # (zeros shift into rad behind the last pair)
        return dict(r=r.as_signed(), q=q, rad=rad, exp=v.exp, sign=v.sign, is_nan=v.is_nan,
                    is_inf=v.is_inf, is_zero=v.is_zero, invalid=v.invalid)

    def step(self, s, fixed):
        r, q, rad = s["r"], s["q"], s["rad"]
        neg = r[-1]
        if len(rad) >= 2:
            pair = rad[-2:]
            rad = Cat(C(0, 2), rad[:-2]) if fixed else rad[:-2]
        else:
            pair = C(0, 2)
        # 4r + pair -+ (4q + 1 + 2 neg): subtract 4q + 1 after r >= 0, add 4q + 3 after r < 0.
        r = add_sub(Cat(pair, r).as_signed(), Cat(C(1, 1), neg, q), ~neg)
        r = r[:len(q) + 4].as_signed()  # in [-(2q' + 1), 2q'] for the new root q'
        return {**s, "r": r, "q": Cat(~r[-1], q), "rad": rad}

    def finish(self, s):
        r, q = s["r"], s["q"]
        # The remainder is r, or r + 2q + 1 (in [0, 2q + 1)) when r is negative.
        sticky = Mux(r[-1], ~sum_is_zero(r, Cat(C(1, 1), q), len(q) + 1), r.any())
        # The root of M * 2**(p+3) has p + 2 bits; its top bit, always one, weighs
        # 2**(exp // 2). As a constant, it folds the rounding stage's leading-zero count away.
        return dict(sign=s["sign"], exp=s["exp"], sig=Cat(q[:-1], C(1, 1)), sticky=sticky,
                    is_nan=s["is_nan"], is_inf=s["is_inf"], is_zero=s["is_zero"],
                    invalid=s["invalid"])
