"""Exact reference model of the floating-point units in ``kfgen.hdl.arith.float``.

Every operation computes its result exactly with Python integers (a finite float is
``(-1)**s * m * 2**x``; sums and products of such numbers are exact integers after
alignment, a quotient or a square root is an integer with a remainder that becomes a
sticky bit) and rounds it once, with :func:`round_to_format`'s rules, to any
:class:`~kfgen.hdl.arith.float.format.FloatFormat`:

* round to nearest, ties to even; signed zeros; infinities; gradual underflow;
* tininess detected after rounding (the magnitude rounded to the format's precision with
  an unbounded exponent range is below ``2**emin``); UF when tiny and inexact;
* overflow to +-inf with OF|NX; every NaN result is the canonical quiet NaN;
* flags in RISC-V ``fflags`` order (NX, UF, OF, DZ, NV = bits 0..4);
* ``subnormals="ftz"``: subnormal inputs read as zeros of their sign (no flag), tiny
  results flush to zero of their sign with UF|NX.

Words are plain Python ints (the bit pattern, ``0 <= word < 2**fmt.width``). i2f takes
and f2i returns a 32-bit two's complement word (``0 .. 2**32 - 1``; i2f also accepts a
negative int32 value). ``tests/test_float_ref.py`` checks the model against numpy and
against an independent rounding of exact fractions.

:func:`random_operands` and :func:`directed_corpus` draw the operand sets that the
hardware testbenches feed both to the units and to :func:`ref_op`.
"""

from __future__ import annotations

from fractions import Fraction
from math import isqrt

import numpy as np

from kfgen.hdl.arith.float.exact import FormatConsts as _Consts
from kfgen.hdl.arith.float.exact import format_consts as _consts
from kfgen.hdl.arith.float.exact import round_magnitude as _round
from kfgen.hdl.arith.float.exact import round_to_format
from kfgen.hdl.arith.float.format import FLAG_DZ, FLAG_NV, FLAG_NX, FloatFormat

__all__ = ["OPS", "INT32_MIN", "INT32_MAX", "ref_op", "round_to_format", "decode",
           "random_operands", "directed_corpus", "conversion_sweep"]

#: Operations and their number of operands.
OPS = {"add": 2, "sub": 2, "mul": 2, "div": 2, "sqrt": 1, "fma": 3, "i2f": 1, "f2i": 1}
INT32_MIN, INT32_MAX = -(1 << 31), (1 << 31) - 1
_WORD32 = (1 << 32) - 1

# Operand classes returned by _unpack.
_FIN, _INF, _QNAN, _SNAN = 0, 1, 2, 3


def _unpack(k: _Consts, w: int, ftz: bool):
    """``(class, sign, m, x)``: a finite word is ``(-1)**sign * m * 2**x``."""
    s = w >> k.sshift & 1
    e = w >> k.fb & k.emask
    f = w & k.fmask
    if e == k.emask:
        if f == 0:
            return _INF, s, 0, 0
        return (_QNAN if f & k.qbit else _SNAN), s, 0, 0
    if e == 0:
        return _FIN, s, (0 if ftz else f), k.sub_exp
    return _FIN, s, f | k.hidden, e - k.bias - k.fb


def _nan(k, invalid):
    return k.nan, FLAG_NV if invalid else 0


def _sum(k, sa, ma, xa, sb, mb, xb, ftz):
    """Exact ``a + b`` of two finite values, rounded (also the fma's final addition)."""
    if mb == 0:
        if ma == 0:
            return (sa & sb) << k.sshift, 0  # -0 only from (-0) + (-0)
        return _round(k, sa, ma, xa, False, ftz)
    if ma == 0:
        return _round(k, sb, mb, xb, False, ftz)
    if xa > xb:
        ma <<= xa - xb
        xa = xb
    else:
        mb <<= xb - xa
    m = (-ma if sa else ma) + (-mb if sb else mb)
    if m > 0:
        return _round(k, 0, m, xa, False, ftz)
    if m < 0:
        return _round(k, 1, -m, xa, False, ftz)
    return 0, 0  # exact cancellation is +0 under RNE


def _add(k, a, b, c, ftz, negate=0):
    ka, sa, ma, xa = _unpack(k, a, ftz)
    kb, sb, mb, xb = _unpack(k, b, ftz)
    sb ^= negate
    if ka >= _QNAN or kb >= _QNAN:
        return _nan(k, ka == _SNAN or kb == _SNAN)
    if ka == _INF:
        if kb == _INF and sa != sb:
            return _nan(k, True)
        return sa << k.sshift | k.inf_mag, 0
    if kb == _INF:
        return sb << k.sshift | k.inf_mag, 0
    return _sum(k, sa, ma, xa, sb, mb, xb, ftz)


def _sub(k, a, b, c, ftz):
    return _add(k, a, b, c, ftz, 1)


def _mul(k, a, b, c, ftz):
    ka, sa, ma, xa = _unpack(k, a, ftz)
    kb, sb, mb, xb = _unpack(k, b, ftz)
    if ka >= _QNAN or kb >= _QNAN:
        return _nan(k, ka == _SNAN or kb == _SNAN)
    s = sa ^ sb
    if ka == _INF or kb == _INF:
        if (ka == _FIN and ma == 0) or (kb == _FIN and mb == 0):
            return _nan(k, True)
        return s << k.sshift | k.inf_mag, 0
    if ma == 0 or mb == 0:
        return s << k.sshift, 0
    return _round(k, s, ma * mb, xa + xb, False, ftz)


def _div(k, a, b, c, ftz):
    ka, sa, ma, xa = _unpack(k, a, ftz)
    kb, sb, mb, xb = _unpack(k, b, ftz)
    if ka >= _QNAN or kb >= _QNAN:
        return _nan(k, ka == _SNAN or kb == _SNAN)
    s = sa ^ sb
    if ka == _INF:
        if kb == _INF:
            return _nan(k, True)
        return s << k.sshift | k.inf_mag, 0
    if kb == _INF:
        return s << k.sshift, 0
    if mb == 0:
        if ma == 0:
            return _nan(k, True)
        return s << k.sshift | k.inf_mag, FLAG_DZ
    if ma == 0:
        return s << k.sshift, 0
    # Enough quotient bits for a guard bit and a round bit; the remainder is the sticky bit.
    sh = max(0, k.p + 2 + mb.bit_length() - ma.bit_length())
    q, r = divmod(ma << sh, mb)
    return _round(k, s, q, xa - xb - sh, r != 0, ftz)


def _sqrt(k, a, b, c, ftz):
    ka, sa, ma, xa = _unpack(k, a, ftz)
    if ka >= _QNAN:
        return _nan(k, ka == _SNAN)
    if ka == _INF:
        return _nan(k, True) if sa else (k.inf_mag, 0)
    if ma == 0:
        return sa << k.sshift, 0  # sqrt(-0) = -0
    if sa:
        return _nan(k, True)
    # Scale m by an even power of two (the exponent must halve exactly) until isqrt has
    # p + 2 bits; the remainder s*s != m is the sticky bit.
    sh = max(0, 2 * k.p + 3 - ma.bit_length())
    if (xa - sh) & 1:
        sh += 1
    m = ma << sh
    s = isqrt(m)
    return _round(k, 0, s, (xa - sh) >> 1, s * s != m, ftz)


def _fma(k, a, b, c, ftz):
    ka, sa, ma, xa = _unpack(k, a, ftz)
    kb, sb, mb, xb = _unpack(k, b, ftz)
    kc, sc, mc, xc = _unpack(k, c, ftz)
    zero_times_inf = ((ka == _INF and kb == _FIN and mb == 0)
                      or (kb == _INF and ka == _FIN and ma == 0))
    if ka >= _QNAN or kb >= _QNAN or kc >= _QNAN:
        # 0 * inf is invalid even when the addend is a quiet NaN (as RISC-V).
        return _nan(k, zero_times_inf or _SNAN in (ka, kb, kc))
    if zero_times_inf:
        return _nan(k, True)
    sp = sa ^ sb
    if ka == _INF or kb == _INF:
        if kc == _INF and sc != sp:
            return _nan(k, True)
        return sp << k.sshift | k.inf_mag, 0
    if kc == _INF:
        return sc << k.sshift | k.inf_mag, 0
    return _sum(k, sp, ma * mb, xa + xb, sc, mc, xc, ftz)


def _i2f(k, a, b, c, ftz):
    v = a & _WORD32
    if v >> 31:
        return _round(k, 1, (1 << 32) - v, 0, False, ftz)
    if v == 0:
        return 0, 0
    return _round(k, 0, v, 0, False, ftz)


def _f2i(k, a, b, c, ftz):
    ka, sa, ma, xa = _unpack(k, a, ftz)
    if ka >= _QNAN:
        return INT32_MAX, FLAG_NV
    if ka == _INF:
        return (INT32_MIN & _WORD32 if sa else INT32_MAX), FLAG_NV
    if xa >= 0:
        i = ma << xa
        inexact = False
    else:
        r = -xa
        i = ma >> r
        rem = ma & ((1 << r) - 1)
        half = 1 << (r - 1)
        if rem > half or (rem == half and i & 1):
            i += 1
        inexact = rem != 0
    if sa:
        i = -i
    # Out of range after rounding: saturate with NV alone (RISC-V fcvt.w).
    if i > INT32_MAX:
        return INT32_MAX, FLAG_NV
    if i < INT32_MIN:
        return INT32_MIN & _WORD32, FLAG_NV
    return i & _WORD32, FLAG_NX if inexact else 0


_FUNCS = {"add": _add, "sub": _sub, "mul": _mul, "div": _div, "sqrt": _sqrt, "fma": _fma,
          "i2f": _i2f, "f2i": _f2i}


def ref_op(op: str, fmt: FloatFormat, a: int, b: int | None = None, c: int | None = None,
           subnormals: str = "ieee") -> tuple[int, int]:
    """The exact result of one operation: ``(word, flags)``.

    Parameters
    ----------
    op : str
        One of :data:`OPS`: ``add`` (a + b), ``sub`` (a - b), ``mul``, ``div`` (a / b),
        ``sqrt`` (a), ``fma`` (a * b + c, one rounding), ``i2f``, ``f2i``.
    fmt : FloatFormat or str
        The float format of the operands and result (a name is parsed).
    a, b, c : int
        Operand words, as many as ``op`` takes. i2f's ``a`` is a 32-bit two's complement
        word (or a negative int32).
    subnormals : "ieee" or "ftz"

    Returns
    -------
    (word, flags)
        ``word`` in the format (f2i: a 32-bit two's complement word); ``flags`` the five
        RISC-V flags (bit 0 NX, 1 UF, 2 OF, 3 DZ, 4 NV).

    Raises
    ------
    ValueError
        Unknown op or subnormals mode, a missing or extra operand, or a word out of range.
    """
    fn = _FUNCS.get(op)
    if fn is None:
        raise ValueError(f"op must be one of {', '.join(OPS)}, not {op!r}")
    if subnormals == "ieee":
        ftz = False
    elif subnormals == "ftz":
        ftz = True
    else:
        raise ValueError(f"subnormals must be 'ieee' or 'ftz', not {subnormals!r}")
    k = _consts(fmt)
    arity = OPS[op]
    for i, (name, w) in enumerate((("a", a), ("b", b), ("c", c))):
        if i >= arity:
            if w is not None:
                raise ValueError(f"{op} takes {arity} operand(s); {name} must be None, not {w!r}")
        elif op == "i2f":
            if not isinstance(w, int) or not INT32_MIN <= w <= _WORD32:
                raise ValueError(f"i2f operand must be a 32-bit word or an int32, not {w!r}")
        elif not isinstance(w, int) or not 0 <= w < k.limit:
            raise ValueError(f"{op} operand {name} must be a {k.fmt.name} word "
                             f"(0 <= {name} < 2**{k.fmt.width}), not {w!r}")
    return fn(k, a, b, c, ftz)


def decode(fmt: FloatFormat, word: int):
    """The value of a word: a Fraction if finite (zeros lose their sign), else ``±inf`` or ``nan``."""
    k = _consts(fmt)
    kind, s, m, x = _unpack(k, word, False)
    if kind == _INF:
        return float("-inf") if s else float("inf")
    if kind != _FIN:
        return float("nan")
    v = Fraction(m) * Fraction(2) ** x
    return -v if s else v


# ------------------------------------------------------------------------- operand generators
def _encode(k: _Consts, s: int, top: int, f: int) -> int:
    """The word nearest below ``(1.f) * 2**top`` (clamped to max exponent; subnormal by truncation)."""
    if top > k.emax:
        top = k.emax
    if top >= k.emin:
        return s << k.sshift | (top + k.bias) << k.fb | f
    m = (k.hidden | f) >> min(k.emin - top, k.p)
    return s << k.sshift | (m or 1)


def _top(k: _Consts, w: int) -> int:
    """The binade of a finite nonzero word (subnormals count as ``emin``)."""
    return max(w >> k.fb & k.emask, 1) - k.bias


def _fractions(k: _Consts, n: int, rng) -> list[int]:
    """Fraction fields: uniform, and patterns that make ties, carries and exact results."""
    raw = rng.integers(0, 1 << 64, size=n, dtype=np.uint64, endpoint=False) >> np.uint64(64 - k.fb)
    f = [int(v) for v in raw]
    mode = rng.random(n)
    small = rng.integers(0, 8, size=n).tolist()
    shift = rng.integers(0, k.fb, size=n).tolist()
    for i in range(n):
        u = mode[i]
        if u < 0.55:
            continue
        if u < 0.65:
            f[i] = k.fmask & ~small[i]  # all ones: carries out of the significand
        elif u < 0.75:
            f[i] = small[i] & k.fmask  # near a power of two
        elif u < 0.85:
            f[i] = 1 << shift[i]  # one bit set
        else:
            f[i] &= ~((1 << shift[i]) - 1)  # trailing zeros: short significands, exact results
    return f


def _words(k: _Consts, n: int, rng, tops=None, specials: float = 1.0) -> list[int]:
    """``n`` words covering every class; ``tops`` (list) pins the binade of the finite ones."""
    cat = rng.random(n) / specials
    sign = rng.integers(0, 2, size=n).tolist()
    f = _fractions(k, n, rng)
    pick = rng.random(n)
    anywhere = rng.integers(k.emin, k.emax + 1, size=n).tolist()
    edge = rng.integers(0, 3, size=n).tolist()
    subshift = rng.integers(0, k.fb, size=n).tolist()
    out = []
    for i in range(n):
        u = cat[i]
        s = sign[i]
        if u < 0.03:
            w = s << k.sshift
        elif u < 0.06:
            w = s << k.sshift | k.inf_mag
        elif u < 0.08:
            w = s << k.sshift | k.inf_mag | k.qbit | f[i] >> 1
        elif u < 0.10:
            w = s << k.sshift | k.inf_mag | (f[i] >> 1 or 1)
        elif u < 0.18 and tops is None:
            w = s << k.sshift | (f[i] >> subshift[i] or 1)
        else:
            if tops is not None:
                top = tops[i]
            elif pick[i] < 0.1:
                top = k.emax - edge[i]
            elif pick[i] < 0.2:
                top = k.emin + edge[i]
            else:
                top = anywhere[i]
            w = _encode(k, s, top, f[i])
        out.append(w)
    return out


def _finite_nonzero(k: _Consts, w: int) -> bool:
    return w & ~(1 << k.sshift) != 0 and (w >> k.fb & k.emask) != k.emask


def _product_tops(k: _Consts, a: list[int], rng, divide: bool) -> list[int]:
    """Binades for b that put a*b (or a/b) at the overflow and underflow boundaries."""
    n = len(a)
    which = rng.integers(0, 4, size=n).tolist()
    near = rng.integers(-1, 2, size=n).tolist()
    deep = rng.integers(k.emin - k.p - 2, k.emin, size=n).tolist()
    anywhere = rng.integers(k.emin, k.emax + 1, size=n).tolist()
    tops = []
    for i in range(n):
        target = (k.emax + near[i], k.emin + near[i], deep[i], anywhere[i])[which[i]]
        ta = _top(k, a[i]) if _finite_nonzero(k, a[i]) else 0
        tb = ta - target if divide else target - ta
        tops.append(min(max(tb, k.emin - k.fb), k.emax))
    return tops


def _random_int32(n: int, rng) -> list[tuple[int]]:
    """int32 words across all magnitudes, with ties for the target precision likely."""
    bits = rng.integers(0, 32, size=n).tolist()
    raw = rng.integers(0, 1 << 32, size=n, dtype=np.uint64).tolist()
    sign = rng.integers(0, 2, size=n).tolist()
    special = rng.random(n)
    out = []
    for i in range(n):
        if special[i] < 0.02:
            v = (0, 1, -1, INT32_MIN, INT32_MAX)[raw[i] % 5]
        else:
            v = raw[i] >> (32 - bits[i]) if bits[i] else 0
            v |= (1 << (bits[i] - 1)) if bits[i] else 0  # exactly bits[i] significant bits
            if special[i] < 0.3 and bits[i] > 2:
                v = v >> 1 << 1 | 1  # odd: a tie whenever bits == p + 1
            if sign[i]:
                v = -v
        out.append((v & _WORD32,))
    return out


def random_operands(fmt: FloatFormat, n: int, rng: np.random.Generator,
                    op: str = "add") -> list[tuple[int, ...]]:
    """``n`` random operand sets (tuples of ``OPS[op]`` words) for ``op``.

    Every exponent range is drawn, not just uniform bit patterns: zeros, infinities,
    quiet and signalling NaNs (a few % each), subnormals, binades at the overflow and
    underflow boundaries, and fractions with all-ones, near-zero and short patterns. The
    second operand is often placed relative to the first: close exponents and near
    cancellation for add/sub, a product or quotient at the overflow/underflow boundary for
    mul/div/fma, and an fma addend close to ``-a*b``. sqrt gets negative operands and
    exact squares; f2i values around integers, halves and ``±2**31``; i2f int32 of every
    bit length.
    """
    if op not in OPS:
        raise ValueError(f"op must be one of {', '.join(OPS)}, not {op!r}")
    k = _consts(fmt)
    if op == "i2f":
        return _random_int32(n, rng)
    a = _words(k, n, rng)
    if op == "sqrt":
        neg = rng.random(n)
        root = rng.integers(1, 1 << min(k.p // 2, 62), size=n, dtype=np.int64).tolist()
        twice = rng.integers((k.emin - k.fb) // 2, k.emax // 2, size=n).tolist()
        out = []
        for i in range(n):
            w = a[i]
            if neg[i] < 0.1:
                w |= 1 << k.sshift
            elif neg[i] < 0.75:
                w &= ~(1 << k.sshift)
            elif neg[i] < 0.9:  # an exact square
                w = round_to_format(k.fmt, 0, Fraction(root[i] ** 2) * Fraction(4) ** twice[i])[0]
            out.append((w,))
        return out
    if op == "f2i":
        sign = rng.integers(0, 2, size=n).tolist()
        top = rng.integers(-2, 33, size=n).tolist()
        f = _fractions(k, n, rng)
        mode = rng.random(n)
        out = []
        for i in range(n):
            if mode[i] < 0.5:
                out.append((a[i],))
                continue
            frac = f[i]
            if 0 <= top[i] < k.fb and mode[i] < 0.85:
                cut = k.fb - top[i]  # fraction bits below the binary point
                frac = frac >> cut << cut  # an integer
                if mode[i] < 0.7:
                    frac |= 1 << (cut - 1)  # x.5 exactly
            out.append((_encode(k, sign[i], top[i], frac),))
        return out
    if op in ("add", "sub"):
        mode = rng.random(n)
        delta = rng.integers(-(k.p + 3), k.p + 4, size=n).tolist()
        tweak = rng.integers(-3, 4, size=n).tolist()
        tops = [_top(k, w) + d if _finite_nonzero(k, w) else d for w, d in zip(a, delta)]
        b = _words(k, n, rng, tops, specials=4.0)
        b_free = _words(k, n, rng)
        out = []
        for i in range(n):
            w = b[i]
            if mode[i] < 0.35:
                w = b_free[i]
            elif mode[i] < 0.55 and _finite_nonzero(k, a[i]):
                # |b| next to |a| with the sign that cancels (effective subtraction)
                mag = max(1, min((a[i] & ~(1 << k.sshift)) + tweak[i], k.inf_mag - 1))
                s = (a[i] >> k.sshift) ^ (op == "add")
                w = s << k.sshift | mag
            out.append((a[i], w))
        return out
    b_free = _words(k, n, rng)
    b_aimed = _words(k, n, rng, _product_tops(k, a, rng, op == "div"), specials=4.0)
    mode = rng.random(n)
    b = [b_free[i] if mode[i] < 0.4 else b_aimed[i] for i in range(n)]
    if op in ("mul", "div"):
        return list(zip(a, b))
    # fma: the addend is free, in the product's binade neighbourhood, or close to -a*b.
    delta = rng.integers(-(k.p + 3), k.p + 4, size=n).tolist()
    tops = [(_top(k, x) + _top(k, y) + d) if _finite_nonzero(k, x) and _finite_nonzero(k, y) else d
            for x, y, d in zip(a, b, delta)]
    c_near = _words(k, n, rng, [min(max(t, k.emin - k.fb), k.emax) for t in tops], specials=4.0)
    c_free = _words(k, n, rng)
    tweak = rng.integers(-2, 3, size=n).tolist()
    mode = rng.random(n)
    out = []
    for i in range(n):
        x, y = a[i], b[i]
        if mode[i] < 0.3:
            w = c_free[i]
        elif mode[i] < 0.75 or not (_finite_nonzero(k, x) and _finite_nonzero(k, y)):
            w = c_near[i]
        else:
            prod = _mul(k, x, y, None, False)[0]
            mag = prod & ~(1 << k.sshift)
            if mag >= k.inf_mag:
                w = c_near[i]
            else:
                mag = max(0, min(mag + tweak[i], k.inf_mag - 1))
                w = ((prod >> k.sshift) ^ 1) << k.sshift | mag
        out.append((x, y, w))
    return out


# ------------------------------------------------------------------------- directed corpus
def _exact(k: _Consts, value) -> int | None:
    """The word of an exactly representable value, else None (the case is dropped)."""
    v = Fraction(value)
    word, flags = round_to_format(k.fmt, int(v < 0), abs(v))
    return word if flags == 0 else None


def _neg(k: _Consts, w: int) -> int:
    return w ^ (1 << k.sshift)


def _special_words(k: _Consts, small: bool) -> list[int]:
    fmt = k.fmt
    one = k.bias << k.fb
    words = [0, fmt.min_subnormal, fmt.min_normal, one, fmt.max_finite, k.inf_mag, k.nan,
             k.inf_mag | 1]
    if not small:
        words += [fmt.max_subnormal, one | 1, fmt.min_normal | 1, (k.bias - 1) << k.fb | k.fmask,
                  fmt.max_finite - 1, k.nan | 1, k.inf_mag | (k.qbit - 1)]
    return words + [_neg(k, w) for w in words]


def directed_corpus(fmt: FloatFormat, op: str) -> list[tuple[int, ...]]:
    """Hand-picked operand sets for ``op`` (tuples of ``OPS[op]`` words).

    All pairs (triples for fma) of special operands (signed zeros, smallest and largest
    subnormals and normals, one and its neighbours, the largest finite, infinities, quiet
    and signalling NaNs), plus sets with exact halfway results, carries out of the
    significand on rounding, cancellation, results at the overflow boundary and at the
    underflow boundary on both sides of tininess-after-rounding, and fma products next
    to ``-c``. Cases a small format cannot represent are left out.
    """
    if op not in OPS:
        raise ValueError(f"op must be one of {', '.join(OPS)}, not {op!r}")
    k = _consts(fmt)
    F = Fraction
    u = F(1, 1 << k.fb)  # ulp of 1
    h = u / 2  # half an ulp of 1
    tiny = F(2) ** k.emin
    top = F(2) ** k.emax
    maxf = (2 - u) * top
    sub = tiny * u  # smallest subnormal
    cases = []

    def case(*values):
        words = [_exact(k, v) for v in values]
        if None not in words:
            cases.append(tuple(words))

    if op in ("add", "sub"):
        specials = _special_words(k, False)
        cases += [(x, y) for x in specials for y in specials]
        sgn = 1 if op == "add" else -1  # cases below are written as sums
        for x, y in [(1, h), (1 + u, h), (1, h * (1 + u)), (1, h * (1 - h)), (2 - u, h), (2 - u, u),
                     (-1, 1), (1 + u, -1), (1 + 2 * u, -(1 + u)), (2, -(2 - u)), (3, -(3 - 2 * u)),
                     (tiny, -sub), (tiny + sub, -tiny), (sub, sub), (tiny - sub, sub), (-sub, sub),
                     (maxf, top * h), (maxf, top * h * (1 - h)), (-maxf, -top * h),
                     (maxf, maxf), (top, top), (maxf, -maxf), (tiny * (1 + u), -tiny)]:
            case(x, sgn * y)
    elif op == "mul":
        specials = _special_words(k, False)
        cases += [(x, y) for x in specials for y in specials]
        for x, y in [(1 + u, F(3, 2)), (1 + u, 1 + u), (1 + u, 1 - h), (1 + u, 2 - 2 * u),
                     (3, 1 - h), (maxf, 2), (maxf, 1 + u),
                     (maxf, 1 - h), (top, 2), (-top, 2), (tiny, F(1, 2)), (tiny, 1 - h),
                     (tiny * (1 + u), 1 - u), (-tiny * (1 + u), 1 - u), (sub, F(1, 2)),
                     (3 * sub, F(1, 2)), (-sub, F(1, 2)), (sub, sub), (-sub, sub), (sub, F(3, 2)),
                     (tiny, 1 - u), (sub * (2 ** k.fb - 1), 1 + u)]:
            case(x, y)
    elif op == "div":
        specials = _special_words(k, False)
        cases += [(x, y) for x in specials for y in specials]
        for x, y in [(1, 3), (2, 3), (-1, 3), (1, 1 + u), (1 + u, 1 + u), (1, 1 - h), (maxf, F(1, 2)),
                     (maxf, 1 - h), (maxf, 1), (top, F(1, 2)), (tiny, 2), (sub, 2), (3 * sub, 2),
                     (-sub, 2), (tiny, 1 + u), (tiny * (1 + u), 1 + u), (1, maxf), (sub, maxf),
                     (tiny, 3), (maxf, tiny), (sub, 3)]:
            case(x, y)
    elif op == "sqrt":
        cases += [(w,) for w in _special_words(k, False)]
        for x in [4, 9, 2, 3, F(1, 4), 1 + u, 1 - h, (1 + F(2) ** -(k.fb // 2)) ** 2, 2 * tiny,
                  tiny * 4, sub, 2 * sub, 4 * sub, maxf, top, -1, -sub, -maxf, (1 + F(1, 4)) ** 2,
                  (2 ** k.fb - 1) ** 2]:
            case(x)
    elif op == "fma":
        specials = _special_words(k, True)
        cases += [(x, y, z) for x in specials for y in specials for z in specials]
        i = k.p // 2
        j = k.p - i
        # Products at an exact tie, scaled so that a nudge of 2**-2p is representable.
        scale = F(2) ** max(0, k.emin + 2 * k.p + 1)
        for z in (0, scale ** 2 * F(2) ** (-2 * k.p), -scale ** 2 * F(2) ** (-2 * k.p)):
            case((1 + F(2) ** -i) * scale, (1 + F(2) ** -j) * scale, z)
        for x, y, z in [(1 + u, 1 - u, -1), (1 + u, 1 + u, -(1 + 2 * u)), (1 + u, 1 + u, -1),
                        (1 - h, 1 - h, -1), (2 - u, 2 - u, -4), (3, 1 - h, -3),
                        (maxf, 1, maxf), (maxf, 2, -maxf), (maxf, 1 + u, -maxf), (-maxf, 2, maxf),
                        (tiny, 1 - h, 0), (tiny, F(1, 2), 0), (-tiny, F(1, 2), 0),
                        (tiny * (1 + u), 1 - u, 0), (sub, F(1, 2), 0), (sub, sub, 0),
                        (tiny, 1, -tiny * (1 - u)), (tiny * 2, F(1, 2), -tiny),
                        (1, 1, -1), (-1, 1, 1), (0, 5, 0), (0, -5, 0), (2, 3, -6),
                        (1 + u, 1 + u, -(1 + 2 * u) * (1 + u))]:
            case(x, y, z)
        cases += [(0, 0, _neg(k, 0)), (_neg(k, 0), k.bias << k.fb, _neg(k, 0)),
                  (0, _neg(k, k.bias << k.fb), _neg(k, 0)), (0, k.inf_mag, k.nan),
                  (k.inf_mag, 0, k.nan), (k.inf_mag, k.bias << k.fb, _neg(k, k.inf_mag))]
    elif op == "i2f":
        vals = [0, 1, -1, 2, 3, INT32_MAX, INT32_MIN, INT32_MIN + 1, 1000, -1000]
        for e in range(k.p, 32):
            base, ulp, half = 1 << e, 1 << (e - k.p + 1), 1 << (e - k.p)
            # ties to even (down, then up from an odd significand), just off a tie, carries
            vals += [base - 1, base + 1, base + half, base + ulp + half, base + half + 1,
                     base + half - 1, 2 * base - half, 2 * base - half - 1, -(base + half),
                     -(base + ulp + half)]
        edge = maxf + top * h  # the overflow threshold (a tie above the largest finite)
        if edge <= INT32_MAX and edge.denominator == 1:
            vals += [int(maxf), int(edge) - 1, int(edge), int(edge) + 1, -int(edge)]
        cases += [(v & _WORD32,) for v in vals if INT32_MIN <= v <= INT32_MAX]
    else:  # f2i
        cases += [(w,) for w in _special_words(k, False)]
        for x in [F(1, 2), F(-1, 2), F(3, 2), F(-3, 2), F(5, 2), F(-5, 2), F(1, 4), F(3, 4), F(-3, 4),
                  1 - h, 1 + u, 7, -7, INT32_MAX, INT32_MAX - F(1, 2), 1 << 31, -(1 << 31),
                  -(1 << 31) - F(1, 2), -(1 << 31) - 1, (1 << 30) + F(1, 2), 2 ** k.p,
                  2 ** k.p - F(1, 2), F(2 ** k.p - 1, 2), (1 << 31) - (1 << 7), (1 << 31) + (1 << 8),
                  -(1 << 31) - (1 << 8)]:
            case(x)
    return list(dict.fromkeys(cases))


# ------------------------------------------------------------------------- conversion sweeps
def _window(centre: int, radius: int) -> range:
    return range(centre - radius, centre + radius + 1)


def conversion_sweep(fmt: FloatFormat, op: str, radius: int = 3) -> list[tuple[int]]:
    """Operands at every rounding and range boundary of a conversion, systematically.

    ``i2f``: for every integer length from 1 to 32 bits and both signs, the ``radius``
    integers on either side of the binade's ends, and (where the integer has more bits than
    the significand) of the ties and of their neighbours above and below for the smallest,
    an odd, an even and the largest significand of the binade; plus the overflow threshold of
    a format whose largest finite number is below 2**31.
    ``f2i``: for every binade from 2**-3 to 2**33 and both signs, the ``radius`` words on
    either side of the binade's ends and of the words nearest ``n + 1/2`` for integers ``n``
    at the binade's ends (ties to even both ways and their neighbours), and the words around
    +-(2**31 - 1/2), +-2**31 and -(2**31 + 1/2), where the saturation starts.
    Words outside the format or int32 are dropped; the list has no repeats.
    """
    if op not in ("i2f", "f2i"):
        raise ValueError(f"op must be 'i2f' or 'f2i', not {op!r}")
    k = _consts(fmt)
    out = []
    if op == "i2f":
        vals = set()
        for bits in range(1, 33):
            lo, hi = 1 << (bits - 1), (1 << bits) - 1
            vals.update(_window(lo, radius))
            vals.update(_window(hi, radius))
            drop = bits - k.p  # integer bits below the significand
            if drop > 0:
                half = 1 << (drop - 1)
                for sig in (k.hidden, k.hidden + 1, k.hidden + 2, 2 * k.hidden - 1):
                    vals.update(_window((sig << drop) + half, radius))
        maxf = fmt.max_finite
        if _top(k, maxf) < 31:
            edge = (((k.hidden << 1) - 1) << 1 | 1) << (_top(k, maxf) - k.p)  # largest + half ulp
            vals.update(_window(edge, radius))
        vals = sorted({v for v in (s * x for s in (1, -1) for x in vals) if INT32_MIN <= v <= INT32_MAX})
        out = [(v & _WORD32,) for v in vals]
    else:
        words = set()

        def around(value):
            if abs(value) >= Fraction(2) ** (k.emax + 1):
                return
            w, _ = round_to_format(fmt, int(value < 0), abs(value))
            mag, sign = w & ~(1 << k.sshift), w >> k.sshift
            for m in _window(mag, radius):
                if 0 <= m < k.inf_mag:
                    words.add(sign << k.sshift | m)

        for e in range(-3, 34):
            lo, hi = Fraction(2) ** e, Fraction(2) ** (e + 1)
            for sign in (1, -1):
                around(sign * lo)
                around(sign * hi * (1 - Fraction(1, 1 << k.p)))
                for n in {int(lo), int(hi) - 1}:
                    around(sign * (n + Fraction(1, 2)))
        for v in (Fraction(2 ** 31) - Fraction(1, 2), Fraction(2 ** 31), -Fraction(2 ** 31),
                  -Fraction(2 ** 31) - Fraction(1, 2), -Fraction(2 ** 31) - 1):
            around(v)
        out = [(w,) for w in sorted(words)]
    return out
