"""The exact floating-point reference (kfgen.sim.float_ref) against independent oracles.

* numpy for binary16/32/64 add, sub, mul, div, sqrt: results bit for bit, and the flags numpy
  reports reliably (overflow, divide by zero, invalid). numpy reports no inexact flag, and its
  underflow is not usable here: on this platform it reports tininess before rounding for mul and
  nothing at all for some inexact subnormal quotients.
* An exact rounding of Python Fractions written out literally from the IEEE-754 rules (below),
  for every flag, in five formats, both subnormal modes, including fma.
* A check that each sqrt result lies within half an ulp of the true root (exact squares).
* numpy int32 -> float casts and numpy.rint for i2f/f2i.
* Hand-worked cases (all five flags, tininess after rounding, signed zeros, fma double rounding,
  bfloat16, e6m11, ftz) whose expected words were derived by hand; the derivation is in the
  comments.
"""

import struct
import zlib
from fractions import Fraction

import numpy as np
import pytest

from kfgen.hdl.arith.float.format import FLAG_NV, FLAG_NX, FloatFormat
from kfgen.sim.float_ref import (OPS, conversion_sweep, decode, directed_corpus, random_operands, ref_op,
                                 round_to_format)

NX, UF, OF, DZ, NV = 1, 2, 4, 8, 16
B16, BF16, B32, B64, E6M11 = (FloatFormat.parse(n) for n in
                              ("binary16", "bfloat16", "binary32", "binary64", "e6m11"))
ALL_FORMATS = [B16, BF16, B32, B64, E6M11]
NUMPY = {B16: (np.float16, np.uint16), B32: (np.float32, np.uint32), B64: (np.float64, np.uint64)}
NUMPY_OPS = {"add": np.add, "sub": np.subtract, "mul": np.multiply, "div": np.divide, "sqrt": np.sqrt}
MASK32 = (1 << 32) - 1


def operand_sets(fmt, op, n, *seed):
    """Random sets (seeded from ``seed``, stable across runs) followed by the directed corpus."""
    rng = np.random.default_rng(zlib.crc32(repr((fmt.name, op) + seed).encode()))
    return random_operands(fmt, n, rng, op) + directed_corpus(fmt, op)


def is_nan(fmt, w):
    e = w >> fmt.frac_bits & ((1 << fmt.exp_bits) - 1)
    return e == (1 << fmt.exp_bits) - 1 and w & ((1 << fmt.frac_bits) - 1) != 0


def show(fmt, sets, got, want, bad):
    digits = (fmt.width + 3) // 4
    lines = [f"{' '.join(f'{w:0{digits}x}' for w in sets[i])}: got {got[i][0]:x}/{got[i][1]:05b} "
             f"want {want[i][0]:x}/{want[i][1]:05b}" for i in bad[:8]]
    return f"{len(bad)} of {len(sets)} differ ({fmt.name}):\n" + "\n".join(lines)


# --------------------------------------------------------------------------------- numpy
@pytest.mark.parametrize("op", list(NUMPY_OPS))
@pytest.mark.parametrize("fmt", [B16, B32, B64], ids=lambda f: f.name)
def test_against_numpy(fmt, op):
    ftype, utype = NUMPY[fmt]
    sets = operand_sets(fmt, op, 4000)
    got = [ref_op(op, fmt, *s) for s in sets]
    cols = [np.array(col, dtype=utype).view(ftype) for col in zip(*sets)]
    with np.errstate(all="ignore"):
        y = NUMPY_OPS[op](*cols).view(utype).tolist()
    bad = [i for i, (w, _) in enumerate(got)
           if not (w == y[i] or (is_nan(fmt, w) and is_nan(fmt, y[i])))]
    assert not bad, show(fmt, sets, got, [(y[i], got[i][1]) for i in range(len(sets))], bad)
    assert all(w == fmt.canonical_nan for w, _ in got if is_nan(fmt, w))

    # Flags one operation at a time: numpy calls back once per error kind it saw. Only OF, DZ
    # and NV are compared (the reference's NX and UF bits are copied into the expectation).
    seen = []
    old = np.seterrcall(lambda kind, flag: seen.append(kind))
    want = []
    try:
        with np.errstate(all="call"):
            for i in range(len(sets)):
                seen.clear()
                NUMPY_OPS[op](*(c[i] for c in cols))
                numpy_flags = ((OF if "overflow" in seen else 0) | (DZ if "divide by zero" in seen else 0)
                               | (NV if "invalid value" in seen else 0))
                want.append((y[i], got[i][1] & (NX | UF) | numpy_flags))
    finally:
        np.seterrcall(old)
    bad = [i for i in range(len(sets)) if got[i][1] != want[i][1]]
    assert not bad, show(fmt, sets, got, want, bad)


# ------------------------------------------------------- independent exact rounding of Fractions
def value_of(fmt, w, ftz=False):
    """``(sign, Fraction)`` of a finite word, or None for inf/NaN (written from the layout)."""
    sign = w >> (fmt.width - 1) & 1
    e = w >> fmt.frac_bits & ((1 << fmt.exp_bits) - 1)
    f = w & ((1 << fmt.frac_bits) - 1)
    if e == (1 << fmt.exp_bits) - 1:
        return None
    if e == 0:
        return sign, Fraction(0) if ftz else Fraction(f) * Fraction(2) ** (1 - fmt.bias - fmt.frac_bits)
    return sign, (1 + Fraction(f, 1 << fmt.frac_bits)) * Fraction(2) ** (e - fmt.bias)


def rne(y: Fraction) -> int:
    """The integer nearest ``y``, ties to the even one."""
    n = y.numerator // y.denominator
    d = y - n
    return n + (d > Fraction(1, 2) or (d == Fraction(1, 2) and n % 2 == 1))


def binade(m: Fraction) -> int:
    """``e`` with ``2**e <= m < 2**(e + 1)``."""
    e = m.numerator.bit_length() - m.denominator.bit_length()
    return e - 1 if Fraction(2) ** e > m else e


def round_exact(fmt, x: Fraction, zero_sign=0, ftz=False):
    """IEEE-754 round-to-nearest-even of the exact ``x``, tininess after rounding, as words and flags."""
    top = fmt.width - 1
    if x == 0:
        return zero_sign << top, 0
    sign, m = int(x < 0), abs(x)
    emin, emax, fb = 1 - fmt.bias, fmt.bias, fmt.frac_bits
    e = binade(m)
    unbounded = rne(m / Fraction(2) ** (e - fb)) * Fraction(2) ** (e - fb)
    if unbounded >= Fraction(2) ** (emax + 1):
        return sign << top | ((1 << fmt.exp_bits) - 1) << fb, OF | NX
    tiny = unbounded < Fraction(2) ** emin
    if tiny and ftz:
        return sign << top, UF | NX
    quantum = Fraction(2) ** (max(e, emin) - fb)
    y = rne(m / quantum) * quantum
    inexact = y != m
    if y == 0:
        word = 0
    elif y < Fraction(2) ** emin:
        word = int(y / Fraction(2) ** (emin - fb))
    else:
        ey = binade(y)
        word = (ey + fmt.bias) << fb | (int(y / Fraction(2) ** (ey - fb)) - (1 << fb))
    return sign << top | word, (NX | (UF if tiny else 0)) if inexact else 0


def exact_expected(fmt, op, s, ftz):
    """Expected (word, flags) for operand words ``s`` that are all finite, or None otherwise."""
    if op == "i2f":
        v = s[0] - (1 << 32) if s[0] >> 31 else s[0]
        return round_exact(fmt, Fraction(v))
    vals = [value_of(fmt, w, ftz) for w in s]
    if None in vals:
        return None
    signed = [-v if sg else v for sg, v in vals]
    (sa, va), (sb, vb) = vals[0], vals[1]
    if op in ("add", "sub"):
        if op == "sub":
            sb ^= 1
            signed[1] = -signed[1]
        both_zero = va == 0 and vb == 0
        return round_exact(fmt, signed[0] + signed[1], sa & sb if both_zero else 0, ftz)
    if op == "mul":
        return round_exact(fmt, signed[0] * signed[1], sa ^ sb, ftz)
    if op == "div":
        if vb == 0:
            if va == 0:
                return fmt.canonical_nan, NV
            return (sa ^ sb) << (fmt.width - 1) | ((1 << fmt.exp_bits) - 1) << fmt.frac_bits, DZ
        return round_exact(fmt, signed[0] / signed[1], sa ^ sb, ftz)
    sc, vc = vals[2]  # fma: the addends are the exact product and c
    prod = signed[0] * signed[1]
    zero_sign = (sa ^ sb) & sc if prod == 0 and vc == 0 else 0
    return round_exact(fmt, prod + signed[2], zero_sign, ftz)


@pytest.mark.parametrize("subnormals", ["ieee", "ftz"])
@pytest.mark.parametrize("op", ["add", "sub", "mul", "div", "fma", "i2f"])
@pytest.mark.parametrize("fmt", ALL_FORMATS, ids=lambda f: f.name)
def test_against_exact_fractions(fmt, op, subnormals):
    ftz = subnormals == "ftz"
    sets = operand_sets(fmt, op, 600 if ftz else 1200, "fractions")
    checked, got, want = [], [], []
    for s in sets:
        expected = exact_expected(fmt, op, s, ftz)
        if expected is not None:
            checked.append(s)
            got.append(ref_op(op, fmt, *s, subnormals=subnormals))
            want.append(expected)
    assert len(checked) > 300
    bad = [i for i in range(len(checked)) if got[i] != want[i]]
    assert not bad, show(fmt, checked, got, want, bad)


@pytest.mark.parametrize("fmt", ALL_FORMATS, ids=lambda f: f.name)
def test_sqrt_within_half_ulp(fmt):
    """A result r of sqrt(x > 0) lies between the midpoints to its neighbours (nearest, ties even)."""
    sets = operand_sets(fmt, "sqrt", 2000)
    inf = ((1 << fmt.exp_bits) - 1) << fmt.frac_bits
    checked = 0
    for (a,) in sets:
        va = value_of(fmt, a)
        if va is None or va[1] == 0 or va[0]:
            continue
        x = va[1]
        r, flags = ref_op("sqrt", fmt, a)
        assert 0 < r < inf, hex(a)
        y = value_of(fmt, r)[1]
        below = value_of(fmt, r - 1)[1]
        above = value_of(fmt, r + 1)[1] if r + 1 < inf else Fraction(2) ** (fmt.bias + 1)
        lo, hi = ((below + y) / 2) ** 2, ((y + above) / 2) ** 2
        assert lo <= x <= hi, hex(a)
        if x in (lo, hi):  # a tie goes to the even significand
            assert r & 1 == 0, hex(a)
        assert flags == (NX if y * y != x else 0), hex(a)
        checked += 1
    assert checked > 800


# ----------------------------------------------------------------------------- conversions
@pytest.mark.parametrize("fmt", [B16, B32, B64], ids=lambda f: f.name)
def test_i2f_against_numpy(fmt):
    ftype, utype = NUMPY[fmt]
    words = [w for (w,) in operand_sets(fmt, "i2f", 4000)]
    ints = np.array(words, dtype=np.uint32).view(np.int32)
    with np.errstate(all="ignore"):
        y = ints.astype(ftype)
    for w, i, v in zip(words, ints.tolist(), y):
        want = (OF | NX) if np.isinf(v) else (NX if int(v) != i else 0)
        assert ref_op("i2f", fmt, w) == (int(v.view(utype)), want), i


@pytest.mark.parametrize("fmt", [B16, B32, B64], ids=lambda f: f.name)
def test_f2i_against_rint(fmt):
    ftype, utype = NUMPY[fmt]
    words = [w for (w,) in operand_sets(fmt, "f2i", 4000)]
    with np.errstate(all="ignore"):  # signalling NaNs
        x = np.array(words, dtype=utype).view(ftype).astype(np.float64)
        r = np.rint(x)
    for w, xi, ri in zip(words, x.tolist(), r.tolist()):
        if xi != xi or ri > 2**31 - 1:
            want = (2**31 - 1, NV)
        elif ri < -2**31:
            want = (2**31, NV)
        else:
            want = (int(ri) & MASK32, NX if ri != xi else 0)
        assert ref_op("f2i", fmt, w) == want, hex(w)


# ------------------------------------------------------------------------------ hand-worked
# (format, op, operands, subnormals, word, flags). Words are derived by hand in the comments.
HAND = [
    # binary32: 1 = 3f800000; 2**-24 = 33800000 (exponent 103) is half an ulp of 1.
    (B32, "add", (0x3F800000, 0x33800000), "ieee", 0x3F800000, NX),  # tie, even: stays
    (B32, "add", (0x3F800001, 0x33800000), "ieee", 0x3F800002, NX),  # tie, odd: up
    (B32, "add", (0x3F800000, 0x33800001), "ieee", 0x3F800001, NX),  # above the tie
    (B32, "add", (0x3FFFFFFF, 0x33800000), "ieee", 0x40000000, NX),  # carry out: 2 - u + u/2 -> 2
    # largest finite 7f7fffff, its half ulp 2**103 = 73000000: tie from odd -> overflow
    (B32, "add", (0x7F7FFFFF, 0x73000000), "ieee", 0x7F800000, OF | NX),
    (B32, "add", (0x7F7FFFFF, 0x72FFFFFF), "ieee", 0x7F7FFFFF, NX),
    (B32, "sub", (0xFF7FFFFF, 0x73000000), "ieee", 0xFF800000, OF | NX),
    # signed zeros of exact results
    (B32, "sub", (0x3F800000, 0x3F800000), "ieee", 0x00000000, 0),
    (B32, "add", (0xBF800000, 0x3F800000), "ieee", 0x00000000, 0),
    (B32, "add", (0x80000000, 0x80000000), "ieee", 0x80000000, 0),
    (B32, "add", (0x00000000, 0x80000000), "ieee", 0x00000000, 0),
    (B32, "sub", (0x80000000, 0x00000000), "ieee", 0x80000000, 0),
    (B32, "sub", (0x00000000, 0x00000000), "ieee", 0x00000000, 0),
    # exact subnormal results raise nothing: min normal - min subnormal = max subnormal
    (B32, "sub", (0x00800000, 0x00000001), "ieee", 0x007FFFFF, 0),
    (B32, "mul", (0x00800000, 0x3F000000), "ieee", 0x00400000, 0),
    (B32, "mul", (0x00000001, 0x3F000000), "ieee", 0x00000000, UF | NX),  # 2**-150: tie to 0
    (B32, "mul", (0x80000001, 0x3F000000), "ieee", 0x80000000, UF | NX),  # keeps its sign
    (B32, "mul", (0x00000003, 0x3F000000), "ieee", 0x00000002, UF | NX),  # 1.5 quanta -> 2
    # Tininess after rounding. 2**-126 (1 - 2**-24) is exact with 24 bits, so tiny; in quanta of
    # 2**-149 it is 2**23 - 1/2, a tie, to even 2**23: the word of 2**-126.
    (B32, "mul", (0x00800000, 0x3F7FFFFF), "ieee", 0x00800000, UF | NX),
    # 2**-126 (1 + 2**-23)(1 - 2**-23) = 2**-126 (1 - 2**-46) rounds to 2**-126 with 24 bits: not tiny.
    (B32, "mul", (0x00800001, 0x3F7FFFFE), "ieee", 0x00800000, NX),
    (B32, "mul", (0x7F7FFFFF, 0x40000000), "ieee", 0x7F800000, OF | NX),
    (B32, "mul", (0xFF7FFFFF, 0x40000000), "ieee", 0xFF800000, OF | NX),
    (B32, "mul", (0x00000000, 0x7F800000), "ieee", 0x7FC00000, NV),
    (B32, "mul", (0x80000000, 0x3F800000), "ieee", 0x80000000, 0),
    (B32, "div", (0x3F800000, 0x40400000), "ieee", 0x3EAAAAAB, NX),  # 1/3 = 0.0101..., rounds up
    (B32, "div", (0x3F800000, 0x00000000), "ieee", 0x7F800000, DZ),
    (B32, "div", (0xBF800000, 0x00000000), "ieee", 0xFF800000, DZ),
    (B32, "div", (0x3F800000, 0x80000000), "ieee", 0xFF800000, DZ),
    (B32, "div", (0x00000000, 0x00000000), "ieee", 0x7FC00000, NV),
    (B32, "div", (0x7F800000, 0xFF800000), "ieee", 0x7FC00000, NV),
    (B32, "div", (0x7F800000, 0x00000000), "ieee", 0x7F800000, 0),  # inf / 0: no DZ
    (B32, "div", (0x00000000, 0x7F800000), "ieee", 0x00000000, 0),
    (B32, "add", (0x7F800000, 0xFF800000), "ieee", 0x7FC00000, NV),
    (B32, "add", (0x7FC00001, 0x3F800000), "ieee", 0x7FC00000, 0),  # quiet NaN payload dropped
    (B32, "add", (0xFFC00000, 0x3F800000), "ieee", 0x7FC00000, 0),  # canonical NaN has sign 0
    (B32, "add", (0x7F800001, 0x3F800000), "ieee", 0x7FC00000, NV),  # signalling
    (B32, "mul", (0x3F800000, 0xFFBFFFFF), "ieee", 0x7FC00000, NV),  # signalling, sign 1
    (B32, "sqrt", (0xBF800000,), "ieee", 0x7FC00000, NV),
    (B32, "sqrt", (0x80000000,), "ieee", 0x80000000, 0),
    (B32, "sqrt", (0xFF800000,), "ieee", 0x7FC00000, NV),
    (B32, "sqrt", (0x7F800000,), "ieee", 0x7F800000, 0),
    (B32, "sqrt", (0x40800000,), "ieee", 0x40000000, 0),
    (B32, "sqrt", (0x40000000,), "ieee", 0x3FB504F3, NX),  # sqrt 2 = 1.0110101000001001111001100|11..
    # sqrt(2**-149) = sqrt2 * 2**-75: exponent 52 -> 1a000000, the same fraction as sqrt 2
    (B32, "sqrt", (0x00000001,), "ieee", 0x1A3504F3, NX),
    # fma, single rounding. (1 + 2**-12)**2 = 1 + 2**-11 + 2**-24 is a tie; c = 2**-80 (17800000)
    # puts it just above: 1 + 2**-11 + 2**-23 = 3f801001. (Double rounding gives 3f801000.)
    (B32, "fma", (0x3F800800, 0x3F800800, 0x17800000), "ieee", 0x3F801001, NX),
    # (1 + 2**-12)(1 + 2**-12 + 2**-23) = 1 + 2**-11 + 2**-23 + 2**-24 + 2**-35;
    # c = -(2**-35 + 2**-58) (ae000001) leaves just below the tie: 3f801001. (Double: 3f801002.)
    (B32, "fma", (0x3F800800, 0x3F800801, 0xAE000001), "ieee", 0x3F801001, NX),
    (B32, "fma", (0x7F7FFFFF, 0x40000000, 0xFF7FFFFF), "ieee", 0x7F7FFFFF, 0),  # no intermediate OF
    # (1 + 2**-23)(1 - 2**-23) - 1 = -2**-46 exactly (exponent 81): a8800000
    (B32, "fma", (0x3F800001, 0x3F7FFFFE, 0xBF800000), "ieee", 0xA8800000, 0),
    (B32, "fma", (0x00000000, 0x7F800000, 0x7FC00000), "ieee", 0x7FC00000, NV),  # 0*inf + qNaN
    (B32, "fma", (0x7F800000, 0x3F800000, 0xFF800000), "ieee", 0x7FC00000, NV),
    (B32, "fma", (0x7F800000, 0x3F800000, 0x7F800000), "ieee", 0x7F800000, 0),
    (B32, "fma", (0x3F800000, 0x3F800000, 0x7FC00000), "ieee", 0x7FC00000, 0),
    (B32, "fma", (0x3F800000, 0x3F800000, 0x7F800001), "ieee", 0x7FC00000, NV),
    (B32, "fma", (0x80000000, 0x3F800000, 0x80000000), "ieee", 0x80000000, 0),
    (B32, "fma", (0x3F800000, 0x3F800000, 0xBF800000), "ieee", 0x00000000, 0),
    (B32, "fma", (0x00000000, 0xBF800000, 0x00000000), "ieee", 0x00000000, 0),
    (B32, "fma", (0x00000000, 0xBF800000, 0x80000000), "ieee", 0x80000000, 0),
    # 2**24 + 1 and + 3 are ties (ulp 2 there): to even 2**24 (4b800000) and 2**24 + 4 (4b800002)
    (B32, "i2f", (16777217,), "ieee", 0x4B800000, NX),
    (B32, "i2f", (16777219,), "ieee", 0x4B800002, NX),
    (B32, "i2f", (0x80000000,), "ieee", 0xCF000000, 0),
    (B32, "i2f", (0x7FFFFFFF,), "ieee", 0x4F000000, NX),
    (B32, "i2f", (0xFFFFFFFF,), "ieee", 0xBF800000, 0),
    (B32, "i2f", (-1,), "ieee", 0xBF800000, 0),
    (B32, "i2f", (0,), "ieee", 0x00000000, 0),
    (B16, "i2f", (65519,), "ieee", 0x7BFF, NX),  # 65504 + 15 < the tie at 65520
    (B16, "i2f", (65520,), "ieee", 0x7C00, OF | NX),
    (B16, "i2f", (-65520 & MASK32,), "ieee", 0xFC00, OF | NX),
    (B16, "i2f", (2049,), "ieee", 0x6800, NX),  # tie to 2048 (exponent 26)
    (B32, "f2i", (0x40200000,), "ieee", 2, NX),  # 2.5
    (B32, "f2i", (0x40600000,), "ieee", 4, NX),  # 3.5
    (B32, "f2i", (0xC0200000,), "ieee", 0xFFFFFFFE, NX),  # -2.5
    (B32, "f2i", (0x3F000000,), "ieee", 0, NX),
    (B32, "f2i", (0xBF000000,), "ieee", 0, NX),
    (B32, "f2i", (0x00000001,), "ieee", 0, NX),
    (B32, "f2i", (0x4F000000,), "ieee", 0x7FFFFFFF, NV),  # 2**31
    (B32, "f2i", (0xCF000000,), "ieee", 0x80000000, 0),  # -2**31
    (B32, "f2i", (0xCF000001,), "ieee", 0x80000000, NV),  # -(2**31 + 2**8)
    (B32, "f2i", (0x4EFFFFFF,), "ieee", 0x7FFFFF80, 0),  # 2**31 - 2**7
    (B32, "f2i", (0x7FC00000,), "ieee", 0x7FFFFFFF, NV),
    (B32, "f2i", (0xFFC00000,), "ieee", 0x7FFFFFFF, NV),
    (B32, "f2i", (0x7F800000,), "ieee", 0x7FFFFFFF, NV),
    (B32, "f2i", (0xFF800000,), "ieee", 0x80000000, NV),
    # binary64: 2**31 - 0.5 = 2**30 (2 - 2**-31): exponent 41d, 31 fraction ones. Tie to even 2**31: NV.
    (B64, "f2i", (0x41DFFFFFFFE00000,), "ieee", 0x7FFFFFFF, NV),
    (B64, "f2i", (0x41DFFFFFFFC00000,), "ieee", 0x7FFFFFFF, 0),  # 2**31 - 1
    # -(2**31 + 0.5): exponent 41e, fraction bit 2**-32 (1 << 20). Tie to even -2**31.
    (B64, "f2i", (0xC1E0000000100000,), "ieee", 0x80000000, NX),
    (B64, "f2i", (0xC1E0000000200000,), "ieee", 0x80000000, NV),  # -(2**31 + 1)
    # bfloat16 (bias 127, 7 fraction bits): 1 = 3f80, 2**-8 = 3b80 is half an ulp of 1.
    (BF16, "add", (0x3F80, 0x3B80), "ieee", 0x3F80, NX),
    (BF16, "add", (0x3F81, 0x3B80), "ieee", 0x3F82, NX),
    (BF16, "add", (0x7F7F, 0x7B00), "ieee", 0x7F80, OF | NX),  # max + 2**119 (half its ulp)
    (BF16, "mul", (0x0001, 0x3F00), "ieee", 0x0000, UF | NX),  # 2**-134: tie to 0
    (BF16, "mul", (0x0001, 0x3FC0), "ieee", 0x0002, UF | NX),  # 1.5 quanta -> 2
    # 2**-126 (1 - 2**-8): exact with 8 bits (tiny); 127.5 quanta -> 128 = 2**-126
    (BF16, "mul", (0x0080, 0x3F7F), "ieee", 0x0080, UF | NX),
    # 73 * 2**-70 (1f92) * 7 * 2**-65 (2060) = 511 * 2**-135 = 2**-126 (1 - 2**-9): rounds up to
    # 2**-126 with 8 bits (tie from 0.11111111 odd), so not tiny; 127.75 quanta -> 128.
    (BF16, "mul", (0x1F92, 0x2060), "ieee", 0x0080, NX),
    (BF16, "mul", (0x1F92, 0x2060), "ftz", 0x0080, NX),
    (BF16, "mul", (0x0080, 0x3F7F), "ftz", 0x0000, UF | NX),
    (BF16, "div", (0x3F80, 0x4040), "ieee", 0x3EAB, NX),  # 1/3 = 1.0101010|1010.. * 2**-2 -> up
    (BF16, "sqrt", (0x4000,), "ieee", 0x3FB5, NX),  # sqrt 2 = 1.0110101|0000.. -> down
    # (1 + 2**-7)(1 - 2**-8) - 1 = 2**-8 - 2**-15 = 1.1111110 * 2**-9 exactly (exponent 118)
    (BF16, "fma", (0x3F81, 0x3F7F, 0xBF80), "ieee", 0x3B7E, 0),
    (BF16, "i2f", (257,), "ieee", 0x4380, NX),  # tie -> 256
    (BF16, "i2f", (259,), "ieee", 0x4382, NX),  # tie -> 260 (ulp 2 at 2**8)
    (BF16, "i2f", (0xFFFFFFFF,), "ieee", 0xBF80, 0),
    (BF16, "f2i", (0x4020,), "ieee", 2, NX),  # 2.5
    (BF16, "f2i", (0x4060,), "ieee", 4, NX),  # 3.5
    (BF16, "f2i", (0xC020,), "ieee", 0xFFFFFFFE, NX),
    (BF16, "f2i", (0x4F00,), "ieee", 0x7FFFFFFF, NV),  # 2**31
    (BF16, "f2i", (0xCF00,), "ieee", 0x80000000, 0),
    (BF16, "add", (0x7F80, 0xFF80), "ieee", 0x7FC0, NV),
    (BF16, "div", (0xBF80, 0x0000), "ieee", 0xFF80, DZ),
    # e6m11 (bias 31, 11 fraction bits, 18-bit words): 1 = f800, 2**-12 = 9800 (exponent 19)
    (E6M11, "add", (0x0F800, 0x09800), "ieee", 0x0F800, NX),
    (E6M11, "add", (0x0F801, 0x09800), "ieee", 0x0F802, NX),
    (E6M11, "add", (0x0FFFF, 0x09800), "ieee", 0x10000, NX),  # carry: 2 - 2**-11 + 2**-12 -> 2
    # max 1f7ff = (2 - 2**-11) 2**31; half its ulp 2**19 = 19000 -> inf; 2**18 = 18800 -> max
    (E6M11, "add", (0x1F7FF, 0x19000), "ieee", 0x1F800, OF | NX),
    (E6M11, "add", (0x1F7FF, 0x18800), "ieee", 0x1F7FF, NX),
    (E6M11, "mul", (0x1F7FF, 0x10000), "ieee", 0x1F800, OF | NX),
    (E6M11, "sub", (0x00800, 0x00001), "ieee", 0x007FF, 0),
    (E6M11, "mul", (0x00001, 0x0F000), "ieee", 0x00000, UF | NX),  # 2**-41 * 0.5
    (E6M11, "mul", (0x00003, 0x0F000), "ieee", 0x00002, UF | NX),
    (E6M11, "sub", (0x00801, 0x00800), "ieee", 0x00001, 0),  # exact subnormal
    (E6M11, "sub", (0x00801, 0x00800), "ftz", 0x00000, UF | NX),  # ... flushed
    (E6M11, "sub", (0x00800, 0x00001), "ftz", 0x00800, 0),  # subnormal input reads as 0
    (E6M11, "div", (0x0F800, 0x10400), "ieee", 0x0EAAB, NX),  # 1/3: 1.01010101010|1010.. * 2**-2
    (E6M11, "sqrt", (0x10000,), "ieee", 0x0FB50, NX),  # sqrt 2: 1.01101010000|0100..
    (E6M11, "div", (0x00000, 0x00000), "ieee", 0x1FC00, NV),
    (E6M11, "i2f", (4097,), "ieee", 0x15800, NX),  # tie -> 4096 (exponent 43)
    (E6M11, "i2f", (4099,), "ieee", 0x15802, NX),  # tie -> 4100 (ulp 2 at 2**12)
    (E6M11, "i2f", (0x80000000,), "ieee", 0x3F000, 0),  # -2**31: sign 20000 | 62 << 11
    (E6M11, "i2f", (0x7FFFFFFF,), "ieee", 0x1F000, NX),
    (E6M11, "f2i", (0x1EFFF,), "ieee", 0x7FF80000, 0),  # (2 - 2**-11) 2**30 = 2**31 - 2**19
    (E6M11, "f2i", (0x1F7FF,), "ieee", 0x7FFFFFFF, NV),
    # ftz, binary32
    (B32, "add", (0x00400000, 0x3F800000), "ftz", 0x3F800000, 0),
    (B32, "add", (0x00400000, 0x3F800000), "ieee", 0x3F800000, NX),
    (B32, "mul", (0x80400000, 0x40000000), "ftz", 0x80000000, 0),
    (B32, "mul", (0x80400000, 0x40000000), "ieee", 0x80800000, 0),
    (B32, "mul", (0x00800000, 0x3F000000), "ftz", 0x00000000, UF | NX),
    (B32, "mul", (0x80800000, 0x3F000000), "ftz", 0x80000000, UF | NX),
    (B32, "mul", (0x00800000, 0x3F7FFFFF), "ftz", 0x00000000, UF | NX),
    (B32, "mul", (0x00800001, 0x3F7FFFFE), "ftz", 0x00800000, NX),
    (B32, "sqrt", (0x80400000,), "ftz", 0x80000000, 0),
    (B32, "sqrt", (0x80400000,), "ieee", 0x7FC00000, NV),
    (B32, "div", (0x3F800000, 0x00400000), "ftz", 0x7F800000, DZ),
    (B32, "div", (0x3F800000, 0x00400000), "ieee", 0x7F000000, 0),  # 2**127
    (B32, "div", (0x00400000, 0x00400000), "ftz", 0x7FC00000, NV),
    (B32, "f2i", (0x00400000,), "ftz", 0, 0),
    (B32, "f2i", (0x00400000,), "ieee", 0, NX),
    (B32, "fma", (0x00800000, 0x3F000000, 0x00800000), "ftz", 0x00C00000, 0),  # tiny product kept
    (B32, "fma", (0x00400000, 0x4B000000, 0x00000000), "ftz", 0x00000000, 0),
    (B32, "fma", (0x00400000, 0x4B000000, 0x00000000), "ieee", 0x0B800000, 0),  # 2**-104
]


@pytest.mark.parametrize("fmt, op, operands, subnormals, word, flags", HAND,
                         ids=[f"{c[0].name}-{c[1]}-{'-'.join(f'{x:x}' for x in c[2])}-{c[3]}"
                              for c in HAND])
def test_hand_worked(fmt, op, operands, subnormals, word, flags):
    assert ref_op(op, fmt, *operands, subnormals=subnormals) == (word, flags)


def test_hand_operands_mean_what_the_comments_say():
    """The operand encodings above, cross-checked with struct (IEEE binary32/64 of the host)."""
    f32 = lambda w: struct.unpack(">f", w.to_bytes(4, "big"))[0]  # noqa: E731
    f64 = lambda w: struct.unpack(">d", w.to_bytes(8, "big"))[0]  # noqa: E731
    assert f32(0x33800000) == 2.0 ** -24 and f32(0x73000000) == 2.0 ** 103
    assert f32(0x3F7FFFFF) == 1 - 2.0 ** -24 and f32(0x3F7FFFFE) == 1 - 2.0 ** -23
    assert f32(0x17800000) == 2.0 ** -80 and f32(0xAE000001) == -(2.0 ** -35 + 2.0 ** -58)
    assert f32(0x3F800800) == 1 + 2.0 ** -12 and f32(0x3F800801) == 1 + 2.0 ** -12 + 2.0 ** -23
    assert f32(0x1A3504F3) == f32(0x3FB504F3) * 2.0 ** -75
    assert f64(0x41DFFFFFFFE00000) == 2**31 - 0.5 and f64(0xC1E0000000100000) == -(2**31 + 0.5)
    assert f64(0x41DFFFFFFFC00000) == 2**31 - 1 and f64(0xC1E0000000200000) == -(2**31 + 1)
    # bfloat16 is the top half of binary32
    bf = lambda w: f32(w << 16)  # noqa: E731
    assert bf(0x1F92) == 73 * 2.0 ** -70 and bf(0x2060) == 7 * 2.0 ** -65
    assert bf(0x3F7F) == 1 - 2.0 ** -8 and bf(0x7B00) == 2.0 ** 119 and bf(0x3B80) == 2.0 ** -8


def test_fma_single_rounding_differs_from_float64_double_rounding():
    """The two hand fma cases are double-rounding traps: float64 a*b + c, then binary32, differs."""
    for (a, b, c), double in [((0x3F800800, 0x3F800800, 0x17800000), 0x3F801000),
                              ((0x3F800800, 0x3F800801, 0xAE000001), 0x3F801002)]:
        x = np.array([a, b, c], dtype=np.uint32).view(np.float32).astype(np.float64)
        via64 = int(np.float32(x[0] * x[1] + x[2]).view(np.uint32))
        assert via64 == double
        assert ref_op("fma", B32, a, b, c)[0] != via64


# ------------------------------------------------------------------------------------ API
def test_decode_against_numpy():
    words = [w for s in operand_sets(B32, "mul", 500) for w in s]
    with np.errstate(all="ignore"):  # signalling NaNs
        floats = np.array(words, dtype=np.uint32).view(np.float32).astype(np.float64).tolist()
    for w, x in zip(words, floats):
        v = decode(B32, w)
        assert (v != v and x != x) or v == x, hex(w)


def test_round_to_format():
    assert round_to_format(B32, 0, Fraction(1, 3)) == (0x3EAAAAAB, NX)
    assert round_to_format(B32, 1, Fraction(0)) == (0x80000000, 0)
    assert round_to_format(B32, 1, 3) == (0xC0400000, 0)
    assert round_to_format(B32, 0, Fraction(1, 2**150)) == (0, UF | NX)
    assert round_to_format(B32, 0, Fraction(3, 2**150)) == (2, UF | NX)
    assert round_to_format(B32, 0, Fraction(2**24 - 1, 2**150), "ftz") == (0, UF | NX)
    with pytest.raises(ValueError):
        round_to_format(B32, 0, Fraction(-1))
    with pytest.raises(ValueError):
        round_to_format(B32, 2, Fraction(1))


@pytest.mark.parametrize("call", [
    lambda: ref_op("neg", B32, 0),
    lambda: ref_op("add", B32, 0),
    lambda: ref_op("sqrt", B32, 0, 0),
    lambda: ref_op("add", B32, 1 << 32, 0),
    lambda: ref_op("add", B32, -1, 0),
    lambda: ref_op("add", B32, 0, 0, subnormals="daz"),
    lambda: ref_op("i2f", B32, 1 << 32),
    lambda: random_operands(B32, 4, np.random.default_rng(0), "neg"),
    lambda: directed_corpus(B32, "neg"),
])
def test_bad_arguments(call):
    with pytest.raises(ValueError):
        call()


# ----------------------------------------------------------------------------- generators
@pytest.mark.parametrize("op", list(OPS))
@pytest.mark.parametrize("fmt", ALL_FORMATS, ids=lambda f: f.name)
def test_generators(fmt, op):
    n = 4000
    sets = random_operands(fmt, n, np.random.default_rng(1), op)
    assert sets == random_operands(fmt, n, np.random.default_rng(1), op)
    assert len(sets) == n and all(len(s) == OPS[op] for s in sets)
    width = 32 if op == "i2f" else fmt.width
    words = [w for s in sets for w in s]
    assert all(isinstance(w, int) and 0 <= w < 1 << width for w in words)
    corpus = directed_corpus(fmt, op)
    assert corpus and all(len(s) == OPS[op] for s in corpus)
    assert all(0 <= w < 1 << width for s in corpus for w in s)
    if op == "i2f":
        ints = [w - (1 << 32) if w >> 31 else w for w in words]
        lengths = {abs(i).bit_length() for i in ints}
        assert lengths >= set(range(0, 32))
        assert sum(i < 0 for i in ints) > n // 4
        return
    fb, emask = fmt.frac_bits, (1 << fmt.exp_bits) - 1
    e = [w >> fb & emask for w in words]
    f = [w & ((1 << fb) - 1) for w in words]
    quiet = 1 << (fb - 1)
    classes = {
        "zero": sum(ei == 0 and fi == 0 for ei, fi in zip(e, f)),
        "subnormal": sum(ei == 0 and fi != 0 for ei, fi in zip(e, f)),
        "inf": sum(ei == emask and fi == 0 for ei, fi in zip(e, f)),
        "qnan": sum(ei == emask and fi & quiet != 0 for ei, fi in zip(e, f)),
        "snan": sum(ei == emask and fi and not fi & quiet for ei, fi in zip(e, f)),
        "top binades": sum(emask - 3 <= ei < emask for ei in e),
        "bottom binades": sum(1 <= ei <= 3 for ei in e),
    }
    floor = len(words) // 100  # each at 1 % or more
    assert all(v >= floor for v in classes.values()), classes
    results = [ref_op(op, fmt, *s) for s in sets]
    flags = [fl for _, fl in results]
    # The operands reach the rounding corners, not just the middle of the range.
    assert sum(fl & NX for fl in flags) > n // 10
    assert sum(fl == 0 for fl in flags) > n // 20
    assert sum(fl & NV for fl in flags) > n // 100
    if op in ("mul", "div", "fma"):
        assert sum(fl & UF for fl in flags) > n // 50
        assert sum(fl & OF for fl in flags) > n // 50
    if op in ("add", "sub", "mul", "div", "fma"):
        subnormal_results = sum(1 for w, _ in results if w >> fb & emask == 0 and w & ((1 << fb) - 1))
        assert subnormal_results > n // 100


def test_corpus_reaches_the_corners():
    """The directed corpus hits exact ties, carries, tininess on both sides and overflow."""
    for fmt in ALL_FORMATS:
        mul = [ref_op("mul", fmt, *s) for s in directed_corpus(fmt, "mul")]
        assert (fmt.min_normal, UF | NX) in mul and (fmt.min_normal, NX) in mul
        assert (fmt.inf(0), OF | NX) in mul and (fmt.max_subnormal, 0) in mul
        add = directed_corpus(fmt, "add")
        one, half_ulp = fmt.bias << fmt.frac_bits, (fmt.bias - fmt.precision) << fmt.frac_bits
        assert (one, half_ulp) in add and (one | 1, half_ulp) in add
        assert (one | ((1 << fmt.frac_bits) - 1), half_ulp) in add  # carry out
        fma = directed_corpus(fmt, "fma")
        assert any(ref_op("fma", fmt, *s) == (0, 0) and s[2] >> (fmt.width - 1) for s in fma)


def _word(fmt, value):
    word, flags = round_to_format(fmt, int(value < 0), abs(Fraction(value)))
    assert flags == 0
    return word


@pytest.mark.parametrize("fmt", [B16, B32, B64])
def test_conversion_sweep_hits_the_boundaries(fmt):
    i2f = [s[0] for s in conversion_sweep(fmt, "i2f")]
    f2i = [s[0] for s in conversion_sweep(fmt, "f2i")]
    for sweep in (i2f, f2i):
        assert len(set(sweep)) == len(sweep)
    assert all(0 <= w < 1 << 32 for w in i2f)
    assert all(0 <= w < 1 << fmt.width for w in f2i)
    p = fmt.precision
    ints = [(1 << 31) - 1, -(1 << 31), 1, -1, (1 << p) + 1, (1 << p) + 3, -((1 << p) + 1),
            (1 << (p + 1)) - 1]  # ties to even both ways, binade ends
    ints = [v for v in ints if -(1 << 31) <= v < 1 << 31]
    assert {v & 0xFFFF_FFFF for v in ints} <= set(i2f)
    halves = [Fraction(1, 2), Fraction(3, 2), Fraction(5, 2), Fraction(-5, 2), 1, -1]
    if fmt.emax >= 31:
        halves += [1 << 31, -(1 << 31)]  # where saturation starts
    assert {_word(fmt, v) for v in halves} <= set(f2i)
    flags = {ref_op("i2f", fmt, w)[1] for w in i2f}
    assert 0 in flags and (FLAG_NX in flags or p >= 32)
    assert {ref_op("f2i", fmt, w)[1] for w in f2i} >= ({0, FLAG_NX, FLAG_NV} if fmt.emax >= 31 else {0, FLAG_NX})
