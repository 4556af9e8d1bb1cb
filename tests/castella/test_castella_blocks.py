"""The Castella datapath blocks (fixed-point helpers, pipeline scheduler, gain divider, LUT
multipliers) and the whole core in Amaranth's own simulator, against the golden model."""


import numpy as np
import pytest
from amaranth.hdl import C, Module, Signal, signed, unsigned
from amaranth.sim import Simulator

from kfgen.hdl.arith.divide import gain_divider
from kfgen.hdl.arith.fixed import rsr, saturate
from kfgen.hdl.arith.multiply import shift_add_multiply
from kfgen.hdl.arith.pipeline import Pipeline, Staged
from kfgen.hdl.castella.core import Castella
from kfgen.hdl.castella.params import CastellaParams, Fmt
from kfgen.sim.castella import model

from helpers import run_comb, run_staged



@pytest.mark.parametrize("shift", [-2, 0, 1, 3])
def test_rsr_matches_model_exhaustively(shift):
    m = Module()
    a = Signal(signed(8))
    y = Signal(signed(12))
    m.d.comb += y.eq(rsr(a, shift))
    vals = list(range(-128, 128))
    got = [g[0] for g in run_comb(m, [a], [y], [(v,) for v in vals])]
    assert got == [int(v) for v in model.rsr(np.array(vals), shift)]


@pytest.mark.parametrize("fmt", [Fmt(5, 0, False), Fmt(5, 2, True)])
def test_saturate_matches_model_exhaustively(fmt):
    m = Module()
    a = Signal(signed(9))
    y = Signal(signed(6) if fmt.signed else unsigned(5))
    flag = Signal()
    val, ovf = saturate(a, fmt)
    m.d.comb += [y.eq(val), flag.eq(ovf)]
    vals = list(range(-256, 256))
    got = run_comb(m, [a], [y, flag], [(v,) for v in vals])
    want = model.sat(np.array(vals), fmt)
    assert [g[0] for g in got] == [int(v) for v in want]
    assert [bool(g[1]) for g in got] == [bool(v != w) for v, w in zip(vals, want)]


def test_pipeline_balances_operands():
    """An operand from an earlier stage is delayed to meet a later one."""
    m = Module()
    pl = Pipeline(m)
    a = Signal(8)
    b = Signal(8)
    sa, sb = Staged(a, 0), Staged(b, 0)
    sb2 = pl.reg("b2", lambda x: x + 1, pl.reg("b1", lambda x: x + 1, sb))  # stage 2
    out = pl.reg("sum", lambda x, y: x + y, sa, sb2)                      # stage 3
    assert out.stage == 3
    seen = []

    async def tb(ctx):
        for k in range(8):
            ctx.set(a, k)
            ctx.set(b, 10 * k)
            seen.append(ctx.get(out.sig))
            await ctx.tick()

    sim = Simulator(m)
    sim.add_clock(1e-8)
    sim.add_testbench(tb)
    sim.run()
    # at cycle k the output holds a[k-3] + b[k-3] + 2
    assert seen[3:] == [(k - 3) + 10 * (k - 3) + 2 for k in range(3, 8)]


@pytest.mark.parametrize("extra", [0, -2, 3])
def test_gain_divider_matches_model(extra):
    p = CastellaParams()
    m = Module()
    pl = Pipeline(m)
    num, den = Signal(16), Signal(18)
    k = gain_divider(pl, "k", Staged(num, 0), Staged(den, 0), extra, p.gain_width)
    rng = np.random.default_rng(extra + 7)
    dens = rng.integers(1, 1 << 17, 300)
    nums = np.minimum((rng.random(300) * dens * 1.2).astype(np.int64), (1 << 16) - 1)
    # corners: zero, just below and at the overflow boundary
    nums = np.concatenate([nums, [0, 99, 100, 65535]])
    dens = np.concatenate([dens, [5, 100, 100, 65535]])
    got = run_staged(m, (num, den), k, [(int(n), int(d)) for n, d in zip(nums, dens)])
    want, _ = model.gain_divide(nums, dens, extra, p.gain_width)
    assert got == [int(w) for w in want]


def test_core_in_amaranth_simulator_matches_model():
    """A short two-track stream through the whole core in Amaranth's simulator."""
    p = CastellaParams(tracks=2)
    dut = Castella(p)
    rng = np.random.default_rng(3)
    steps = 12
    ys = (20000 + 200 * np.arange(steps)[None, :] + rng.normal(0, 100, (2, steps))).astype(np.int64)
    tids = np.tile(np.arange(2), steps)
    yv = ys.T.reshape(-1)
    rs = np.repeat(np.arange(steps) == 0, 2)
    rows, _ = model.expected_stream(p, tids, yv, rs)
    rf = p.field_list("m_axis_tdata")
    got = []

    async def tb(ctx):
        ctx.set(dut.m_axis_tready, 1)
        i = 0
        for _ in range(2000):
            if i < len(yv):
                ctx.set(dut.s_axis_tvalid, 1)
                ctx.set(dut.s_axis_tdata, int(yv[i]))
                ctx.set(dut.s_axis_tid, int(tids[i]))
                ctx.set(dut.s_axis_tuser, int(rs[i]))
            else:
                ctx.set(dut.s_axis_tvalid, 0)
            if ctx.get(dut.s_axis_tvalid) and ctx.get(dut.s_axis_tready):
                i += 1
            if ctx.get(dut.m_axis_tvalid):
                got.append(ctx.get(dut.m_axis_tdata))
            if len(got) == len(yv):
                break
            await ctx.tick()

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(tb)
    sim.run()
    want = []
    for r in rows:
        w = 0
        for f in rf:
            w |= (r[f["name"]] & ((1 << f["width"]) - 1)) << f["lsb"]
        want.append(w)
    assert got == want


@pytest.mark.parametrize("const", [None, 28873])
def test_shift_add_multiply_is_exact(const):
    """Unsigned selector times a signed signal (or a constant), through the pipelined tree."""
    m = Module()
    pl = Pipeline(m)
    a, b = Signal(5), Signal(signed(9))
    rhs = Staged(b, 0) if const is None else Staged(C(const), 0)
    prod = shift_add_multiply(pl, "p", Staged(a, 0), rhs)
    assert prod.stage == 3  # ceil(log2(5)) adder levels
    vecs = [(x, y) for x in range(32) for y in (-256, -255, -1, 0, 1, 77, 255)]
    got = run_staged(m, (a, b), prod, vecs)
    assert got == [x * (y if const is None else const) for x, y in vecs]
