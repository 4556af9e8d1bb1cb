"""The numbers of the trigonometric units (:mod:`.trig`): widths, iteration counts and tables,
exact to the last bit, shared by the hardware and its golden model
(:mod:`kfgen.sim.fpu.trig_model`).

Pure Python (no Amaranth). Every constant comes from exact integer arithmetic: pi from
Machin's formula and ``atan(2**-i)`` from its alternating series, each summed with floors
whose total error is bounded, and held in an interval that is narrowed until the floor or
the rounding it feeds is decided (as :mod:`.exp_plan` does for ``ln 2``).

The algorithms (see :class:`TrigPlan`):

* ``sin``/``cos``: ``t = |x| 2/pi mod 4`` by a Payne-Hanek product of the significand with a
  window of the bits of ``2/pi`` chosen by the exponent (the whole binary16, bfloat16 and
  binary32 ranges; ``|x| < 2**128`` in wider formats, outside which the result is NaN with
  NV), then a rotation CORDIC on the reduced angle ``f = t - round(t)`` in quarter turns, or
  ``sin r ~ r = f pi/2`` (one product) when ``|f|`` is so small that ``r - sin r`` is below a
  quarter unit of ``r``.
* ``atan2``: a vectoring CORDIC on the operands aligned to the larger one's exponent, or
  ``atan(y/x) ~ y/x`` (a restoring division) when ``x > 0`` and ``|y/x| < 2**-S``.

The guard bits are sized from an error budget written in :class:`TrigPlan` and checked by
the tests against an exact multi-precision reference: exhaustively in binary16 and bfloat16,
on random and directed inputs (the floats closest to multiples of ``pi/2``, found here by
continued fractions) in binary32 and binary64.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import isqrt
from fractions import Fraction
from functools import lru_cache

from .exact import format_consts, round_magnitude
from .exp_plan import _nearest
from .format import FloatFormat

__all__ = ["TrigPlan", "trig_plan", "pi_floor", "constant_word", "FUNCTIONS", "RANGE_LIMIT"]

#: The functions, and their operand count.
FUNCTIONS = {"sin": 1, "cos": 1, "atan2": 2}
#: sin and cos take ``|x| < 2**min(emax + 1, RANGE_LIMIT)``: the Payne-Hanek table grows with
#: the range (one entry per exponent), and beyond ``2**128`` (binary32's whole range) a
#: binary64 argument's nearest multiple of ``pi/2`` is a matter of hundreds of bits of ``pi``.
RANGE_LIMIT = 128
#: Guard bits of every fixed-point value beyond what the result's precision needs.
GUARD = 4


# ------------------------------------------------------------------------- exact constants
def _atan_inv_sum(x: int, bits: int) -> tuple[int, int]:
    """``(s, err)``: ``|atan(1/x) * 2**bits - s| <= err`` (integer ``x >= 2``): the series
    ``sum (-1)**k / ((2k+1) x**(2k+1))``, each term floored (under one unit), the tail after the
    last nonzero term below one unit."""
    s, k, power = 0, 0, x
    while True:
        term = (1 << bits) // ((2 * k + 1) * power)
        if term == 0:
            return s, k + 1
        s += -term if k & 1 else term
        k += 1
        power *= x * x


@lru_cache(maxsize=None)
def pi_floor(n: int) -> int:
    """``floor(pi * 2**n)``, decided: Machin's ``pi = 16 atan(1/5) - 4 atan(1/239)`` with 24
    guard bits, the summed error bound around it, more bits until both ends floor alike."""
    g = 24
    while True:
        a, ea = _atan_inv_sum(5, n + g)
        b, eb = _atan_inv_sum(239, n + g)
        s, err = 16 * a - 4 * b, 16 * ea + 4 * eb
        lo, hi = (s - err) >> g, (s + err) >> g
        if lo == hi:
            return lo
        g += 32


def constant_word(fmt, multiple: tuple[int, int], sign: int = 0) -> int:
    """``multiple[0] pi / 2**multiple[1]`` rounded to nearest in ``fmt`` with ``sign`` (the
    results of atan2's special operands): pi's bits from :func:`pi_floor`, and its infinite
    tail as a sticky bit."""
    k = format_consts(fmt)
    n = k.p + 8
    return round_magnitude(k, sign, pi_floor(n) * multiple[0], -n - multiple[1], True, False)[0]


def _pi(n: int) -> tuple[Fraction, Fraction]:
    lo = pi_floor(n)
    return Fraction(lo, 1 << n), Fraction(lo + 1, 1 << n)


def _atan_pow2(i: int, n: int) -> tuple[Fraction, Fraction]:
    """Rationals around ``atan(2**-i)``, ``2**-(n-8)`` apart at most (``i >= 0``)."""
    if i == 0:  # atan(1) = pi/4
        lo, hi = _pi(n + 2)
        return lo / 4, hi / 4
    bits = n + 16
    s, k, term = 0, 0, None
    while True:
        term = (1 << bits) >> (i * (2 * k + 1))
        term //= 2 * k + 1
        if term == 0:
            break
        s += -term if k & 1 else term
        k += 1
    err = k + 1
    return Fraction(s - err, 1 << bits), Fraction(s + err, 1 << bits)


def _decide(interval, bits: int) -> int:
    """Round to nearest at ``bits`` the value ``interval(n)`` brackets ever more tightly."""
    n = bits + 24
    while (got := _nearest(*interval(n), 1 << bits)) is None:
        n += 32
    return got


def _two_over_pi_floor(n: int) -> int:
    """``floor(2/pi * 2**n)``."""
    m = n + 24
    while True:
        p = pi_floor(m)
        lo, hi = (1 << (n + 1 + m)) // (p + 1), (1 << (n + 1 + m)) // p
        if lo == hi:
            return lo
        m += 32


def _isqrt_ratio(num: int, den: int, bits: int) -> int:
    """``floor(sqrt(num/den) * 2**bits)``."""
    return isqrt((num << (2 * bits)) // den)


# ------------------------------------------------------------------------- cancellation
def _min_distance(alpha_num: int, q_bits: int, limit: int) -> Fraction:
    """A lower bound of ``||m alpha||`` (distance to the nearest integer) over ``1 <= m <
    limit``, ``alpha = alpha_num / 2**q_bits`` known to ``2**-q_bits``: ``||q alpha||`` for the
    largest convergent denominator ``q`` below ``limit`` (a best approximation: ``||m alpha||
    >= ||q alpha||`` for every ``m`` below the next convergent's), less ``limit *
    2**-q_bits`` for ``alpha``'s own error."""
    b = 1 << q_bits
    q = max(d for d in _convergent_denominators(alpha_num, b) if d < limit)
    dist = Fraction(q * alpha_num % b, b)
    return min(dist, 1 - dist) - Fraction(limit, b)


def _convergent_denominators(a: int, b: int) -> list[int]:
    """The denominators of the convergents of ``a/b`` (``0 <= a < b``)."""
    out, q_prev, q = [], 0, 1
    num, den = b, a  # a/b = 1 / (b/a)
    out.append(1)
    while den:
        c, r = divmod(num, den)
        q_prev, q = q, c * q + q_prev
        out.append(q)
        num, den = den, r
    return out


# ------------------------------------------------------------------------- the plan
@dataclass(frozen=True)
class TrigPlan:
    """Every width, count and table of the trigonometric units for one format.

    ``p`` is the precision; every fixed-point value is an integer in units of ``2**-bits``.

    Shortcuts: ``S = p // 2 + 2``. For ``|x| < 2**-S``, ``|x - sin x| < |x|**3 / 6 <
    2**-(p+4) |x|``, a quarter of the spacing below ``|x|``: ``sin x`` rounds to ``x`` (NX,
    UF when ``x`` is subnormal) and ``cos x`` to 1 (NX). Likewise ``atan(q) ~ q`` for ``q =
    y/x < 2**-S``.

    sin, cos (``2**-S <= |x| < 2**range_bits``): ``|x| = M 2**E``, ``M`` the ``p``-bit
    significand. ``T = M * window[E - e_low] mod 2**(t_frac + p + 2)``, the window being
    ``floor(2**(E + t_frac + p) 2/pi) mod 2**(t_frac + p + 2)`` (bits of ``2/pi`` from the
    first whose product with ``M`` is not a multiple of 4), so ``t = T >> p`` is ``|x| 2/pi
    mod 4`` with ``t_frac`` fraction bits, less than ``2**(1 - t_frac)`` low. ``k =
    round(t)`` (its quadrant), ``f = t - k`` in ``[-1/2, 1/2)``. ``t_frac`` is ``p + GUARD +
    1`` bits beyond ``min_f_bits``, the exponent of the smallest ``|f|`` any input of the
    range can give (from the convergents of ``2**E 2/pi`` for every ``E``, or ``|x| 2/pi``
    itself where ``k`` is 0): ``f`` is known to ``2**-(p + GUARD)`` of itself. Then ``sin x``
    or ``cos x`` is ``+-sin r`` or ``+-cos r``, ``r = |f| pi/2``: for a sine with ``|f| <
    2**-(S+1)`` (so ``|r| < 2**-S``), ``r`` itself, ``|f|`` normalised to ``mul_bits`` times
    ``pi/2`` at ``mul_bits``; else a rotation CORDIC, ``cordic_bits`` fraction bits and
    ``iterations`` steps from ``(1/K, 0)`` through the angle ``|f|`` in quarter turns
    (``atan_quarter[i] = round(atan(2**-i) 2/pi)``), whose result is at least ``2**-(S+2)``
    and whose absolute error (a half unit per table entry and per truncated shift, about
    ``3 iterations`` units, plus ``2**-iterations``) is below ``2**-(S + p + GUARD + 2)``.

    atan2 (finite, nonzero ``x``, ``y``): with ``x > 0`` and ``|y| < 2**-S x`` by exponents,
    ``q = floor(|y|_M 2**div_bits / |x|_M)`` (a restoring division, ``div_bits + 1`` steps)
    and ``atan2 ~ q 2**(Ey - Ex - div_bits)``; else a vectoring CORDIC in radians
    (``atan_radians``) on the operands aligned to the larger exponent (``x < 0`` rotated by
    ``pi/2`` first), its angle at least ``2**-(S+2)``, with the same error budget. Every
    result but an exact zero is inexact (the sticky bit set).
    """

    fmt: FloatFormat
    p: int
    tiny_bits: int           # S
    range_bits: int          # |x| < 2**range_bits (sin, cos)
    full_range: bool
    min_f_bits: int
    t_frac: int
    e_low: int               # E of the first window
    window: tuple            # indexed by E - e_low
    mul_bits: int
    pi_half_mul: int         # floor(pi/2 2**mul_bits)
    cordic_bits: int
    iterations: int
    atan_quarter: tuple
    atan_radians: tuple
    inv_gain: int            # round(2**cordic_bits / K)
    pi_half: int             # round(pi/2 2**cordic_bits)
    div_bits: int

    @property
    def acc_bits(self) -> int:
        """Width of the reduction's product (mod ``2**acc_bits``)."""
        return self.t_frac + self.p + 2


@lru_cache(maxsize=None)
def trig_plan(fmt) -> TrigPlan:
    """The plan of ``fmt`` (a :class:`~.format.FloatFormat` or its name)."""
    fmt = FloatFormat.parse(fmt)
    p = fmt.precision
    S = p // 2 + 2
    if fmt.emin > -S:
        raise ValueError(f"sin, cos and atan2 need a format whose subnormals are below 2**-{S} "
                         f"(emin <= -{S}), not {fmt.name} (emin {fmt.emin})")
    full = fmt.emax + 1 <= RANGE_LIMIT
    R = fmt.emax + 1 if full else RANGE_LIMIT
    e_low = -S - (p - 1)            # the smallest E of the main path (|x| >= 2**-S)
    e_high = R - p                  # the largest (|x| < 2**R)
    # The smallest |f|: convergents where t can reach 1/2, |x| 2/pi where it cannot.
    q_bits = R + 3 * p + 96
    big = _two_over_pi_floor(q_bits + e_high + 2)
    min_f = Fraction(1)
    for E in range(e_low, e_high + 1):
        if p + E < 0:  # t < 2**(p+E) 2/pi < 1/2: k = 0, f = t >= 2**(p-1+E) 2/pi
            min_f = min(min_f, Fraction(63, 100) / (1 << (1 - p - E)))
            continue
        shift = (q_bits + e_high + 2) - (E + q_bits)
        alpha = (big >> shift) & ((1 << q_bits) - 1)  # frac(2**E 2/pi) at q_bits
        min_f = min(min_f, _min_distance(alpha, q_bits, 1 << p))
    if min_f <= 0:
        raise AssertionError(f"trig plan for {fmt}: reduction bound failed")
    min_f_bits = 0
    while Fraction(1, 1 << min_f_bits) > min_f:
        min_f_bits += 1
    t_frac = min_f_bits + p + GUARD + 1
    acc = t_frac + p + 2
    ref = _two_over_pi_floor(e_high + t_frac + p)
    window = tuple((ref >> (e_high - E)) & ((1 << acc) - 1) for E in range(e_low, e_high + 1))
    mul_bits = p + GUARD + 2
    if 2 * mul_bits + 1 > acc:
        raise AssertionError(f"trig plan for {fmt}: the product does not fit the accumulator")
    pi_half_mul = pi_floor(mul_bits - 1)
    W = p + S + GUARD + 8
    n = W + 1
    atan_quarter = tuple(_decide(lambda m, i=i: _quarter(i, m), W) for i in range(n))
    atan_radians = tuple(_decide(lambda m, i=i: _atan_pow2(i, m), W) for i in range(n))
    num, den = 1, 1
    for i in range(n):
        num, den = num << (2 * i), den * ((1 << (2 * i)) + 1)  # 1/K**2 = prod 1/(1 + 4**-i)
    inv_gain = (_isqrt_ratio(num, den, W + 1) + 1) >> 1
    pi_half = _decide(lambda m: tuple(v / 2 for v in _pi(m)), W)
    return TrigPlan(fmt=fmt, p=p, tiny_bits=S, range_bits=R, full_range=full,
                    min_f_bits=min_f_bits, t_frac=t_frac, e_low=e_low, window=window,
                    mul_bits=mul_bits, pi_half_mul=pi_half_mul, cordic_bits=W, iterations=n,
                    atan_quarter=atan_quarter, atan_radians=atan_radians, inv_gain=inv_gain,
                    pi_half=pi_half, div_bits=p + GUARD + 2)


def _quarter(i: int, n: int) -> tuple[Fraction, Fraction]:
    """Rationals around ``atan(2**-i) 2/pi``."""
    alo, ahi = _atan_pow2(i, n + 4)
    plo, phi = _pi(n + 4)
    return alo * 2 / phi, ahi * 2 / plo
