"""Bit-exact golden model of the exponential unit :class:`kfgen.hdl.arith.float.exp.FloatExp`.

The unit's integer arithmetic stage by stage, vectorised over numpy arrays of words: the same
truncations, tables and constants (read from :func:`~kfgen.hdl.arith.float.exp_plan.exp_plan`),
then the shared rounding stage's rules (round to nearest even, tininess after rounding,
gradual underflow or ftz, overflow to infinity). Arrays are ``int64`` when every intermediate
value fits 62 bits (binary16, bfloat16, binary32) and Python integers (``object``) otherwise.

:func:`exp_model` is what the hardware must give bit for bit and flag for flag; how close it is
to ``e**x`` is checked separately against the exact reference :mod:`.exp_exact`.
"""

from __future__ import annotations

import numpy as np

from kfgen.hdl.arith.float.exp_plan import CHUNK, exp_plan
from kfgen.hdl.arith.float.format import FLAG_NV, FLAG_NX, FLAG_OF, FLAG_UF, FloatFormat

__all__ = ["exp_model", "round_vector"]


def _shift(v, amount: int):
    """``floor(v * 2**amount)`` for a constant ``amount`` of either sign."""
    return v << amount if amount >= 0 else v >> -amount


def _index(v):
    """``v`` as an array of indices (an object array of small Python integers converts)."""
    return v.astype(np.int64)


def _word(value: int, like):
    """A constant for ``np.where`` beside ``like``: as an object array when ``like`` is one
    (numpy would try a C integer for a Python int, and a word may not fit one)."""
    return np.asarray(value, dtype=object) if like.dtype == object else value


def _largest_width(plan) -> int:
    """The widest intermediate value, in bits (to pick the array type)."""
    fmt, p = plan.fmt, plan.fmt.precision
    widths = [fmt.width, plan.int_bits + plan.frac_bits + 1,
              plan.int_bits + plan.k_frac + plan.inv_ln2_bits + 2,
              plan.t_bits + 1 + plan.q_bits - plan.index_bits + 1, plan.work_bits + p + 4]
    h_max = plan.coeff_top
    for z_bits, _, _, largest in plan.steps:
        widths.append(z_bits - plan.index_bits + h_max.bit_length())
        h_max = largest
    if plan.steps:
        widths.append(plan.q_z_bits - plan.index_bits + h_max.bit_length())
    return max(widths)


def round_vector(fmt: FloatFormat, sig, width: int, top, sticky, ftz: bool):
    """Round the values ``(sig + t) * 2**(top - width + 1)``, ``sig`` of ``width`` bits with
    its top bit set, ``0 < t < 1`` where ``sticky`` (else ``t = 0``), to ``fmt``: ``(word,
    flags)``. Round to nearest even; tiny after rounding (below ``2**emin`` rounded to ``p``
    bits with an unbounded exponent); UF when tiny and inexact, or flushed (``ftz``);
    overflow to infinity with OF|NX."""
    p, m = fmt.precision, fmt.frac_bits
    one = sig.dtype.type(1) if sig.dtype != object else 1
    room = top - fmt.emin                        # >= 0: a normal (or overflowing) result
    below = np.minimum(np.maximum(-room, 0), width + 1)  # the further shift of a subnormal
    drop = (width - p) + below                   # bits under the kept ones, >= 2
    keep = sig >> np.minimum(drop, width)
    keep = np.where(drop >= width + 1, 0, keep)  # (a shift by the width leaves nothing)
    round_bit = np.where(drop - 1 < width, (sig >> np.minimum(drop - 1, width - 1)) & one, 0)
    low_mask = (one << np.minimum(drop - 1, width)) - one
    rest = ((sig & low_mask) != 0) | sticky
    up = (round_bit == 1) & (rest | ((keep & one) == 1))
    mant = keep + up.astype(np.int64 if sig.dtype != object else object)
    inexact = (round_bit == 1) | rest
    # Normal: the field is top + bias, plus one when the rounding carries (mant = 2**p); a
    # subnormal's mant is its whole magnitude (a carry into the hidden bit makes it normal).
    normal = room >= 0
    carry = mant >> p
    field = np.where(normal, top + fmt.bias + carry, 0)
    frac = np.where(normal, np.where(carry == 1, 0, mant & fmt.frac_mask), 0)
    magnitude = np.where(normal, (field << m) | frac, mant)
    overflow = normal & (field >= fmt.exp_max_field)
    # Tiny after rounding: below 2**(emin - 1), or in [2**(emin-1), 2**emin) without the p + 1
    # top bits all ones (which round up to 2**emin at full precision).
    all_ones = (sig >> (width - p - 1)) == (one << (p + 1)) - one
    tiny = (room <= -2) | ((room == -1) & ~all_ones)
    word = np.where(overflow, _word(fmt.inf(0), sig), magnitude)
    flags = np.where(overflow, FLAG_OF | FLAG_NX,
                     np.where(inexact, FLAG_NX, 0) | np.where(tiny & inexact, FLAG_UF, 0))
    if ftz:
        word = np.where(tiny, 0, word)
        flags = np.where(tiny, FLAG_UF | FLAG_NX, flags)
    return word, flags


def exp_model(fmt, words, subnormals: str = "ieee"):
    """``exp`` of each word of ``fmt`` as the unit computes it: ``(words, flags)`` as int64
    arrays (Python integers in an object array for formats wider than 62 bits).

    Parameters
    ----------
    fmt : FloatFormat or str
    words : array-like of int
        Operand words, ``0 <= w < 2**fmt.width``.
    subnormals : "ieee" or "ftz"
    """
    fmt = FloatFormat.parse(fmt)
    if subnormals not in ("ieee", "ftz"):
        raise ValueError(f"subnormals must be 'ieee' or 'ftz', not {subnormals!r}")
    plan = exp_plan(fmt)
    dtype = np.int64 if _largest_width(plan) <= 62 else object
    w = np.asarray([int(x) for x in np.ravel(words)], dtype=dtype) if dtype is object \
        else np.asarray(words, dtype=np.int64).ravel()
    if w.size and (int(w.min()) < 0 or int(w.max()) >= 1 << fmt.width):
        raise ValueError(f"words must be {fmt.name} words (0 <= w < 2**{fmt.width})")
    p, m = fmt.precision, fmt.frac_bits
    I, F, G, a = plan.int_bits, plan.frac_bits, plan.work_bits, plan.index_bits

    sign = (w >> (fmt.width - 1)) & 1
    field = (w >> m) & fmt.exp_max_field
    frac = w & fmt.frac_mask
    is_nan = (field == fmt.exp_max_field) & (frac != 0)
    is_inf = (field == fmt.exp_max_field) & (frac == 0)
    is_snan = is_nan & ((frac & fmt.quiet_bit) == 0)
    if subnormals == "ftz":
        sig = np.where(field == 0, 0, frac | (1 << m))
    else:
        sig = np.where(field == 0, frac, frac | (1 << m))
    exp = np.maximum(field, 1) - fmt.bias
    big = exp >= I

    # X = floor(|x| 2**F): the significand at the top of I + F bits, shifted right.
    right = np.minimum(np.maximum(I - 1 - exp, 0), I + F)
    x_fixed = (sig << (I + F - p)) >> right
    # k = round(X / ln 2)
    xt = x_fixed >> (F - plan.k_frac)
    shift = plan.k_frac + plan.inv_ln2_bits
    k = (xt * plan.inv_ln2 + (1 << (shift - 1))) >> shift
    # k ln 2 modulo 1, and r
    mask = (1 << F) - 1
    k_ln2 = 0
    for i, table in enumerate(plan.ln2_tables):
        k_ln2 = k_ln2 + np.asarray(table, dtype=dtype)[_index((k >> (CHUNK * i)) & (len(table) - 1))]
    k_ln2 = k_ln2 & mask
    x_frac = x_fixed & mask
    r = np.where(sign == 1, k_ln2 - x_frac, x_frac - k_ln2) & mask
    index = r >> (F - a)
    z = r & ((1 << (F - a)) - 1)

    t = np.asarray(plan.table, dtype=dtype)[_index(index)]
    if plan.degree == 1:
        q = _shift(z, plan.q_bits - F)
    else:
        h, h_bits = plan.coeff_top, plan.coeff_top_bits
        for z_bits, bits, const, _ in plan.steps:
            h = const + _shift(_shift(z, z_bits - F) * h, bits - z_bits - h_bits)
            h_bits = bits
        q = _shift(z, plan.q_bits - F) + _shift(_shift(z, plan.q_z_bits - F) * h,
                                                plan.q_bits - plan.q_z_bits - h_bits)
    y = t + _shift(_shift(t, plan.t_bits - G) * q, G - plan.t_bits - plan.q_bits)

    top_one = (y >> G) & 1
    sig_y = np.where(top_one == 1, y, y << 1)
    k_signed = np.where(sign == 1, -k, k)
    k_signed = np.where(big, np.where(sign == 1, plan.k_under, plan.k_over), k_signed)
    top = k_signed - 1 + top_one
    nonzero = sig != 0
    word, flags = round_vector(fmt, sig_y, G + 1, top, nonzero, subnormals == "ftz")

    # NaN: the canonical NaN (NV if signalling); e**+inf = +inf, e**-inf = +0, exactly.
    inf, nan = _word(fmt.inf(0), w), _word(fmt.canonical_nan, w)
    word = np.where(is_nan, nan, np.where(is_inf, np.where(sign == 1, 0, inf), word))
    flags = np.where(is_nan, np.where(is_snan, FLAG_NV, 0), np.where(is_inf, 0, flags))
    if dtype is not object:
        return word.astype(np.int64), flags.astype(np.int64)
    return word, flags.astype(np.int64)
