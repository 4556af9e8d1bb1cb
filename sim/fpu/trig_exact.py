"""Exact reference for ``sin``, ``cos`` and ``atan2``: the true value bracketed by mpmath (a
multi-precision library, independent of the units' algorithms), and the floats around it.

mpmath evaluates at ``p + 40`` bits (its argument reduction for large ``x`` adds the bits it
needs); the value is taken as an interval four of its units wide and both ends are rounded to
the format with exact integer arithmetic (:mod:`.exp_exact`'s rounding); when they round
differently (a float or a rounding boundary inside), the precision is raised until they do.
Specials follow IEEE 754-2019 clause 9.2 (``atan2``'s signed zeros and infinities).

:func:`trig_exact_word` gives the correctly rounded word and flags and the floats just below
and just above the true value; a faithful result is one of those two (:func:`faithful`).
"""

from __future__ import annotations

from fractions import Fraction

import mpmath
import numpy as np

from kfgen.hdl.arith.float.format import FLAG_NV, FloatFormat
from kfgen.hdl.arith.float.trig_plan import _convergent_denominators, _two_over_pi_floor, trig_plan

from .exp_exact import _format, _round_ratio
from ..float_ref import decode

__all__ = ["trig_exact_word", "trig_exact", "faithful", "near_pi_half_words", "random_words"]


def _value(fn: str, a: Fraction, b: Fraction | None, prec: int):
    with mpmath.workprec(prec):
        x = mpmath.mpf(a.numerator) / a.denominator
        if fn == "sin":
            return mpmath.sin(x)
        if fn == "cos":
            return mpmath.cos(x)
        return mpmath.atan2(x, mpmath.mpf(b.numerator) / b.denominator)


def _exact_finite(f, fn, a: Fraction, b: Fraction | None):
    prec = f.p + 40
    while True:
        v = _value(fn, a, b, prec)
        man, exp = v.man_exp if v else (0, 0)  # |man|: the sign apart
        if man == 0:
            raise AssertionError("a transcendental result is never zero")
        # |v| within 4 units of its last bit: man (2**prec -+ 4) 2**(exp - prec), as num / den.
        shift = exp - prec
        scale, den = (1 << shift, 1) if shift >= 0 else (1, 1 << -shift)
        lo = _round_ratio(f, man * ((1 << prec) - 4) * scale, den)
        hi = _round_ratio(f, man * ((1 << prec) + 4) * scale, den)
        if lo == hi:
            sign = int(v < 0) << (f.width - 1)
            return lo[0] | sign, lo[1], lo[2] | sign, (lo[2] + 1) | sign
        prec += 32


def _pi_word(f, multiple: Fraction, sign: int):
    v = _value("atan2", Fraction(1), Fraction(1), f.p + 60) * 4 * multiple.numerator / multiple.denominator
    man, exp = v.man_exp
    word, flags, _ = _round_ratio(f, man * (1 << max(exp, 0)), 1 << max(-exp, 0))
    return word | sign << (f.width - 1), flags


def trig_exact_word(fn: str, fmt, a: int, b: int | None = None) -> tuple[int, int, int, int]:
    """``(rn, flags, down, up)`` of ``sin(a)``, ``cos(a)`` or ``atan2(a, b)``: the true value
    rounded to nearest with its flags, and the floats just below and just above it in
    magnitude (``rn`` for all three when exact). A NaN result is the canonical NaN with NV
    when it is invalid (an infinite ``sin`` or ``cos`` argument, a signalling NaN)."""
    f = _format(fmt)
    nan = f.fmt.canonical_nan

    def special(word, flags=0):
        return word, flags, word, word

    ka, va = _kind(f, a)
    if fn != "atan2":
        if ka == "nan":
            return special(nan, FLAG_NV if _signalling(f, a) else 0)
        if ka == "inf":
            return special(nan, FLAG_NV)
        if va == 0:
            return special(a if fn == "sin" else f.one)
        return _exact_finite(f, fn, va, None)
    kb, vb = _kind(f, b)
    if "nan" in (ka, kb):
        return special(nan, FLAG_NV if _signalling(f, a) or _signalling(f, b) else 0)
    sy, sx = a >> (f.width - 1), b >> (f.width - 1)
    if ka == "fin" and va == 0:
        if sx == 0:
            return special(a)
        return special(*_pi_word(f, Fraction(1), sy))
    if ka == "inf":
        multiple = Fraction(1, 2) if kb == "fin" else Fraction(3 if sx else 1, 4)
        return special(*_pi_word(f, multiple, sy))
    if kb == "fin" and vb == 0:
        return special(*_pi_word(f, Fraction(1, 2), sy))
    if kb == "inf":
        return special(sy << (f.width - 1)) if sx == 0 else special(*_pi_word(f, Fraction(1), sy))
    return _exact_finite(f, fn, va, vb)


def _kind(f, w: int):
    field, frac = w >> f.m & f.field_max, w & f.frac_mask
    if field == f.field_max:
        return ("nan" if frac else "inf"), None
    return "fin", decode(f.fmt, w)


def _signalling(f, w: int) -> bool:
    field, frac = w >> f.m & f.field_max, w & f.frac_mask
    return field == f.field_max and frac != 0 and not frac & f.fmt.quiet_bit


def trig_exact(fn: str, fmt, a, b=None) -> dict[str, np.ndarray]:
    """:func:`trig_exact_word` over arrays: ``rn``, ``flags``, ``down``, ``up``."""
    a = [int(w) for w in np.ravel(a)]
    b = [None] * len(a) if b is None else [int(w) for w in np.ravel(b)]
    rows = [trig_exact_word(fn, fmt, x, y) for x, y in zip(a, b)]
    dtype = np.int64 if FloatFormat.parse(fmt).width <= 62 else object
    cols = list(zip(*rows)) if rows else [(), (), (), ()]
    return {key: np.asarray(col, dtype=dtype) for key, col in zip(("rn", "flags", "down", "up"), cols)}


def faithful(got, exact: dict) -> np.ndarray:
    """Which words of ``got`` are faithful: the correctly rounded one or the other float
    around the true value."""
    got = np.asarray(got, dtype=exact["rn"].dtype)
    return (got == exact["rn"]) | (got == exact["down"]) | (got == exact["up"])


# ------------------------------------------------------------------------- test inputs
def near_pi_half_words(fmt, per_exponent: int = 2) -> list[int]:
    """The floats closest to multiples of ``pi/2``: for every exponent of the reduction's
    range, the significands of the best continued-fraction approximations of ``2**E 2/pi``
    (the inputs whose reduced angle is smallest), and their neighbours."""
    f = _format(fmt)
    plan = trig_plan(f.fmt)
    p, e_high = f.p, plan.range_bits - f.p
    q_bits = plan.range_bits + 3 * p + 96
    big = _two_over_pi_floor(q_bits + e_high + 2)
    words = set()
    for E in range(max(-p, plan.e_low), e_high + 1):
        alpha = (big >> (e_high + 2 - E)) & ((1 << q_bits) - 1)
        dens = _convergent_denominators(alpha, 1 << q_bits)
        for q in [d for d in dens if d < 1 << p][-per_exponent:]:
            # the multiples of the convergent that are p-bit significands
            for M in {q << max(0, (p - 1) - (q.bit_length() - 1))} | {q * j for j in range(1, 4)}:
                if 1 << (p - 1) <= M < 1 << p:
                    field = E + p - 1 + f.bias
                    if 0 < field < f.field_max:
                        w = field << f.m | (M & f.frac_mask)
                        words.update(x for x in (w - 1, w, w + 1))
    return sorted(words)


def random_words(fmt, n: int, rng, lo_exp: int, hi_exp: int) -> list[int]:
    """``n`` words of either sign with a uniform exponent in ``[lo_exp, hi_exp]`` (clipped to
    the normal range) and a uniform fraction."""
    f = _format(fmt)
    lo, hi = max(1, lo_exp + f.bias), min(f.field_max - 1, hi_exp + f.bias)
    fields = rng.integers(lo, hi + 1, size=n)
    signs = rng.integers(0, 2, size=n)
    fracs = [int.from_bytes(rng.bytes(16), "little") & f.frac_mask for _ in range(n)]
    return [int(s) << (f.width - 1) | int(e) << f.m | m for s, e, m in zip(signs, fields, fracs)]
