"""cocotb testbench of :class:`kfgen.sim.streams.StreamChecker` on the small source that
:mod:`test_stream_checker` builds: ``KFGEN_TB_FAULT`` picks the rule the source breaks
(``none`` for a correct one), and the checker must fail the run exactly then."""

import os

import cocotb
import numpy as np
from cocotb.clock import Clock
from cocotb.triggers import FallingEdge, ReadOnly

from kfgen.sim.streams import StreamChecker

FAULTS = ("none", "tdata", "tid", "tuser", "tvalid")
CYCLES = 300


@cocotb.test()
async def stream(dut):
    fault = os.environ["KFGEN_TB_FAULT"]
    rng = np.random.default_rng(int(os.environ.get("KFGEN_TB_SEED", "1")))
    cocotb.start_soon(Clock(dut.clk, 10, unit="ns").start())
    dut.rst.value = 1
    dut.fault.value = FAULTS.index(fault)
    dut.m_axis_tready.value = 0
    for _ in range(2):
        await FallingEdge(dut.clk)
    dut.rst.value = 0
    checker = StreamChecker.axis(dut, "m_axis")
    for cycle in range(1, CYCLES + 1):
        await FallingEdge(dut.clk)
        dut.m_axis_tready.value = int(rng.random() < 0.5)
        await ReadOnly()
        checker.sample(cycle)
    # a correct run must have exercised both sides of the rule
    assert checker.waits > 20 and checker.transfers > 20, (checker.waits, checker.transfers)
