"""div, sqrt, i2f and f2i in Amaranth's simulator against the exact reference, bit for bit.

Every operand set is streamed through the unit with random ``i_valid`` gaps (idle cycles drive
random words, which must not leak into results); each result must come out exactly
``latency`` cycles after its operation was accepted, ``o_valid`` never at another time, and
equal :func:`kfgen.sim.float_ref.ref_op` in word and flags. Iterative dividers and square
roots are also offered back-to-back requests: ``i_ready`` must be high exactly when
``cycles_per_op`` cycles have passed since the last accepted operation, and a refused
operation is held until it is accepted (none lost, none duplicated).
"""

import gc
from collections import deque
from itertools import combinations

import numpy as np
import pytest
from amaranth.sim import Simulator

from kfgen.hdl.arith.float.div import FloatDiv
from kfgen.hdl.arith.float.f2i import FloatToInt
from kfgen.hdl.arith.float.format import FloatFormat
from kfgen.hdl.arith.float.i2f import IntToFloat
from kfgen.hdl.arith.float.sqrt import FloatSqrt
from kfgen.hdl.arith.float.timing import StagePlans
from kfgen.sim.float_ref import directed_corpus, random_operands, ref_op

UNITS = {"div": FloatDiv, "sqrt": FloatSqrt, "i2f": IntToFloat, "f2i": FloatToInt}
ARITY = {"div": 2, "sqrt": 1, "i2f": 1, "f2i": 1}
MASK32 = (1 << 32) - 1


def unused(unit):
    """A unit built for its properties only (no UnusedElaboratable warning)."""
    unit._MustUse__silence = True
    return unit


def operand_sets(op, fmt, n_random, seed, corpus=1):
    """Every ``corpus``-th set of the directed corpus (none if 0) and ``n_random`` random
    sets, as unsigned words."""
    sets = list(directed_corpus(fmt, op))[::corpus] if corpus else []
    sets += random_operands(fmt, n_random, np.random.default_rng(seed), op)
    return [tuple(w & MASK32 if op == "i2f" else w for w in s) for s in sets]


def stream(unit, op, sets, seed, idle=0.3):
    """Stream ``sets`` through ``unit``; returns the ``(word, flags)`` results in order.

    Asserts the handshake and the timing on the way: ``o_valid`` exactly ``latency`` cycles
    after each accepted operation and at no other time; for ``cycles_per_op > 1``, ``i_ready``
    high exactly when the last acceptance is ``cycles_per_op`` or more cycles back.
    """
    rng = np.random.default_rng(seed)
    inputs = [getattr(unit, name) for name in ("i_a", "i_b")[:ARITY[op]]]
    in_width = 32 if op == "i2f" else unit.fmt.width
    latency, interval = unit.latency, unit.initiation_interval
    results = []

    async def testbench(ctx):
        index, cycle, last_accept, holding = 0, 0, None, False
        due = deque()
        while index < len(sets) or due:
            present = index < len(sets) and (holding or rng.random() >= idle)
            words = sets[index] if present else \
                [int(rng.integers(0, 1 << in_width, dtype=np.uint64)) for _ in inputs]
            for port, word in zip(inputs, words):
                ctx.set(port, word)
            ctx.set(unit.i_valid, present)
            if interval > 1:
                ready = ctx.get(unit.i_ready)
                expected = last_accept is None or cycle - last_accept >= interval
                assert ready == expected, f"cycle {cycle}: i_ready {ready}, expected {expected}"
            else:
                ready = 1
            if present and ready:
                due.append(cycle + latency)
                last_accept, holding = cycle, False
                index += 1
            else:
                holding = present  # a refused operation stays on the inputs until accepted
            valid = ctx.get(unit.o_valid)
            assert valid == bool(due and due[0] == cycle), f"cycle {cycle}: o_valid {valid}"
            if valid:
                results.append((ctx.get(unit.o_y), ctx.get(unit.o_flags)))
                due.popleft()
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


def check(unit, op, sets, seed, idle=0.3):
    got = stream(unit, op, sets, seed, idle)
    assert len(got) == len(sets)
    want = [ref_op(op, unit.fmt, *s, subnormals=unit.subnormals) for s in sets]
    bad = [f"{op}({', '.join(map(hex, s))}) = {g[0]:#x} flags {g[1]:05b}, "
           f"reference {w[0]:#x} flags {w[1]:05b}"
           for s, g, w in zip(sets, got, want) if g != w]
    assert not bad, f"{len(bad)} of {len(sets)} differ:\n" + "\n".join(bad[:10])


# --------------------------------------------------------------------------- div and sqrt
@pytest.mark.parametrize("op", ["div", "sqrt"])
@pytest.mark.parametrize("fmt, subnormals, n_random", [
    # binary32's IEEE units run on Verilator in make test (tests/fpu/test_fpu_cocotb.py)
    pytest.param("binary32", "ieee", 1500, marks=pytest.mark.full),
    ("binary32", "ftz", 500),
    ("binary16", "ieee", 500),
    ("binary16", "ftz", 300),
    ("bfloat16", "ieee", 500),
    ("bfloat16", "ftz", 300),
])
def test_pipelined(op, fmt, subnormals, n_random):
    fmt = FloatFormat.parse(fmt)
    unit = UNITS[op](fmt, subnormals=subnormals)
    assert unit.initiation_interval == 1 and not hasattr(unit, "i_ready")
    check(unit, op, operand_sets(op, fmt, n_random, seed=len(fmt.name) + n_random), seed=1)


@pytest.mark.parametrize("op", ["div", "sqrt"])
@pytest.mark.parametrize("fmt, subnormals, cycles, n_random, corpus", [
    pytest.param("binary32", "ieee", 4, 400, 3, marks=pytest.mark.full),  # a third of the corpus (all of it for sqrt)
    ("binary32", "ieee", 2, 300, 0),            # the fewest cycles that are iterative
    ("binary32", "ftz", 4, 200, 0),
    ("binary32", "ieee", "steps", 60, 0),       # one step per cycle: the smallest
    ("binary16", "ieee", 3, 300, 0),
    ("bfloat16", "ieee", 5, 300, 0),
])
def test_iterative(op, fmt, subnormals, cycles, n_random, corpus):
    fmt = FloatFormat.parse(fmt)
    cycles = UNITS[op].iterations(fmt) if cycles == "steps" else cycles
    unit = UNITS[op](fmt, subnormals=subnormals, cycles_per_op=cycles)
    assert unit.initiation_interval == cycles
    # Mostly back-to-back requests: i_ready holds most of them back.
    corpus = corpus if op == "div" else min(corpus, 1)
    check(unit, op, operand_sets(op, fmt, n_random, seed=cycles, corpus=corpus), seed=2,
          idle=0.1)


def some_stage_counts(plans):
    """The fewest, a few more, the middle and the most registers a unit can have."""
    counts = list(plans)
    return sorted({*counts[:3], counts[len(counts) // 2], counts[-1]})


@pytest.mark.parametrize("op", ["div", "sqrt"])
@pytest.mark.parametrize("cycles", [1, 4])
def test_stage_counts_set_the_latency(op, cycles):
    """Short streams through binary16 units with registers placed for several stage counts."""
    fmt = FloatFormat.parse("binary16")
    for stages in some_stage_counts(unused(UNITS[op](fmt, cycles_per_op=cycles)).PLANS):
        unit = UNITS[op](fmt, stages=stages, cycles_per_op=cycles)
        assert unit.latency == stages
        check(unit, op, operand_sets(op, fmt, 12, seed=stages, corpus=0), seed=stages)


@pytest.mark.filterwarnings("ignore::amaranth.hdl.UnusedElaboratable")
@pytest.mark.parametrize("op", ["div", "sqrt"])
def test_recurrence_parameters_are_checked(op):
    cls = UNITS[op]
    steps = cls.iterations(FloatFormat())
    for bad in (0, steps + 1, 2.0, True):
        with pytest.raises(ValueError, match="cycles_per_op"):
            cls(cycles_per_op=bad)
    with pytest.raises(ValueError, match="stages"):
        cls(cycles_per_op=4, stages=4)  # the core's 4 cycles and at least the output register
    with pytest.raises(ValueError, match="stages"):
        cls(stages=steps + 20)
    with pytest.raises(ValueError, match="format"):
        cls("binary33")
    with pytest.raises(ValueError, match="subnormals"):
        cls(subnormals="daz")
    gc.collect()  # (the half-built units warn here, where the warning is ignored)
    unit = unused(cls(cycles_per_op=4, stages=5))
    assert (unit.latency, unit.initiation_interval, unit.cycles_per_op) == (5, 4, 4)
    assert "i_ready" in unit.signature.members


@pytest.mark.parametrize("op", ["div", "sqrt"])
def test_default_has_a_register_after_every_step(op):
    """Two steps (~10 ns on an ECP5) would not fit 100 MHz: the delay model keeps them apart."""
    unit = unused(UNITS[op]())
    plan = unit.PLANS[unit.latency]
    steps = UNITS[op].iterations(unit.fmt)
    assert all(f"{op}.{i}" in plan for i in range(1, steps + 1))


def test_stage_plans_minimise_the_longest_stage():
    """Against every placement of a small datapath: the longest stage is the shortest possible."""
    segments = [("in", 0), ("a", 3), ("b", 5), ("c", 2), ("d", 6), ("e", 4), ("out", 1)]
    plans = StagePlans(segments)
    names = [name for name, _ in segments]
    delay = dict(segments)

    def longest(chosen):
        stages, run = [], 0
        for name in names:
            run += delay[name]
            if name in chosen:
                stages.append(run)
                run = 0
        return max(stages + [run])

    assert list(plans) == list(range(len(names) + 1)) and plans[0] == ()
    for count in range(1, len(names) + 1):
        plan = plans[count]
        assert len(plan) == count and plan[-1] == "out"
        assert [n for n in names if n in plan] == list(plan)
        best = min(longest(set(c) | {"out"}) for c in combinations(names[:-1], count - 1))
        assert longest(set(plan)) == best
    assert plans.default(budget=8.5) == 3  # (a + b, c + d, e + out)
    # An iterative core: forced, hidden, and its cycles counted.
    core = StagePlans([("a", 4), ("core", 20), ("b", 3), ("out", 3)], forced=("core",),
                      offset=3, hidden=("core",))
    assert list(core) == [5, 6, 7]
    assert core[5] == ("out",) and core[7] == ("a", "b", "out")


# --------------------------------------------------------------------------- conversions
@pytest.mark.parametrize("op", ["i2f", "f2i"])
@pytest.mark.parametrize("fmt, subnormals, n_random", [
    ("binary32", "ieee", 800),
    ("binary32", "ftz", 200),
    ("binary16", "ieee", 500),
    ("binary64", "ieee", 500),
])
def test_conversion(op, fmt, subnormals, n_random):
    fmt = FloatFormat.parse(fmt)
    unit = UNITS[op](fmt, subnormals=subnormals)
    check(unit, op, operand_sets(op, fmt, n_random, seed=n_random), seed=3)


@pytest.mark.parametrize("op", ["i2f", "f2i"])
def test_conversion_stage_counts(op):
    fmt = FloatFormat.parse("binary32")
    for stages in some_stage_counts(unused(UNITS[op](fmt)).PLANS):
        unit = UNITS[op](fmt, stages=stages)
        assert unit.latency == stages and unit.initiation_interval == 1
        check(unit, op, operand_sets(op, fmt, 30, seed=stages, corpus=0), seed=stages)


@pytest.mark.filterwarnings("ignore::amaranth.hdl.UnusedElaboratable")
@pytest.mark.parametrize("op", ["i2f", "f2i"])
def test_conversion_parameters_are_checked(op):
    with pytest.raises(ValueError, match="stages"):
        UNITS[op](stages=-1)
    with pytest.raises(ValueError, match="exp_bits"):
        UNITS[op]("e2m5")
    gc.collect()


def test_i2f_binary16_overflow_boundary():
    """65519 rounds down to 65504, 65520 up to infinity (OF|NX)."""
    fmt = FloatFormat.parse("binary16")
    sets = [(v & MASK32,) for v in (65519, 65520, -65519, -65520, 2048, 2049, 2051, -(1 << 31))]
    check(IntToFloat(fmt), "i2f", sets, seed=4)
