"""Exact reference for ``exp``: ``e**x`` correctly rounded to any format, and the two floats
around it, for checking the unit's accuracy.

Independent of the unit's algorithm: ``e**x`` comes from Python's :mod:`decimal` (whose
``exp`` is correctly rounded to the context's precision) on the exact decimal value of ``x``,
which bounds it in an interval of rationals one decimal unit wide; the interval is rounded
to the format at both ends with exact integer arithmetic (IEEE 754 rounding to nearest even,
as :func:`kfgen.sim.float_ref.round_to_format`, which the tests hold it against), and when the two ends do not round alike (a float or a rounding boundary inside
the interval) the precision is raised until they do. Results far beyond the overflow or
underflow thresholds are decided by a bound, without evaluating ``e**x``.

:func:`exp_exact` gives, per word, the correctly rounded word and flags (RNE, tininess after
rounding) and the floats just below and just above ``e**x``: a faithful result is one of
those two, and :func:`faithful` says which words are, and that overflow is exact (a result
overflows exactly when the correctly rounded one does).
"""

from __future__ import annotations

import decimal
from fractions import Fraction
from functools import lru_cache

import numpy as np

from kfgen.hdl.arith.float.format import FLAG_NX, FLAG_OF, FLAG_UF, FloatFormat

from ..float_ref import decode

__all__ = ["exp_exact", "exp_exact_word", "faithful", "ulp_error", "directed_words", "random_words"]

# ln 2 is between these (to 9 digits): enough for the far-range shortcuts.
_LN2_LO, _LN2_HI = Fraction(693147180, 10 ** 9), Fraction(693147181, 10 ** 9)


def _decimal(value: Fraction) -> decimal.Decimal:
    """The exact decimal of a dyadic rational ``n / 2**j``: ``n 5**j / 10**j``."""
    den = value.denominator
    j = den.bit_length() - 1
    if den != 1 << j:
        raise ValueError("not a dyadic rational")
    return decimal.Decimal(f"{value.numerator * 5 ** j}E-{j}")


class _Format:
    """A format's constants as plain attributes (its properties cost a call each)."""

    def __init__(self, fmt: FloatFormat):
        self.fmt, self.m, self.p, self.bias = fmt, fmt.frac_bits, fmt.precision, fmt.bias
        self.emin, self.emax, self.inf, self.max_finite = fmt.emin, fmt.emax, fmt.inf(0), fmt.max_finite
        self.one = fmt.pack(0, fmt.bias, 0)
        self.width, self.field_max, self.frac_mask = fmt.width, fmt.exp_max_field, fmt.frac_mask
        # e**x > 2**(emax + 1) above (emax + 1) ln 2, and e**x < 2**(emin - m - 2) below
        # (emin - m - 2) ln 2: as n / 10**9, outward.
        self.over = (fmt.emax + 1) * _LN2_HI
        self.under = (fmt.emin - fmt.frac_bits - 2) * _LN2_HI
        self.tiny = Fraction(1, 1 << (fmt.precision + 8))  # decided without decimal below


@lru_cache(maxsize=None)
def _format(fmt) -> _Format:
    return _Format(FloatFormat.parse(fmt))


def _round_ratio(f: _Format, num: int, den: int) -> tuple[int, int, int]:
    """``(word, flags, down)`` for ``v = num / den > 0``: ``v`` rounded to nearest even with
    its flags (NX, and OF or UF as IEEE 754 says with tininess after rounding), and the
    largest float at or below ``v`` (``max_finite`` above it). Integers only."""
    m = f.m
    top = num.bit_length() - den.bit_length()  # floor(log2 v) or one more
    if (num << -top if top < 0 else num) < (den << top if top > 0 else den):
        top -= 1
    scale = max(top, f.emin)
    shift = m + 2 - scale  # two bits under the last kept one
    q, rem = divmod(num << shift, den) if shift >= 0 else divmod(num, den << -shift)
    kept = q >> 2
    up = q >> 1 & 1 and (q & 1 or rem or kept & 1)
    # (scale + bias - 1) << m plus a p-bit significand (hidden bit included) is the word; for
    # a subnormal scale = emin makes the first term zero and the significand is the word.
    base = (scale + f.bias - 1) << m
    word, down = base + kept + bool(up), base + kept
    if top > f.emax or word >= f.inf:
        return f.inf, FLAG_OF | FLAG_NX, f.max_finite
    # Tiny after rounding: below 2**emin (1 - 2**-(p+1)), where rounding to p bits with an
    # unbounded exponent stops short of 2**emin.
    lhs, rhs = num << (f.p + 1), den * ((1 << (f.p + 1)) - 1)
    lhs, rhs = (lhs << -f.emin, rhs) if f.emin <= 0 else (lhs, rhs << f.emin)
    return word, FLAG_NX | (FLAG_UF if lhs < rhs else 0), down


@lru_cache(maxsize=None)
def _context(digits: int) -> decimal.Context:
    return decimal.Context(prec=digits, rounding=decimal.ROUND_HALF_EVEN, Emin=-10 ** 7,
                           Emax=10 ** 7, traps=[decimal.InvalidOperation])


def exp_exact_word(fmt, word: int) -> tuple[int, int, int, int]:
    """``(rn, flags, down, up)`` for one word: ``e**x`` rounded to nearest even with its flags,
    and the floats just below and just above ``e**x`` (equal when it is exact: ``x = 0``;
    ``up`` is ``+inf`` above the largest finite). Specials: NaN gives the canonical NaN
    (flags are not modelled here: NV is the golden model's business), ``e**+inf = +inf``,
    ``e**-inf = +0``."""
    f = _format(fmt)
    sign, field, frac = word >> (f.width - 1), word >> f.m & f.field_max, word & f.frac_mask
    if field == f.field_max:
        if frac:
            nan = f.fmt.canonical_nan
            return nan, 0, nan, nan
        w = 0 if sign else f.inf
        return w, 0, w, w
    sig = frac | (1 << f.m) if field else frac
    if sig == 0:
        return f.one, 0, f.one, f.one
    x = Fraction(-sig if sign else sig) * Fraction(2) ** (max(field, 1) - f.bias - f.m)
    if x > f.over:
        return f.inf, FLAG_OF | FLAG_NX, f.max_finite, f.inf
    if x < f.under:
        return 0, FLAG_UF | FLAG_NX, 0, 1
    if abs(x) < f.tiny:
        # 1 + x < e**x < 1 + x + x**2 for |x| <= 1/2 (Lagrange's remainder x**2/2 e**xi), far
        # inside (1 - 2**-(p+1), 1 + 2**-p): RN is 1, between 1 and the float next to it.
        return (f.one, FLAG_NX, f.one - 1, f.one) if sign else (f.one, FLAG_NX, f.one, f.one + 1)
    xd = _decimal(x)
    digits = (f.p + 24) * 3 // 10 + 4
    while True:
        # d is e**x rounded to `digits` digits: e**x is within half a unit of its last digit.
        d = _context(digits).exp(xd)
        num, den = d.as_integer_ratio()
        unit = d.adjusted() - digits  # half a unit of the last digit is 5 * 10**unit
        if unit >= 0:
            half = 5 * 10 ** unit * den
        else:
            half = 5 * den
            num, den = num * 10 ** -unit, den * 10 ** -unit
        lo, hi = _round_ratio(f, num - half, den), _round_ratio(f, num + half, den)
        if lo == hi:
            return lo[0], lo[1], lo[2], lo[2] + 1  # the next float up is the next word
        digits += 10


def exp_exact(fmt, words) -> dict[str, np.ndarray]:
    """:func:`exp_exact_word` over ``words``: arrays ``rn``, ``flags``, ``down``, ``up``
    (``object`` arrays of Python integers for words wider than 62 bits)."""
    rows = [exp_exact_word(fmt, int(w)) for w in np.ravel(words)]
    dtype = np.int64 if FloatFormat.parse(fmt).width <= 62 else object
    cols = list(zip(*rows)) if rows else [(), (), (), ()]
    return {key: np.asarray(col, dtype=dtype) for key, col in zip(("rn", "flags", "down", "up"), cols)}


def faithful(fmt, got, exact: dict) -> np.ndarray:
    """Which of the words ``got`` are faithful results: the correctly rounded one, or the
    other float around ``e**x``, except infinity when the correctly rounded one is finite
    (overflow must be exact)."""
    fmt = FloatFormat.parse(fmt)
    got = np.asarray(got, dtype=exact["rn"].dtype)
    inf = fmt.inf(0)
    other = ((got == exact["down"]) | (got == exact["up"])) & (got != inf)
    return (got == exact["rn"]) | other


def ulp_error(fmt, word: int, got: int) -> float:
    """``|got - e**x|`` in units of the spacing of the floats around ``e**x`` (of the subnormal
    spacing below ``2**emin``), for finite ``got`` and finite nonzero ``x``; ``e**x`` from
    :mod:`decimal` to about 40 digits, ample for a few significant digits of the error."""
    fmt = FloatFormat.parse(fmt)
    x = decode(fmt, word)
    d = Fraction(_context(max(40, fmt.precision // 3 + 20)).exp(_decimal(x)))
    top = d.numerator.bit_length() - d.denominator.bit_length()
    if Fraction(2) ** top > d:
        top -= 1
    spacing = Fraction(2) ** (max(top, fmt.emin) - fmt.frac_bits)
    return float(abs(decode(fmt, got) - d) / spacing)


# ------------------------------------------------------------------------- test inputs
def _ln_down(f: _Format, value: decimal.Decimal) -> tuple[int, int]:
    """The words just below and just above ``ln(value)`` (a positive decimal), signed."""
    ln = _context(f.p // 3 + 40).ln(value)
    num, den = abs(ln).as_integer_ratio()
    down = _round_ratio(f, num, den)[2]
    if ln < 0:  # the magnitude's floor is the word just above a negative x
        return (down + 1) | 1 << (f.width - 1), down | 1 << (f.width - 1)
    return down, down + 1


def directed_words(fmt) -> list[int]:
    """Inputs at the edges of ``exp``: specials and extreme words; the words around ``ln`` of
    the overflow threshold, of half the smallest subnormal (rounding to zero or not), of the
    smallest normal and of the tininess boundary below it; ``|x|`` around ``2**-(p+1)`` (the
    result leaves 1); ``x`` around ``j ln 2`` (results at powers of two) and ``(j + 1/2) ln 2``
    (where ``k = round(x / ln 2)`` changes) for ``j`` near 0 and near both ends of the range;
    and around ``+-2**i`` from ``2**-(p+3)`` to the end of the range and at the format's
    extremes."""
    f = _format(fmt)
    fmt = f.fmt
    sign = 1 << (f.width - 1)
    words = {0, sign, f.inf, f.inf | sign, fmt.canonical_nan, fmt.canonical_nan | sign, f.inf | 1,
             f.inf | 1 | sign, 1, 1 | sign, fmt.max_subnormal, fmt.max_subnormal | sign, fmt.min_normal,
             fmt.min_normal | sign, f.max_finite, f.max_finite | sign, f.one, f.one | sign}
    D = decimal.Decimal
    ctx = _context(f.p // 3 + 40)
    two = D(2)
    edges = [ctx.multiply(ctx.power(two, f.emax), 2 - ctx.power(two, -f.p)),    # overflow
             ctx.power(two, f.emin - f.m - 1),                                  # half the smallest subnormal
             ctx.power(two, f.emin),                                            # smallest normal
             ctx.multiply(ctx.power(two, f.emin), 1 - ctx.power(two, -f.p - 1))]  # tininess
    ln2 = ctx.ln(two)
    for j in list(range(-4, 5)) + [f.emax - 1, f.emax, f.emax + 1, f.emin - 1, f.emin, f.emin - f.m - 1]:
        edges += [ctx.exp(ctx.multiply(ln2, D(j))), ctx.exp(ctx.multiply(ln2, D(j) + D("0.5")))]
    for value in edges:
        if value > 0 and value != 1:
            below, above = _ln_down(f, value)
            words.update(w for c in (below, above) for w in range(c - 3, c + 4))
    top = (max(f.emax + 1, f.bias + f.m) * 7 // 10).bit_length()  # 2**top above the range's end
    for i in sorted({f.emin - f.m, f.emin, f.emax} | set(range(max(f.emin, -f.p - 3), min(f.emax, top) + 1))):
        word = _round_ratio(f, *(Fraction(2) ** i).as_integer_ratio())[0]
        words.update(w | s for w in (word - 1, word, word + 1) for s in (0, sign))
    return sorted(w for w in words if 0 <= w < 1 << f.width)


def random_words(fmt, n: int, rng) -> list[int]:
    """``n`` random inputs: a quarter uniform over all words (mostly far beyond the range:
    overflow, zero, NaN), the rest with a uniform exponent from ``2**-(p+3)`` to where
    ``e**x`` leaves the format, either sign, a uniform fraction."""
    f = _format(fmt)
    words = [int(w) for w in rng.integers(0, 1 << 62, size=n // 4, dtype=np.int64) >> max(0, 62 - f.width)]
    if f.width > 62:
        words = [w << (f.width - 62) | int(rng.integers(0, 1 << (f.width - 62))) for w in words]
    top = (max(f.emax + 1, f.bias + f.m) * 7 // 10).bit_length()  # 2**top above the range's end
    lo, hi = max(1, f.bias - f.p - 3), min(f.field_max - 1, f.bias + top)
    rest = n - len(words)
    fields = rng.integers(lo, hi + 1, size=rest)
    signs = rng.integers(0, 2, size=rest)
    fracs = rng.integers(0, 1 << 62, size=rest, dtype=np.int64)
    words += [int(s) << (f.width - 1) | int(e) << f.m | (int(m) >> max(0, 62 - f.m)) & f.frac_mask
              if f.m <= 62 else int(s) << (f.width - 1) | int(e) << f.m | (int(m) << (f.m - 62)) & f.frac_mask
              for s, e, m in zip(signs, fields, fracs)]
    return words
