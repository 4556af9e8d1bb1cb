"""The add, sub, mul and fma units in Amaranth's simulator, bit for bit and flag for flag
against the exact reference :func:`kfgen.sim.float_ref.ref_op`.

Operands are streamed through the pipeline with random ``i_valid`` gaps; every result must
arrive exactly ``latency`` cycles after its operands, in order. The Python simulator is slow,
so the runs here are sized for seconds; the long sweeps run on Verilator.
"""

import zlib

import numpy as np
import pytest
from amaranth.hdl import Fragment
from amaranth.sim import Simulator

from kfgen.hdl.arith.float.add import FloatAdd, FloatSub
from kfgen.hdl.arith.float.fma import FloatFMA
from kfgen.hdl.arith.float.format import FLAG_NAMES, FloatFormat
from kfgen.hdl.arith.float.mul import FloatMul
from kfgen.sim.float_ref import directed_corpus, random_operands, ref_op

UNITS = {"add": FloatAdd, "sub": FloatSub, "mul": FloatMul, "fma": FloatFMA}
FORMATS = ["binary32", "binary16", "bfloat16", "e6m11"]
# (directed, random) operand sets per binary32 run (a directed corpus smaller than its share
# is taken whole); the other formats get half. About 45 s in all.
SIZES = {"add": (2000, 3000), "sub": (2000, 3000), "mul": (2000, 3000), "fma": (2500, 2000)}


def stream(dut, operands, rng, gap=0.3):
    """Feed ``operands`` (tuples for i_a, i_b[, i_c]) with random idle cycles.

    Returns ``(sent, got)``: the cycle of each accepted operand set, and
    ``(cycle, o_y, o_flags)`` for each cycle with ``o_valid`` high.
    """
    ports = [getattr(dut, name) for name in ("i_a", "i_b", "i_c")[:len(operands[0])]]
    idle = rng.random(4 * len(operands) + 16) < gap
    sent, got = [], []

    async def tb(ctx):
        cycle, i = 0, 0
        while i < len(operands) or cycle <= sent[-1] + dut.latency:
            if i < len(operands) and not idle[cycle]:
                for port, word in zip(ports, operands[i]):
                    ctx.set(port, word)
                ctx.set(dut.i_valid, 1)
                sent.append(cycle)
                i += 1
            else:
                ctx.set(dut.i_valid, 0)
            if ctx.get(dut.o_valid):
                got.append((cycle, ctx.get(dut.o_y), ctx.get(dut.o_flags)))
            if dut.latency:
                await ctx.tick()
            else:  # no registers, no clock domain
                await ctx.delay(1e-8)
            cycle += 1

    sim = Simulator(dut)
    if dut.latency:
        sim.add_clock(1e-8)
    sim.add_testbench(tb)
    sim.run()
    return sent, got


def flag_names(flags):
    return "|".join(n for i, n in enumerate(FLAG_NAMES) if flags >> i & 1) or "-"


def check_stream(dut, op, operands, rng):
    """Stream ``operands`` through ``dut``; assert timing and every result against ref_op."""
    sent, got = stream(dut, operands, rng)
    assert len(got) == len(operands), f"{len(operands)} operations in, {len(got)} results out"
    assert [c for c, _, _ in got] == [c + dut.latency for c in sent], "latency is not exact"
    bad = []
    for ops, (_, y, flags) in zip(operands, got):
        want = ref_op(op, dut.fmt, *ops, subnormals=dut.subnormals)
        if (y, flags) != want:
            bad.append(f"{op}({', '.join(f'{w:#x}' for w in ops)}) = {y:#x} {flag_names(flags)}, "
                       f"want {want[0]:#x} {flag_names(want[1])}")
    assert not bad, f"{len(bad)}/{len(operands)} wrong:\n" + "\n".join(bad[:12])


#: binary32's fused multiply-add with ftz (the slowest unit to simulate in Amaranth, half a
#: minute) runs in make test-full: ftz's FMA runs in the narrower formats in every run, and
#: binary32's on Verilator (tests/fpu/test_fpu_cocotb.py). So do binary32's IEEE units (40 s
#: of CPU in all): make test runs every one of them on Verilator (its "binary32" group).
FULL_ONLY = {("fma", "binary32", "ftz")} | {(op, "binary32", "ieee") for op in ("add", "sub", "mul", "fma")}
#: bfloat16 and e6m11 (the code binary16 runs, other widths: 35 s) in make test-full too.
FULL_ONLY |= {(op, fmt, sub) for op in ("add", "sub", "mul", "fma") for fmt in ("bfloat16", "e6m11") for sub in ("ieee", "ftz")}


@pytest.mark.parametrize("op, fmt_name, subnormals", [
    pytest.param(op, fmt, sub, id=f"{op}-{fmt}-{sub}", marks=[pytest.mark.full] if (op, fmt, sub) in FULL_ONLY else [])
    for op in UNITS for fmt in FORMATS for sub in ("ieee", "ftz")])
def test_unit_matches_reference(op, fmt_name, subnormals):
    fmt = FloatFormat.parse(fmt_name)
    rng = np.random.default_rng(zlib.crc32(f"{op} {fmt_name} {subnormals}".encode()))
    n_dir, n_rand = SIZES[op]
    if fmt_name != "binary32":
        n_dir, n_rand = n_dir // 2, n_rand // 2
    corpus = directed_corpus(fmt, op)
    picks = rng.choice(len(corpus), size=min(n_dir, len(corpus)), replace=False)
    operands = [corpus[i] for i in sorted(picks)] + random_operands(fmt, n_rand, rng, op)
    # The default stage count for binary32; the others try the neighbouring plans.
    cls = UNITS[op]
    stages = None if fmt_name == "binary32" else cls.DEFAULT_STAGES + FORMATS.index(fmt_name) - 2
    dut = cls(fmt, subnormals=subnormals, stages=stages)
    check_stream(dut, op, operands, rng)


@pytest.mark.parametrize("op", list(UNITS))
def test_stages_set_latency(op):
    """Every stage count builds a unit whose latency is exactly that count."""
    fmt = FloatFormat.parse("binary16")
    cls = UNITS[op]
    rng = np.random.default_rng(zlib.crc32(op.encode()))
    for stages in sorted(cls.PLANS):
        dut = cls(fmt, stages=stages)
        assert dut.latency == stages and dut.initiation_interval == 1
        check_stream(dut, op, random_operands(fmt, 24, rng, op), rng)


def test_default_format_is_binary32():
    for cls in UNITS.values():
        unit = cls()
        Fragment.get(unit, None)
        assert unit.fmt == FloatFormat.parse("binary32") and unit.latency == cls.DEFAULT_STAGES
        assert len(unit.i_a) == 32 and len(unit.o_y) == 32 and len(unit.o_flags) == 5


@pytest.mark.parametrize("kwargs, match", [
    (dict(fmt="binary8"), "unknown format"),
    (dict(fmt=32), "fmt must be"),
    (dict(subnormals="daz"), "subnormals must be"),
    (dict(stages=-1), "stages must be"),
    (dict(stages=99), "stages must be"),
    (dict(stages=2.0), "stages must be"),
    (dict(stages=True), "stages must be"),
])
def test_bad_parameters(kwargs, match):
    for cls in UNITS.values():
        with pytest.raises(ValueError, match=match):
            cls(**kwargs)
