"""cocotb testbench for generated Schur-complement units, several in one Verilator build.

``KFGEN_TB_GROUP`` names a JSON file: ``{"cores": [{"prefix", "manifest", "stim", "out"}]}``.
The simulated top (:func:`kfgen.sim.fpu.run.fpu_group_wrapper`) exposes each core's ports as
``<prefix>_<port>``. Each stimulus ``.npz`` holds the ``s_axis_tdata`` words, the expected
``m_axis_tdata`` and ``m_axis_tuser`` words, ``calm`` (how many matrices go first with no
idle input cycle and ``m_axis_tready`` always high), the probabilities ``gap`` (an idle input
cycle) and ``stall`` (``m_axis_tready`` low) for the rest, and a ``seed``.

One coroutine serves every core, one wake-up a clock (not one per matrix or per stream): at
the falling edge it drives each core's ``s_axis`` (a matrix stays offered until taken) and
``m_axis_tready``, in the read-only phase it samples both handshakes of every core, checks
both streams against the AXI4-Stream rules (:class:`~kfgen.sim.streams.StreamChecker`: the
core's ``m_axis``, and its own ``s_axis`` as a self-check), and compares each result with
the golden model's as it arrives. The calm matrices must be accepted exactly
``initiation_interval`` cycles apart and come out exactly ``latency_cycles`` after; every
result in order, bit for bit; nothing more.
"""

from __future__ import annotations

import json
import os

import cocotb
import numpy as np
from cocotb.clock import Clock
from cocotb.triggers import FallingEdge, ReadOnly

from ..streams import StreamChecker


class _Core:
    def __init__(self, dut, spec):
        self.prefix = spec["prefix"]
        self.manifest = json.loads(open(spec["manifest"]).read())
        self.out_path = spec["out"]
        stim = np.load(spec["stim"], allow_pickle=True)
        self.tdata = [int(x) for x in stim["tdata"]]
        self.expect = list(zip((int(x) for x in stim["expect_tdata"]), (int(x) for x in stim["expect_tuser"])))
        self.calm, self.gap, self.stall = int(stim["calm"]), float(stim["gap"]), float(stim["stall"])
        self.rng = np.random.default_rng(int(stim["seed"]))
        self.n = len(self.tdata)
        self.latency = self.manifest["latency_cycles"]
        self.ii = self.manifest["initiation_interval"]

        def sig(name):
            return getattr(dut, f"{self.prefix}_{name}")

        self.s_valid, self.s_ready, self.s_data = sig("s_axis_tvalid"), sig("s_axis_tready"), sig("s_axis_tdata")
        self.m_valid, self.m_ready = sig("m_axis_tvalid"), sig("m_axis_tready")
        self.m_data, self.m_user = sig("m_axis_tdata"), sig("m_axis_tuser")
        self.checkers = self._checkers()
        self.sent, self.offered, self.ready = 0, False, False
        self.in_cycle: list[int] = []
        self.got: list[tuple[int, int, int]] = []  # (tdata, tuser, cycle)
        self.errors: list[str] = []

    def _checkers(self):
        return [StreamChecker(f"{self.prefix}_m_axis", self.m_valid, self.m_ready,
                              {"tdata": self.m_data, "tuser": self.m_user}),
                StreamChecker(f"{self.prefix}_s_axis", self.s_valid, self.s_ready, {"tdata": self.s_data})]

    def reset(self):
        self.s_valid.value = 0
        self.m_ready.value = 0

    def restart(self):
        """The stimulus from its start, after a reset (fresh stream checkers)."""
        self.reset()
        self.checkers = self._checkers()
        self.sent, self.offered, self.ready = 0, False, False
        self.in_cycle, self.got = [], []

    def junk(self, rng):
        """Random traffic: any word offered (and withdrawn: this is traffic a reset will cut,
        not a stream the rules hold), any ready."""
        width = len(self.s_data)
        self.s_data.value = int.from_bytes(rng.bytes((width + 7) // 8), "little") & ((1 << width) - 1)
        self.s_valid.value = int(rng.random() < 0.5)
        self.m_ready.value = int(rng.random() < 0.5)

    def drive(self):
        calm = self.sent < self.calm
        if not self.offered and self.sent < self.n and (calm or self.rng.random() >= self.gap):
            self.s_data.value = self.tdata[self.sent]
            self.offered = True
        self.s_valid.value = int(self.offered)
        self.ready = len(self.got) < self.calm or self.rng.random() >= self.stall
        self.m_ready.value = int(self.ready)

    def sample(self, cycle):
        for checker in self.checkers:
            checker.sample(cycle)
        if self.offered and self.s_ready.value:
            self.in_cycle.append(cycle)
            self.sent += 1
            self.offered = False
        if self.ready and self.m_valid.value:
            i = len(self.got)
            word, user = int(self.m_data.value), int(self.m_user.value)
            self.got.append((word, user, cycle))
            if i >= self.n:
                self._error(f"result {i} beyond the {self.n} matrices")
            elif (word, user) != self.expect[i]:
                self._error(f"result {i}: got tdata={word:#x} tuser={user:#x}, expected "
                            f"tdata={self.expect[i][0]:#x} tuser={self.expect[i][1]:#x} "
                            f"(input {self.tdata[i]:#x})")
            elif i < self.calm and cycle - self.in_cycle[i] != self.latency:
                self._error(f"result {i}: latency {cycle - self.in_cycle[i]}, the manifest says {self.latency}")
            elif 0 < i < self.calm and self.in_cycle[i] - self.in_cycle[i - 1] != self.ii:
                self._error(f"matrix {i}: accepted {self.in_cycle[i] - self.in_cycle[i - 1]} cycles after the "
                            f"previous one with nothing held back; the manifest's initiation interval is {self.ii}")

    def _error(self, text):
        if len(self.errors) < 20:
            self.errors.append(f"{self.prefix}: {text}")

    @property
    def done(self):
        return len(self.got) >= self.n


async def _clean_run(dut, cores):
    """Every core's stimulus through, each result checked as it comes; then nothing more.
    The cycles taken."""
    cycle = 0
    limit = 1000 + max(4 * c.n * (c.ii + 1) + c.latency for c in cores)
    while not all(c.done for c in cores):
        await FallingEdge(dut.clk)
        cycle += 1
        assert cycle < limit, "timeout: " + ", ".join(f"{c.prefix} {len(c.got)}/{c.n}" for c in cores)
        for c in cores:
            c.drive()
        await ReadOnly()
        for c in cores:
            c.sample(cycle)
    # nothing more may come out
    for _ in range(max(c.latency for c in cores) + 4):
        await FallingEdge(dut.clk)
        cycle += 1
        for c in cores:
            c.s_valid.value = 0
            c.m_ready.value = 1
            c.ready = True
        await ReadOnly()
        for c in cores:
            c.sample(cycle)
    errors = [e for c in cores for e in c.errors]
    extra = [f"{c.prefix}: {len(c.got) - c.n} results too many" for c in cores if len(c.got) != c.n]
    assert not errors and not extra, "\n".join(extra + errors)
    return cycle


async def _reset(dut, cores, cycles=2):
    await FallingEdge(dut.clk)
    dut.rst.value = 1
    for c in cores:
        c.reset()
    for _ in range(cycles):
        await FallingEdge(dut.clk)
    dut.rst.value = 0


@cocotb.test()
async def stream(dut):
    group = json.loads(open(os.environ["KFGEN_TB_GROUP"]).read())
    cores = [_Core(dut, spec) for spec in group["cores"]]
    cocotb.start_soon(Clock(dut.clk, 10, unit="ns").start())
    await _reset(dut, cores)
    cycle = await _clean_run(dut, cores)
    for c in cores:
        np.savez(c.out_path, tdata=np.array([g[0] for g in c.got], dtype=object),
                 tuser=np.array([g[1] for g in c.got]), out_cycle=np.array([g[2] for g in c.got]),
                 in_cycle=np.array(c.in_cycle), cycles=cycle, m_axis_waits=c.checkers[0].waits,
                 s_axis_waits=c.checkers[1].waits)


@cocotb.test()
async def fault_campaign(dut):
    """``KFGEN_TB_SEQUENCES`` sequences: random traffic into every core cut by resets
    (``rst``) at random cycles, then, after a reset, the stimulus's clean run with every
    result against the golden model (the calm matrices at the manifest's exact latency and
    initiation interval) and nothing more out. Nothing may hang: each clean run has its
    timeout."""
    group = json.loads(open(os.environ["KFGEN_TB_GROUP"]).read())
    cores = [_Core(dut, spec) for spec in group["cores"]]
    rng = np.random.default_rng(cores[0].rng.integers(1 << 32))
    cocotb.start_soon(Clock(dut.clk, 10, unit="ns").start())
    longest = max(c.latency for c in cores)
    resets = 0
    for _ in range(int(os.environ.get("KFGEN_TB_SEQUENCES", "20"))):
        await _reset(dut, cores)
        for _ in range(int(rng.integers(5, 3 * longest))):
            await FallingEdge(dut.clk)
            if rng.random() < 0.03:
                await _reset(dut, cores, int(rng.integers(1, 4)))
                resets += 1
            for c in cores:
                c.junk(rng)
        await _reset(dut, cores)
        for c in cores:
            c.restart()
        await _clean_run(dut, cores)
    dut._log.info("fault campaign: %d resets in the traffic", resets)
