"""The Schur-complement core in Amaranth's simulator, in a 6-bit format (e3m2) where it is small
enough to simulate in a second: every result against the golden model, the handshakes, the
latency and the initiation interval of an iterative divider (Verilator runs the real formats,
:mod:`test_schur_cocotb`)."""

import numpy as np
import pytest
from amaranth.sim import Simulator

from kfgen.hdl.schur.core import Schur
from kfgen.hdl.schur.params import SchurParams
from kfgen.sim.schur.model import stimulus
from kfgen.sim.schur.run import expected


@pytest.mark.parametrize("kw", [{"div_cycles_per_op": 3}, {"div_cycles_per_op": 1, "div_latency": 2}],
                         ids=["iterative", "pipelined"])
def test_core_streams_in_amaranth_simulator(kw):
    p = SchurParams(format="e3m2", mul_latency=1, add_latency=1, **kw)
    dut = Schur(p)
    rng = np.random.default_rng(4)
    n, calm = 120, 12
    # the status cases (zero and negative pivots, NaNs, infinities), then positive-definite,
    # symmetric and random words
    matrices = stimulus(p.fmt, 2, n, rng)
    tdata, want_data, want_user = expected(p, matrices)
    got, in_cycle, out_cycle = [], [], []

    async def bench(ctx):
        sent, cycle = 0, 0
        while len(got) < n:
            offer = sent < n and (sent < calm or rng.random() < 0.7)
            ready = len(got) < calm or rng.random() < 0.4
            ctx.set(dut.s_axis_tvalid, offer)
            if offer:
                ctx.set(dut.s_axis_tdata.as_value(), tdata[sent])
            ctx.set(dut.m_axis_tready, ready)
            # (the handshakes as the next edge sees them)
            _, _, s_ready, m_valid, m_data, m_user = await ctx.tick().sample(
                dut.s_axis_tready, dut.m_axis_tvalid, dut.m_axis_tdata.as_value(), dut.m_axis_tuser.as_value())
            if offer and s_ready:
                in_cycle.append(cycle)
                sent += 1
            if ready and m_valid:
                got.append((m_data, m_user))
                out_cycle.append(cycle)
            cycle += 1
            assert cycle < 50 * n

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    assert got == list(zip(want_data, want_user))
    # d = 2: the input register, two divisions, two multiplies and two adds, the FIFO's two cycles
    assert dut.latency == 1 + 2 * (p.div_latency + p.mul_latency + p.add_latency) + 2
    assert [o - i for i, o in zip(in_cycle[:calm], out_cycle[:calm])] == [dut.latency] * calm
    assert set(np.diff(in_cycle[:calm])) == {dut.initiation_interval}
    assert min(np.diff(in_cycle)) == dut.initiation_interval
