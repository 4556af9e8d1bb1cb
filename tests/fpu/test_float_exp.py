"""The exponential unit: its plan's constants and error bound; the golden model against the exact
reference (every binary16 and bfloat16 word, 10**5 binary32 inputs, 10**6 with ``--full``);
the unit in Amaranth's simulator and the generated Verilog in Verilator under cocotb, bit for
bit and flag for flag against the golden model.

A result is faithful when it is one of the two floats around ``e**x`` (an error below one unit
in the last place) and overflows exactly when ``e**x`` rounded to nearest does; flags: NX for
every finite ``x != 0``, OF exactly with an infinite result, UF exactly with a result tiny
after rounding (so with every subnormal or zero result).
"""

import decimal
from fractions import Fraction

import numpy as np
import pytest
from amaranth.sim import Simulator

from kfgen.hdl.arith.float.exp import FloatExp
from kfgen.hdl.arith.float.exp_plan import CHUNK, exp_bounds, exp_plan, ln2_bounds
from kfgen.hdl.arith.float.format import FLAG_NV, FLAG_NX, FLAG_OF, FLAG_UF, FloatFormat
from kfgen.sim.float_ref import _consts, _round, decode, round_to_format
from kfgen.sim.fpu.exp_exact import (_format, _round_ratio, directed_words, exp_exact, faithful,
                                     random_words, ulp_error)
from kfgen.sim.fpu.exp_model import exp_model, round_vector

from helpers import simulate_fpu_cores

D = decimal.Decimal
CTX = decimal.Context(prec=120)


def words_array(fmt, words):
    return np.asarray(words, dtype=object if FloatFormat.parse(fmt).width > 62 else np.int64)


def check_against_exact(fmt, words, y, flags):
    """Every result faithful, flags as the module docstring says; returns the largest error in
    ulps among the results that are not correctly rounded (0 if there are none)."""
    fmt = FloatFormat.parse(fmt)
    ex = exp_exact(fmt, words)
    ok = faithful(fmt, y, ex)
    bad = [f"x={int(w):#x}: {int(g):#x}, exact rounding {int(r):#x} (between {int(d):#x} and {int(u):#x})"
           for w, g, r, d, u in zip(words[~ok], y[~ok], ex["rn"][~ok], ex["down"][~ok], ex["up"][~ok])]
    assert not bad, f"{len(bad)} of {len(words)} not faithful:\n" + "\n".join(bad[:10])
    field = (words >> fmt.frac_bits) & fmt.exp_max_field
    frac = words & fmt.frac_mask
    nan, finite = (field == fmt.exp_max_field) & (frac != 0), field != fmt.exp_max_field
    zero = finite & (field == 0) & (frac == 0)
    snan = nan & ((frac & fmt.quiet_bit) == 0)
    inf = fmt.inf(0)
    tiny = (y < fmt.min_normal) | ((y == fmt.min_normal) & ((flags & FLAG_UF) != 0))
    expected_uf = (y < fmt.min_normal) & finite & ~zero
    assert np.all(flags[nan] == np.where(snan[nan], FLAG_NV, 0)), "NaN flags"
    assert np.all(y[nan] == fmt.canonical_nan), "NaN results"
    assert np.all(flags[zero] == 0) and np.all(y[zero] == fmt.pack(0, fmt.bias, 0)), "e**0 = 1 exactly"
    live = finite & ~zero
    assert np.all((flags[live] & FLAG_NX) != 0), "NX on every finite x != 0"
    assert np.all(((flags[live] & FLAG_OF) != 0) == (y[live] == inf)), "OF exactly with +inf"
    assert np.all(((flags & FLAG_UF) != 0)[expected_uf]) and np.all(tiny[(flags & FLAG_UF) != 0]), "UF"
    assert np.all(flags[~nan & ~live] == 0), "exact specials raise nothing"
    off = np.nonzero(live & (y != ex["rn"]))[0]
    return max((ulp_error(fmt, int(words[i]), int(y[i])) for i in off), default=0.0)


# ------------------------------------------------------------------------- constants and plan
def test_ln2_and_exp_bounds():
    """Against decimal at 120 digits (its error, below 10**-119, far under the intervals')."""
    ln2 = Fraction(CTX.ln(D(2)))
    for n in (8, 64, 200):
        lo, hi = ln2_bounds(n)
        assert hi == lo + 1 and Fraction(lo, 1 << n) < ln2 < Fraction(hi, 1 << n)
    for x in (Fraction(1, 3), Fraction(-1, 2), Fraction(255, 256), Fraction(-1, 1024)):
        lo, hi = exp_bounds(x, 80)
        assert lo < Fraction(CTX.exp(CTX.divide(D(x.numerator), D(x.denominator)))) < hi
        assert hi - lo <= Fraction(1, 1 << 80)


@pytest.mark.parametrize("fmt", ["binary16", "binary32", "binary64"])
def test_tables_are_rounded_to_nearest(fmt):
    """e**A and k ln 2 entries against decimal at 120 digits (no tie is that close)."""
    plan = exp_plan(fmt)
    a, G, F = plan.index_bits, plan.work_bits, plan.frac_bits
    for idx, entry in enumerate(plan.table):
        A = idx - (1 << a) if idx >> (a - 1) else idx
        want = CTX.exp(D(A) / D(1 << a)) * D(1 << G)
        assert entry == int(want.to_integral_value(decimal.ROUND_HALF_EVEN)), idx
    ln2 = CTX.ln(D(2))
    for i, table in enumerate(plan.ln2_tables):
        for j, entry in enumerate(table):
            want = int((D(j << (CHUNK * i)) * ln2 * D(1 << F)).to_integral_value(decimal.ROUND_HALF_EVEN))
            assert entry == want % (1 << F), (i, j)


#: Formats whose plans are checked (and the command line's extremes).
PLAN_FORMATS = ("binary16", "bfloat16", "binary32", "binary64", "e3m2", "e4m3", "e5m5", "e6m11",
                "e3m40", "e15m2", "e15m64", "e10m30", "e7m50", "e12m9")


@pytest.mark.parametrize("fmt", PLAN_FORMATS)
def test_plan_error_bound(fmt):
    """The bound the plan was chosen by is below 2**-(p+1) and the overflow margins (so the
    rounding is faithful and the overflow exact), with |r| < 1/2 and no Horner product that
    always floors to zero."""
    plan = exp_plan(fmt)
    p = plan.fmt.precision
    below, above = plan.overflow_margins
    eps = plan.error_bound
    assert 0 < eps < Fraction(1, 1 << (p + 1)) and eps < below and eps + eps * eps <= above
    assert plan.work_bits >= p + 1 and plan.frac_bits > plan.index_bits
    # The margins are (lower bounds of) the distances from ln of the overflow threshold, found
    # here with decimal, to the floats on either side of it.
    ln_t = Fraction(CTX.ln(CTX.multiply(CTX.subtract(D(2), CTX.power(D(2), -p)), CTX.power(D(2), plan.fmt.emax))))
    f = _format(plan.fmt)
    x_below = decode(plan.fmt, _round_ratio(f, ln_t.numerator, ln_t.denominator)[2])
    x_above = decode(plan.fmt, _round_ratio(f, ln_t.numerator, ln_t.denominator)[2] + 1)
    slack = Fraction(1, 10 ** 100)  # decimal's ln is off by less
    assert ln_t - x_below >= below - slack and x_above - ln_t >= above - slack


# ------------------------------------------------------------------------- the references
def test_round_vector_is_the_rounding_stage():
    """round_vector (the golden model's rounding) against float_ref's scalar rounding, which the
    other units' hardware matches bit for bit: random significands at every exponent from
    overflow to far below the subnormals, with and without the sticky bit, ieee and ftz."""
    rng = np.random.default_rng(7)
    for name in ("binary16", "bfloat16", "binary32", "e3m2"):
        fmt = FloatFormat.parse(name)
        k, width = _consts(fmt), fmt.precision + 5
        n = 4000
        sig = rng.integers(1 << (width - 1), 1 << width, size=n, dtype=np.int64)
        sig[: n // 8] = (1 << width) - 1 - rng.integers(0, 8, size=n // 8)  # carries
        top = rng.integers(fmt.emin - fmt.precision - 4, fmt.emax + 2, size=n)
        sticky = rng.integers(0, 2, size=n).astype(bool)
        for ftz in (False, True):
            word, flags = round_vector(fmt, sig, width, top, sticky, ftz)
            want = [_round(k, 0, int(s), int(t) - width + 1, bool(st), ftz) for s, t, st in zip(sig, top, sticky)]
            assert [(int(w), int(f)) for w, f in zip(word, flags)] == want, (name, ftz)


def test_exact_reference_rounding():
    """The exact reference's integer rounding against float_ref.round_to_format on random
    rationals in every range, and its binary32 results against numpy's float64 exp rounded
    to float32 (equal unless float64's value were within 2**-29 of a binary32 tie)."""
    rng = np.random.default_rng(3)
    for name in ("binary16", "binary32", "e3m2"):
        f = _format(name)
        for _ in range(2000):
            num = int(rng.integers(1, 1 << 60))
            den = int(rng.integers(1, 1 << 40)) << int(rng.integers(0, 200))
            num <<= int(rng.integers(0, 200))
            word, flags, down = _round_ratio(f, num, den)
            assert (word, flags) == round_to_format(f.fmt, 0, Fraction(num, den))
            # the largest float at or below the value (the largest finite above them all)
            assert decode(f.fmt, down) <= Fraction(num, den)
            assert down == f.max_finite or decode(f.fmt, down + 1) > Fraction(num, den)
    x = rng.uniform(-103, 88, size=20000).astype(np.float32)
    words = x.view(np.uint32).astype(np.int64)
    ex = exp_exact("binary32", words)
    with np.errstate(over="ignore", under="ignore"):
        want = np.exp(x.astype(np.float64)).astype(np.float32).view(np.uint32).astype(np.int64)
    assert np.array_equal(ex["rn"], want)
    assert np.all(ex["down"] <= ex["rn"]) and np.all(ex["rn"] <= ex["up"]) and np.all(ex["up"] - ex["down"] == 1)


# ------------------------------------------------------------------------- golden model vs exact
@pytest.mark.parametrize("fmt", ["binary16", "bfloat16"])
def test_model_exhaustive_16bit(fmt, record_property):
    words = np.arange(1 << 16, dtype=np.int64)
    y, flags = exp_model(fmt, words)
    worst = check_against_exact(fmt, words, y, flags)
    assert worst < 1
    record_property("max_ulp_error", worst)


@pytest.mark.parametrize("fmt", ["e3m2", "e4m3", "e5m5", "e5m7", "e6m6"])
def test_model_exhaustive_narrow(fmt):
    words = np.arange(1 << FloatFormat.parse(fmt).width, dtype=np.int64)
    y, flags = exp_model(fmt, words)
    assert check_against_exact(fmt, words, y, flags) < 1


def _sweep(fmt, n, seed):
    words = words_array(fmt, directed_words(fmt) + random_words(fmt, n, np.random.default_rng(seed)))
    y, flags = exp_model(fmt, words)
    assert check_against_exact(fmt, words, y, flags) < 1


def test_model_binary32():
    _sweep("binary32", 100_000, seed=1)


@pytest.mark.full
def test_model_binary32_million():
    _sweep("binary32", 1_000_000, seed=2)


@pytest.mark.parametrize("fmt, n", [("binary64", 5_000), ("e6m11", 5_000), ("e15m64", 2_000),
                                    ("e3m40", 2_000), ("e15m2", 2_000)])
def test_model_wide(fmt, n):
    _sweep(fmt, n, seed=3)


@pytest.mark.full
def test_model_e6m11_exhaustive():
    words = np.arange(1 << 18, dtype=np.int64)
    y, flags = exp_model("e6m11", words)
    assert check_against_exact("e6m11", words, y, flags) < 1


def test_model_ftz():
    """ftz: a subnormal x reads as zero (1 exactly, no flag); a result tiny after rounding is
    +0 with UF|NX; everything else as with ieee."""
    fmt = FloatFormat.parse("binary16")
    words = np.arange(1 << 16, dtype=np.int64)
    y, flags = exp_model(fmt, words, "ftz")
    y_ieee, flags_ieee = exp_model(fmt, words, "ieee")
    field = (words >> fmt.frac_bits) & fmt.exp_max_field
    sub = (field == 0) & ((words & fmt.frac_mask) != 0)
    assert np.all(y[sub] == fmt.pack(0, fmt.bias, 0)) and np.all(flags[sub] == 0)
    tiny = ~sub & ((flags_ieee & FLAG_UF) != 0)
    assert np.all(y[tiny] == 0) and np.all(flags[tiny] == FLAG_UF | FLAG_NX)
    rest = ~sub & ~tiny
    assert np.array_equal(y[rest], y_ieee[rest]) and np.array_equal(flags[rest], flags_ieee[rest])


# ------------------------------------------------------------------------- the unit, simulated
def stream(unit, words, seed, idle=0.3):
    """Stream ``words`` through ``unit`` with random idle cycles (random words on the input);
    results must come out ``latency`` cycles after their operands and at no other time."""
    rng = np.random.default_rng(seed)
    latency, results = unit.latency, []

    async def testbench(ctx):
        index, cycle, due = 0, 0, []
        while index < len(words) or due:
            present = index < len(words) and rng.random() >= idle
            ctx.set(unit.i_a, int(words[index]) if present else int(rng.integers(0, 1 << 62)) % (1 << unit.fmt.width))
            ctx.set(unit.i_valid, present)
            if present:
                due.append(cycle + latency)
                index += 1
            valid = ctx.get(unit.o_valid)
            assert valid == bool(due and due[0] == cycle), f"cycle {cycle}: o_valid {valid}"
            if valid:
                results.append((ctx.get(unit.o_y), ctx.get(unit.o_flags)))
                due.pop(0)
            if latency:
                await ctx.tick()
            else:
                await ctx.delay(1e-8)
            cycle += 1

    sim = Simulator(unit)
    if latency:
        sim.add_clock(1e-8)
    sim.add_testbench(testbench)
    sim.run()
    return results


def check_unit(unit, words, seed):
    got = stream(unit, words, seed)
    y, flags = exp_model(unit.fmt, words_array(unit.fmt, words), unit.subnormals)
    bad = [f"exp({w:#x}) = {g[0]:#x} flags {g[1]:05b}, model {int(a):#x} flags {int(b):05b}"
           for w, g, a, b in zip(words, got, y, flags) if g != (int(a), int(b))]
    assert len(got) == len(words) and not bad, f"{len(bad)} of {len(words)} differ:\n" + "\n".join(bad[:10])


@pytest.mark.parametrize("fmt, subnormals, n", [("binary32", "ieee", 600), ("binary16", "ftz", 300),
                                                ("e3m2", "ieee", 0), ("e15m64", "ieee", 100)])
def test_unit_default_stages(fmt, subnormals, n):
    unit = FloatExp(fmt, subnormals=subnormals)
    words = directed_words(fmt) + random_words(fmt, n, np.random.default_rng(n))
    check_unit(unit, words, seed=1)


def test_unit_stage_counts():
    """Registers placed for the fewest (none), a few, the middle and the most stages."""
    probe = FloatExp("binary16")
    probe._MustUse__silence = True
    counts = list(probe.PLANS)
    words = directed_words("binary16")[::4] + random_words("binary16", 30, np.random.default_rng(2))
    for stages in sorted({*counts[:3], counts[len(counts) // 2], counts[-1]}):
        unit = FloatExp("binary16", stages=stages)
        assert unit.latency == stages and unit.initiation_interval == 1
        check_unit(unit, words, seed=stages)


# ------------------------------------------------------------------------- Verilator
def special_words(fmt) -> list[int]:
    """Every zero, subnormal, infinity and NaN word (both signs, every payload)."""
    fmt = FloatFormat.parse(fmt)
    fields = (0, fmt.exp_max_field)
    return [s << (fmt.width - 1) | e << fmt.frac_bits | m for s in (0, 1) for e in fields
            for m in range(1 << fmt.frac_bits)]


def _rtl_units(full: bool):
    """prefix: (format, subnormals, inputs). make test: every special word, the directed
    inputs and a few thousand random ones per 16-bit format, and 20,000 binary32 inputs;
    make test-full: every binary16, bfloat16 and e6m11 word, 200,000 binary32 inputs, 20,000
    binary64 and binary16 with ftz."""
    def sampled(fmt, n, seed):
        return special_words(fmt) + directed_words(fmt) + random_words(fmt, n, np.random.default_rng(seed))

    if not full:
        return {"b16": ("binary16", "ieee", sampled("binary16", 4_000, 4)),
                "bf16": ("bfloat16", "ieee", sampled("bfloat16", 6_000, 5)),
                "b32": ("binary32", "ieee", directed_words("binary32") + random_words(
                    "binary32", 20_000, np.random.default_rng(6)))}
    return {"b16": ("binary16", "ieee", list(range(1 << 16))),
            "bf16": ("bfloat16", "ieee", list(range(1 << 16))),
            "e6m11": ("e6m11", "ieee", list(range(1 << 18))),
            "b32": ("binary32", "ieee", directed_words("binary32") + random_words(
                "binary32", 200_000, np.random.default_rng(7))),
            "b64": ("binary64", "ieee", directed_words("binary64") + random_words(
                "binary64", 20_000, np.random.default_rng(8))),
            "b16ftz": ("binary16", "ftz", list(range(1 << 16)))}


def _model(op, fmt, operands, subnormals):
    return exp_model(fmt, words_array(fmt, operands["a"]), subnormals)


def _cores(full: bool):
    return {prefix: ("exp", fmt, subnormals, {"a": words})
            for prefix, (fmt, subnormals, words) in _rtl_units(full).items()}


@pytest.mark.verilator
def test_rtl_bit_exact(build_root):
    simulate_fpu_cores(build_root, "exp", _cores(full=False), _model)


@pytest.mark.verilator
@pytest.mark.full
def test_rtl_bit_exact_full(build_root):
    simulate_fpu_cores(build_root, "exp_full", _cores(full=True), _model)
