"""Generated floating-point units in Verilator under cocotb, bit for bit and flag for flag
against the exact reference (:mod:`kfgen.sim.float_ref`).

Units of one format share a Verilator build (a wrapper instantiates them side by side, which
also shows that differently named cores coexist). Operands: the directed corpus plus random
sets drawn across every exponent range; operations are streamed with random ``i_valid`` gaps
and each result must arrive exactly ``latency_cycles`` after its operation.
"""

import os

import numpy as np
import pytest

from kfgen.hdl.arith.float.format import FloatFormat
from kfgen.sim.float_ref import conversion_sweep, directed_corpus, random_operands, ref_op
from kfgen.sim.fpu.run import run_fpu_group

from helpers import VERILATOR_CACHE, kfgen

pytestmark = pytest.mark.verilator

ALL_OPS = ("add", "sub", "mul", "div", "sqrt", "fma", "i2f", "f2i")

# name: (format, subnormals, {prefix: (op, cycles_per_op)}, random sets per op)
GROUPS = {
    "binary32": ("binary32", "ieee", {op: (op, 1) for op in ALL_OPS}, 5_000),
    "binary32_ftz": ("binary32", "ftz", {op: (op, 1) for op in ("add", "mul", "div", "sqrt", "fma")}, 3_000),
    "binary32_iter": ("binary32", "ieee", {"div4": ("div", 4), "sqrt4": ("sqrt", 4), "div26": ("div", 26)}, 2_000),
    "binary16": ("binary16", "ieee", {op: (op, 1) for op in ALL_OPS}, 3_000),
    "bfloat16": ("bfloat16", "ieee", {op: (op, 1) for op in ("add", "sub", "mul", "div", "sqrt", "fma")}, 3_000),
    "binary64": ("binary64", "ieee", {op: (op, 1) for op in ("add", "mul", "div", "sqrt", "fma", "i2f", "f2i")},
                 1_500),
    "e6m11": ("e6m11", "ieee", {op: (op, 1) for op in ("add", "mul", "div", "fma")}, 1_500),
}
FULL_RANDOM = 1_000_000


def _expected(fmt, op, subnormals, sets):
    names = ("a", "b", "c")[:len(sets[0])]
    operands = {k: [s[i] for s in sets] for i, k in enumerate(names)}
    y, flags = [], []
    for s in sets:
        w, f = ref_op(op, fmt, *s, subnormals=subnormals)
        y.append(w)
        flags.append(f)
    return operands, (y, flags)


def _simulate(build_root, name, units, seed):
    """Generate each unit ``prefix: (op, format, subnormals, cycles_per_op, operand sets)``,
    run them side by side in one Verilator build and check every word and flag."""
    root = build_root / "fpu" / name
    spec = {}
    for prefix, (op, fmt_name, subnormals, cpo, sets) in units.items():
        top = f"f_{name}_{prefix}"
        kfgen("fpu", "--op", op, "--format", fmt_name, "--subnormals", subnormals,
              "--cycles-per-op", cpo, "--name", top, "-o", root / top)
        spec[prefix] = (root / top, top, *_expected(FloatFormat.parse(fmt_name), op, subnormals, sets))
    # KFGEN_WAVES=1 make test: an FST per group in its sim_build directory
    results = run_fpu_group(root / "sim_build", spec, gap=0.2, seed=seed, name=name, cache_dir=VERILATOR_CACHE,
                            waves=bool(os.environ.get("KFGEN_WAVES")))
    for prefix, (_, _, operands, (y, flags)) in spec.items():
        res = results[prefix]
        # the testbench compared each result as it came; recheck the whole record here
        assert [int(v) for v in res["y"]] == y, prefix
        assert [int(v) for v in res["flags"]] == flags, prefix
    return results


def _run_group(build_root, group, n_random, seed):
    fmt_name, subnormals, units, _ = GROUPS[group]
    fmt = FloatFormat.parse(fmt_name)
    rng_seeds = {prefix: seed + 97 * k for k, prefix in enumerate(units)}
    return _simulate(build_root, group, {
        prefix: (op, fmt_name, subnormals, cpo,
                 list(directed_corpus(fmt, op))
                 + list(random_operands(fmt, n_random, np.random.default_rng(rng_seeds[prefix]), op)))
        for prefix, (op, cpo) in units.items()}, seed)


#: Groups run in make test-full only (their units share every line of Amaranth with the
#: binary32 group that runs; the engine cores' RTL tests run iterative division and square
#: root in every run).
FULL_GROUPS = ("bfloat16", "binary32_ftz", "e6m11", "binary16", "binary64", "binary32_iter")


@pytest.mark.parametrize("group", [g if g not in FULL_GROUPS else pytest.param(g, marks=pytest.mark.full)
                                   for g in GROUPS])
def test_fpu_units_bit_exact(build_root, group):
    results = _run_group(build_root, group, GROUPS[group][3], seed=1)
    for prefix, (op, cpo) in GROUPS[group][2].items():
        res = results[prefix]
        # an iterative unit takes a new operation every cycles_per_op cycles, no sooner
        if cpo > 1:
            assert np.min(np.diff(res["in_cycle"])) == cpo, prefix


@pytest.mark.full
def test_fpu_binary32_million(build_root):
    _run_group(build_root, "binary32", FULL_RANDOM, seed=2)


@pytest.mark.full
def test_fpu_conversion_sweeps(build_root):
    """i2f and f2i at every rounding and range boundary (:func:`conversion_sweep`), in
    binary16 (overflowing i2f), binary32 and binary64 (exact i2f, saturating f2i)."""
    units = {}
    for fmt_name in ("binary16", "binary32", "binary64"):
        fmt = FloatFormat.parse(fmt_name)
        for op in ("i2f", "f2i"):
            sets = conversion_sweep(fmt, op) + list(directed_corpus(fmt, op))
            units[f"{op}_{fmt_name}"] = (op, fmt_name, "ieee", 1, sets)
    _simulate(build_root, "conversions", units, seed=3)


@pytest.mark.full
def test_fpu_16bit_exhaustive(build_root):
    """Every binary16 and bfloat16 word through the one-operand float units (sqrt, f2i),
    both subnormal modes for sqrt (an exhaustive sweep: make test-full; every run has the
    directed and random operands of test_fpu_units_bit_exact in both formats)."""
    units = {}
    for fmt_name in ("binary16", "bfloat16"):
        words = [(w,) for w in range(1 << 16)]
        units[f"sqrt_{fmt_name}"] = ("sqrt", fmt_name, "ieee", 1, words)
        units[f"sqrtftz_{fmt_name}"] = ("sqrt", fmt_name, "ftz", 1, words)
        units[f"f2i_{fmt_name}"] = ("f2i", fmt_name, "ieee", 1, words)
    _simulate(build_root, "exhaustive16", units, seed=4)
