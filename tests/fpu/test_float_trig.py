"""The trigonometric units (sin, cos, atan2): their plan's constants and reduction bound; the
golden model against the exact multi-precision reference (every binary16 and bfloat16 word
for sin and cos, every word as atan2's y against x = +-1 and random pairs; 10**5 binary32
inputs per function, 10**6 with ``--full``; binary64 samples); flags and specials; the
generated Verilog in Verilator under cocotb, bit for bit and flag for flag against the golden
model.

A result is faithful when it is one of the two floats around the true value. Flags: NX on
every result but the exact ones (sin(+-0), cos(+-0), atan2(+-0, x >= +0), atan2(y, +inf)), UF
exactly with a subnormal or zero inexact result, NV with a NaN result from an infinite sin or
cos argument, a signalling NaN or (binary64) an argument beyond 2**128.
"""

from fractions import Fraction

import mpmath
import numpy as np
import pytest

from kfgen.hdl.arith.float.format import FLAG_NV, FLAG_NX, FLAG_UF, FloatFormat
from kfgen.hdl.arith.float.params import FpuParams
from kfgen.hdl.arith.float.trig import FloatAtan2, FloatSin
from kfgen.hdl.arith.float.trig_plan import _two_over_pi_floor, constant_word, pi_floor, trig_plan
from kfgen.sim.float_ref import round_to_format
from kfgen.sim.fpu.trig_exact import near_pi_half_words, random_words, trig_exact, trig_exact_word
from kfgen.sim.fpu.trig_model import trig_model

from helpers import simulate_fpu_cores

FUNCTIONS = ("sin", "cos", "atan2")


# ------------------------------------------------------------------------- constants and plan
def test_pi_and_two_over_pi_bits():
    with mpmath.workprec(400):
        for n in (8, 53, 200, 300):
            assert pi_floor(n) == int(mpmath.floor(mpmath.pi * 2 ** n))
            assert _two_over_pi_floor(n) == int(mpmath.floor(2 / mpmath.pi * 2 ** n))


@pytest.mark.parametrize("fmt", ["binary16", "bfloat16", "binary32", "binary64"])
def test_tables_are_rounded_to_nearest(fmt):
    plan = trig_plan(fmt)
    W = plan.cordic_bits
    with mpmath.workprec(W + 80):
        for i in range(plan.iterations):
            at = mpmath.atan(mpmath.mpf(2) ** -i)
            assert plan.atan_radians[i] == int(mpmath.nint(at * 2 ** W))
            assert plan.atan_quarter[i] == int(mpmath.nint(at * 2 / mpmath.pi * 2 ** W))
        gain = mpmath.fprod(mpmath.sqrt(1 + mpmath.mpf(4) ** -i) for i in range(plan.iterations))
        assert plan.inv_gain == int(mpmath.nint(2 ** W / gain))
        assert plan.pi_half == int(mpmath.nint(mpmath.pi / 2 * 2 ** W))
        assert plan.pi_half_mul == int(mpmath.floor(mpmath.pi / 2 * 2 ** plan.mul_bits))
    # each window: the bits of 2/pi from weight 2**-(E + t_frac + p) up, modulo 4 quarter turns
    with mpmath.workprec(plan.range_bits + plan.acc_bits + 64):
        for E in (plan.e_low, -3, 0, plan.range_bits - plan.p):
            full = int(mpmath.floor(2 / mpmath.pi * mpmath.mpf(2) ** (E + plan.t_frac + plan.p)))
            assert plan.window[E - plan.e_low] == full % (1 << plan.acc_bits)


def test_reduction_bound_brute_force():
    """binary16 and bfloat16: every input of the reduction's range gives ``|f| >=
    2**-min_f_bits``, the bound the plan derives from continued fractions."""
    for fmt in ("binary16", "bfloat16"):
        f, plan = FloatFormat.parse(fmt), trig_plan(fmt)
        two_pi = Fraction(_two_over_pi_floor(400), 1 << 400)
        smallest = Fraction(1)
        for field in range(1, f.exp_max_field):
            e = field - f.bias
            if not -plan.tiny_bits <= e < plan.range_bits:
                continue
            for frac in range(1 << f.frac_bits):
                t = Fraction(frac | 1 << f.frac_bits) * Fraction(2) ** (e - f.frac_bits) * two_pi
                smallest = min(smallest, abs(t - round(t)))
        assert smallest >= Fraction(1, 1 << plan.min_f_bits), fmt
        assert smallest < Fraction(1, 1 << (plan.min_f_bits - 8)), "the bound is not loose by much"


def test_constants_of_atan2_specials():
    for fmt in ("binary16", "binary32", "binary64"):
        f = FloatFormat.parse(fmt)
        for multiple, value in (((1, 0), mpmath.pi), ((1, 1), mpmath.pi / 2), ((1, 2), mpmath.pi / 4),
                                ((3, 2), 3 * mpmath.pi / 4)):
            with mpmath.workprec(200):
                v = Fraction(int(mpmath.nint(value * 2 ** 150)), 1 << 150)
            word = constant_word(f, multiple)
            assert word == round_to_format(f, 0, v)[0], (fmt, multiple)


def test_plan_refuses_formats_with_large_subnormals():
    with pytest.raises(ValueError, match="subnormals are below"):
        trig_plan("e4m10")


def test_unit_latency_and_stages():
    assert FloatSin.plan("binary32").latency == trig_plan("binary32").p + 2 * trig_plan("binary32").iterations + 14
    assert FloatAtan2.plan("binary16").initiation_interval == FloatAtan2.plan("binary16").latency
    with pytest.raises(ValueError, match="stages must be an integer from 140 to 140"):
        FloatSin.plan("binary32", stages=3)
    assert FpuParams(op="atan2", format="binary16").stages == FloatAtan2.plan("binary16").latency


# ------------------------------------------------------------------------- golden model vs exact
def check_against_exact(fn, fmt, a, b=None, subnormals="ieee"):
    """Every result faithful and flagged as the module docstring says."""
    fmt = FloatFormat.parse(fmt)
    y, flags = trig_model(fn, fmt, a, b, subnormals)
    ex = trig_exact(fn, fmt, a, b)
    dtype = ex["rn"].dtype
    y = np.asarray(y, dtype=dtype)
    ok = (y == ex["rn"]) | (y == ex["down"]) | (y == ex["up"])
    a_arr = np.asarray(a, dtype=object)
    b_arr = None if b is None else np.asarray(b, dtype=object)
    bad = [f"{fn}({int(x):#x}{'' if b_arr is None else f', {int(b_arr[i]):#x}'}) = {int(y[i]):#x}, "
           f"exact rounding {int(ex['rn'][i]):#x}" for i, x in enumerate(a_arr) if not ok[i]]
    assert not bad, f"{len(bad)} of {len(y)} not faithful:\n" + "\n".join(bad[:10])
    nan = (y & fmt.exp_max_field << fmt.frac_bits) == fmt.exp_max_field << fmt.frac_bits
    nan &= (y & fmt.frac_mask) != 0
    exact = (ex["flags"] & FLAG_NX) == 0
    assert np.all(((flags & FLAG_NX) != 0) == (~exact & ~nan)), "NX exactly on inexact results"
    mag = y & ~np.asarray(fmt.sign_mask, dtype=dtype) if dtype != object else \
        np.asarray([int(v) & ~fmt.sign_mask for v in y], dtype=object)
    assert np.all(((flags & FLAG_UF) != 0) == (~exact & ~nan & (mag < fmt.min_normal))), "UF"
    assert np.all(y[nan] == fmt.canonical_nan) and np.all((flags[nan] & ~FLAG_NV) == 0), "NaN results"
    assert np.all(flags[nan] == ex["flags"][nan]), "NV as the reference says"
    return y, flags


@pytest.mark.parametrize("fn", ["sin", "cos"])
@pytest.mark.parametrize("fmt", ["binary16", pytest.param("bfloat16", marks=pytest.mark.full)])  # bfloat16: 18 s
def test_model_exhaustive_16bit(fn, fmt):
    check_against_exact(fn, fmt, list(range(1 << 16)))


@pytest.mark.full
@pytest.mark.parametrize("fmt", ["binary16", "bfloat16"])
def test_model_atan2_16bit(fmt):
    """Every word as y against x = 1 and x = -1 (atan over the whole range, and pi minus it),
    and random pairs concentrated where the paths meet (|y/x| near 2**-S)."""
    f, plan = FloatFormat.parse(fmt), trig_plan(fmt)
    words = list(range(1 << 16))
    one = f.pack(0, f.bias, 0)
    for x in (one, one | f.sign_mask):
        check_against_exact("atan2", fmt, words, [x] * len(words))
    rng = np.random.default_rng(3)
    xs = random_words(fmt, 10_000, rng, -10, 10)
    ys = [int(v) for v in random_words(fmt, 10_000, rng, -plan.tiny_bits - 14, -plan.tiny_bits + 14)]
    check_against_exact("atan2", fmt, ys, xs)


def _sweep(fn, fmt, n, seed):
    rng = np.random.default_rng(seed)
    plan = trig_plan(fmt)
    if fn == "atan2":
        ys = random_words(fmt, n // 2, rng, -30, 30) + random_words(fmt, n - n // 2, rng, -plan.tiny_bits - 4, 4)
        xs = random_words(fmt, n // 2, rng, -30, 30) + random_words(fmt, n - n // 2, rng, -4, plan.tiny_bits + 4)
        check_against_exact("atan2", fmt, ys, xs)
    else:
        words = near_pi_half_words(fmt) + random_words(fmt, n // 2, rng, -plan.tiny_bits - 2, plan.range_bits - 1) \
            + random_words(fmt, n - n // 2, rng, -plan.tiny_bits - 2, 6)
        check_against_exact(fn, fmt, words)


@pytest.mark.parametrize("fn", FUNCTIONS)
def test_model_binary32(fn):
    _sweep(fn, "binary32", 20_000, seed=1)  # 10**6 in make test-full


@pytest.mark.full
@pytest.mark.parametrize("fn", FUNCTIONS)
def test_model_binary32_million(fn):
    _sweep(fn, "binary32", 1_000_000, seed=2)


@pytest.mark.parametrize("fn", FUNCTIONS)
def test_model_binary64(fn):
    _sweep(fn, "binary64", 3_000, seed=4)


def test_out_of_range_and_specials():
    """binary64 beyond 2**128: NaN with NV (the documented range); infinities: NaN with NV;
    zeros exact; atan2's IEEE 754 special cases."""
    f = FloatFormat.parse("binary64")
    big = [f.pack(s, f.bias + e, 12345) for s in (0, 1) for e in (128, 500, f.emax)]
    for fn in ("sin", "cos"):
        y, flags = trig_model(fn, f, big + [f.inf(0), f.inf(1)])
        assert all(int(v) == f.canonical_nan for v in y) and all(flags == FLAG_NV)
    b16 = FloatFormat.parse("binary16")
    one, zero, inf = b16.pack(0, b16.bias, 0), 0, b16.inf(0)
    neg = b16.sign_mask
    pi, half, quarter = constant_word(b16, (1, 0)), constant_word(b16, (1, 1)), constant_word(b16, (1, 2))
    three = constant_word(b16, (3, 2))
    cases = {(zero, one): (zero, 0), (neg, one): (neg, 0), (zero, neg): (pi, FLAG_NX),
             (neg, neg | one): (pi | neg, FLAG_NX), (one, zero): (half, FLAG_NX),
             (one | neg, neg): (half | neg, FLAG_NX), (inf, inf): (quarter, FLAG_NX),
             (inf | neg, inf | neg): (three | neg, FLAG_NX), (one, inf): (zero, 0),
             (one | neg, inf | neg): (pi | neg, FLAG_NX), (inf, one): (half, FLAG_NX)}
    for (y, x), want in cases.items():
        got = trig_model("atan2", b16, [y], [x])
        assert (int(got[0][0]), int(got[1][0])) == want, (hex(y), hex(x))
        assert trig_exact_word("atan2", b16, y, x)[:2] == want


def test_model_ftz():
    """ftz: a subnormal operand reads as a zero of its sign; a tiny result flushes to a signed
    zero with UF|NX; every other result as with ieee."""
    fmt = FloatFormat.parse("binary16")
    words = np.arange(1 << 16, dtype=np.int64)
    sub = ((words >> fmt.frac_bits) & fmt.exp_max_field == 0) & ((words & fmt.frac_mask) != 0)
    for fn in ("sin", "cos"):
        y, flags = trig_model(fn, fmt, words, subnormals="ftz")
        y_ieee, flags_ieee = trig_model(fn, fmt, words)
        want = (words[sub] & fmt.sign_mask) if fn == "sin" else fmt.pack(0, fmt.bias, 0)
        assert np.all(y[sub] == want) and np.all(flags[sub] == 0)
        tiny = ~sub & ((flags_ieee & FLAG_UF) != 0)  # (near multiples of pi)
        assert np.all(y[tiny] == y_ieee[tiny] & fmt.sign_mask) and np.all(flags[tiny] == FLAG_UF | FLAG_NX)
        rest = ~sub & ~tiny
        assert np.array_equal(y[rest], y_ieee[rest]) and np.array_equal(flags[rest], flags_ieee[rest])
    ys = [fmt.pack(0, 1, 5), fmt.pack(1, 3, 0)]
    y, flags = trig_model("atan2", fmt, ys, [fmt.pack(0, 30, 0)] * 2, "ftz")
    assert list(y) == [0, fmt.sign_mask] and list(flags) == [FLAG_UF | FLAG_NX] * 2


# ------------------------------------------------------------------------- Verilator
def special_words(fmt) -> list[int]:
    """Zeros, a few subnormals, infinities and NaNs (both signs)."""
    f = FloatFormat.parse(fmt)
    return [s << (f.width - 1) | w for s in (0, 1)
            for w in (0, 1, f.frac_mask, f.min_normal, f.inf(0), f.inf(0) | 1, f.canonical_nan, f.max_finite)]


def _inputs(fn, fmt, n, seed):
    rng = np.random.default_rng(seed)
    plan = trig_plan(fmt)
    lo, hi = -plan.tiny_bits - 3, min(plan.range_bits + 1, 40)
    a = special_words(fmt) + random_words(fmt, n, rng, lo, hi)
    if fn != "atan2":
        a += near_pi_half_words(fmt)[:n // 4]
        return {"a": a}
    specials = special_words(fmt)
    pairs = [(y, x) for y in specials for x in specials]
    ys = random_words(fmt, n, rng, -20, 20)
    xs = random_words(fmt, n, rng, -20, 20)
    return {"a": [p[0] for p in pairs] + ys, "b": [p[1] for p in pairs] + xs}


def _rtl_units(full: bool):
    """prefix: (fn, format, subnormals, operands). make test: specials, directed and a thousand
    random inputs of sin and atan2 in binary32; make test-full: every binary16 and bfloat16 word
    (sin, cos; atan2 against +-1), bfloat16 sin with ftz, 10**5 binary32 inputs per function,
    binary64."""
    if not full:  # cos is sin's unit with the quadrant moved by one (its RTL in test-full)
        return {f"{fn}32": (fn, "binary32", "ieee", _inputs(fn, "binary32", 1_000, 2)) for fn in ("sin", "atan2")}
    every = list(range(1 << 16))
    units = {}
    for fmt, tag in (("binary16", "16"), ("bfloat16", "bf")):
        f = FloatFormat.parse(fmt)
        one = f.pack(0, f.bias, 0)
        units |= {f"sin{tag}": ("sin", fmt, "ieee", {"a": every}), f"cos{tag}": ("cos", fmt, "ieee", {"a": every}),
                  f"atan2{tag}": ("atan2", fmt, "ieee", {"a": every + every, "b": [one] * len(every)
                                                         + [one | f.sign_mask] * len(every)})}
    units |= {f"{fn}32": (fn, "binary32", "ieee", _inputs(fn, "binary32", 100_000, 5)) for fn in FUNCTIONS}
    units |= {"sinbf": ("sin", "bfloat16", "ftz", _inputs("sin", "bfloat16", 500, 3))}
    units |= {f"{fn}64": (fn, "binary64", "ieee", _inputs(fn, "binary64", 5_000, 6)) for fn in FUNCTIONS}
    return units


def _model(fn, fmt, operands, subnormals):
    return trig_model(fn, fmt, operands["a"], operands.get("b"), subnormals)


@pytest.mark.verilator
def test_rtl_bit_exact(build_root):
    simulate_fpu_cores(build_root, "trig", _rtl_units(full=False), _model)


@pytest.mark.verilator
@pytest.mark.full
def test_rtl_bit_exact_full(build_root):
    simulate_fpu_cores(build_root, "trig_full", _rtl_units(full=True), _model)
