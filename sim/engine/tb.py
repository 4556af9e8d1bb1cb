"""The cocotb harness of a generated engine core (the UKF, the IMM): :class:`TB` drives it as
software would, through cocotbext-axi's ``AxiMaster`` (bursts for the buffer's regions, single
beats for the registers, random idle cycles and backpressure on every channel, AXI handshake
checkers once a clock), and keeps the golden memory (:func:`kfgen.sim.linalg.exec.run` on the
core's own programs): every word read back is compared with it, every step's cycles with the
manifest's ``cycles``.

Environment: ``KFGEN_TB_MANIFEST``, the core's ``TOP.json``; ``KFGEN_TB_SEED`` (default 1);
``KFGEN_TB_CALM`` (1: no per-clock monitor and no random pauses, for long runs).

No wait is unbounded: waits on ``irq`` and polls of ``STATUS`` give up after
:func:`kfgen.sim.engine.watchdog.bound` of the step's manifest cycles, naming the step.
"""

from __future__ import annotations

import json
import logging
import os
import sys

import cocotb
import numpy as np
from cocotb.clock import Clock
from cocotb.simtime import get_sim_time
from cocotb.triggers import ClockCycles, FallingEdge, ReadOnly, RisingEdge
from cocotbext.axi import AxiBus, AxiMaster, AxiResp

from kfgen.sim.linalg.exec import from_words, to_words
from kfgen.sim.streams import StreamChecker

from .prologue import Prologue
from .watchdog import Expired, Watchdog, bound, poll, wait_irq

__all__ = ["CLOCK_NS", "load_manifest", "TB", "setup", "holes", "wait_idle", "watchdog_fires"]

CLOCK_NS = 10


def load_manifest() -> dict:
    """The manifest ``KFGEN_TB_MANIFEST`` names. A core records its application's file by name
    alone (:func:`kfgen.hdl.engine.app.recorded_spec`): the core's directory and
    ``KFGEN_APP_DIR`` (where a runner found the application) go on ``sys.path``, where the
    loader looks for it."""
    path = os.environ["KFGEN_TB_MANIFEST"]
    for directory in (os.environ.get("KFGEN_APP_DIR"), os.path.dirname(os.path.abspath(path))):
        if directory and directory not in sys.path:
            sys.path.insert(0, directory)
    with open(path) as f:
        return json.load(f)


class TB:
    """Drives an engine core through AXI4 and keeps its golden memory. A core's testbench
    subclasses it: ``PARAMS`` (its parameter class) and ``PROGRAMS`` (parameters -> its
    programs: ``fmt``, ``layout``, ``steps`` and an optional ``prologue``) make the core's
    parameters and programs from the manifest."""

    PARAMS: type
    PROGRAMS: staticmethod

    def __init__(self, dut):
        self.dut = dut
        self.manifest = load_manifest()
        self.params = self.PARAMS(**self.manifest["parameters"])
        self.programs = self.PROGRAMS(self.params)
        self.fmt, self.layout = self.programs.fmt, self.programs.layout
        self.gold = self.layout.initial_memory()
        self.prologue = Prologue(self.programs)
        self.regs = {r["name"]: r for r in self.manifest["registers"]}
        self.has_step = any(fd["name"] == "step" for fd in self.regs["CTRL"]["fields"])  # the IMM's has none
        self.mems = {mm["name"]: mm for mm in self.manifest["memories"]}
        self.words = self.mems["x"]["words_per_element"]
        self.rng = np.random.default_rng(int(os.environ.get("KFGEN_TB_SEED", "1")))
        self.cycle = 0
        self.w_beats, self.irq_rises = [], []
        cocotb.start_soon(Clock(dut.clk, CLOCK_NS, unit="ns").start())
        self.axi = AxiMaster(AxiBus.from_prefix(dut, "s_axi"), dut.clk, dut.rst)
        logging.getLogger(f"cocotb.{dut._name}.s_axi").setLevel(logging.WARNING)
        # KFGEN_TB_CALM=1 (long runs): no per-clock monitor (no handshake checkers, no cycle
        # measurement) and no random pauses, so that the simulation wakes Python only for the
        # bus's own transfers
        self.calm = bool(int(os.environ.get("KFGEN_TB_CALM", "0")))
        if self.calm:
            return
        self.checkers = [
            StreamChecker("R", dut.s_axi_rvalid, dut.s_axi_rready,
                          {k: getattr(dut, f"s_axi_{k}") for k in ("rid", "rdata", "rresp", "rlast")}),
            StreamChecker("B", dut.s_axi_bvalid, dut.s_axi_bready,
                          {k: getattr(dut, f"s_axi_{k}") for k in ("bid", "bresp")}),
        ]
        for ch in (self.axi.write_if.aw_channel, self.axi.write_if.w_channel, self.axi.read_if.ar_channel,
                   self.axi.write_if.b_channel, self.axi.read_if.r_channel):
            ch.set_pause_generator(self._pauses())

    def _pauses(self):
        rng = np.random.default_rng(self.rng.integers(1 << 32))
        while True:
            yield bool(rng.random() < 0.3)

    async def reset(self):
        self.dut.rst.value = 1
        await ClockCycles(self.dut.clk, 3)
        self.dut.rst.value = 0
        await RisingEdge(self.dut.clk)
        if not self.calm:
            cocotb.start_soon(self._monitor())

    async def _monitor(self):
        """Once a clock, before the rising edge: handshake rules, W beats and irq rises."""
        dut, irq = self.dut, 0
        while True:
            await FallingEdge(dut.clk)
            await ReadOnly()
            self.cycle += 1
            for c in self.checkers:
                c.sample(self.cycle)
            if dut.s_axi_wvalid.value == 1 and dut.s_axi_wready.value == 1:
                self.w_beats.append(self.cycle)
            now = int(dut.irq.value)
            if now and not irq:
                self.irq_rises.append(self.cycle)
            irq = now

    @staticmethod
    def now():
        """The clock cycles simulated so far (also in calm runs, which count none)."""
        return int(get_sim_time("ns")) // CLOCK_NS

    # ------------------------------------------------------------- registers
    def field(self, reg, name):
        return next(f for f in self.regs[reg]["fields"] if f["name"] == name)

    def bits(self, reg, **values):
        word = 0
        for name, v in values.items():
            fd = self.field(reg, name)
            word |= (fd["values"][v] if isinstance(v, str) else int(v)) << fd["lsb"]
        return word

    async def read_reg(self, reg, word=0):
        got = await self.axi.read(self.regs[reg]["offset"] + 4 * word, 4)
        assert got.resp == AxiResp.OKAY, (reg, got.resp)
        return int.from_bytes(got.data, "little")

    async def write_reg(self, reg, value):
        return (await self.axi.write(self.regs[reg]["offset"], value.to_bytes(4, "little"))).resp

    # ------------------------------------------------------------- buffer
    def _bytes(self, words):
        return b"".join(w.to_bytes(4 * self.words, "little") for w in words)

    def _words(self, data):
        step = 4 * self.words
        return [int.from_bytes(data[i:i + step], "little") for i in range(0, len(data), step)]

    async def put(self, name, values, expect=AxiResp.OKAY):
        """Write region ``name`` in one burst (the golden memory too, if it is accepted)."""
        mem, reg = self.mems[name], self.layout[name]
        words = to_words(self.fmt, np.ravel(values))
        assert len(words) == reg.size
        resp = (await self.axi.write(mem["offset"], self._bytes(words))).resp
        assert resp == expect, (name, resp)
        if resp == AxiResp.OKAY:
            self.gold[reg.base:reg.base + reg.size] = words
            self.prologue.wrote(name)
        return words

    async def get_words(self, name, expect=AxiResp.OKAY):
        mem, reg = self.mems[name], self.layout[name]
        got = await self.axi.read(mem["offset"], reg.size * 4 * self.words)
        assert got.resp == expect, (name, got.resp)
        return self._words(got.data)

    async def check(self, name):
        """Read region ``name`` by burst: every word equals the golden model's; its values."""
        reg = self.layout[name]
        got = await self.get_words(name)
        want = self.gold[reg.base:reg.base + reg.size]
        bad = [(i, hex(g), hex(w)) for i, (g, w) in enumerate(zip(got, want)) if g != w]
        assert not bad, (name, bad[:8])
        return np.array(from_words(self.fmt, got)).reshape(reg.rows, reg.cols)

    # ------------------------------------------------------------- steps
    async def start(self, step):
        resp = await self.write_reg("CTRL", self.bits("CTRL", start=1, **({"step": step} if self.has_step else {})))
        return resp

    async def step(self, name):
        """Run ``name`` in hardware (start, wait for irq) and in the golden model; check the
        status, the cycles against the manifest, and clear the status."""
        steps = self.prologue.steps(name)  # (the prologue's program may run first)
        st = self.prologue.run(name, self.gold, steps)
        cycles = sum(self.manifest["cycles"][s] for s in steps)
        beats = len(self.w_beats)
        rises = len(self.irq_rises)
        assert await self.start(name) == AxiResp.OKAY
        dog = Watchdog(name, cycles, self.now())
        if self.calm:  # no cycle count (None): wait for irq, then check the status as below
            await wait_irq(self.dut, dog, self.now)
            measured = None
        else:
            if len(self.irq_rises) == rises:
                await wait_irq(self.dut, dog, self.now)
                await RisingEdge(self.dut.clk)  # the monitor has recorded the rise
            # the beat is sampled before the edge that takes it (edge 1); STATUS.done reads 1
            # after edge `cycles`, irq rises at edge `cycles + 1` and is sampled before the next
            measured = self.irq_rises[rises] - self.w_beats[beats] - 1
            assert measured == cycles, (steps, measured, cycles)
        status = await self.read_reg("STATUS")
        want = self.bits("STATUS", done=1, err_pivot=st.pivot, err_nan=st.nan)
        assert status == want, (name, hex(status), hex(want))
        assert await self.write_reg("STATUS", status) == AxiResp.OKAY  # w1c
        assert await self.read_reg("STATUS") == 0
        return st, measured


async def setup(dut, cls):
    """A testbench of class ``cls`` (a :class:`TB`) on ``dut``, after reset, every interrupt
    enabled."""
    tb = cls(dut)
    await tb.reset()
    enable = tb.bits("IRQ_ENABLE", done=1, err_pivot=1, err_nan=1, err_busy=1)
    assert await tb.write_reg("IRQ_ENABLE", enable) == AxiResp.OKAY
    assert await tb.read_reg("IRQ_ENABLE") == enable
    return tb


async def holes(tb):
    """Between the registers and the buffer, and past the buffer's end: SLVERR, reads 0; a
    write of the read-only ID: SLVERR."""
    axi = tb.axi
    last = max(mm["offset"] + mm["shape"][0] * mm["shape"][1] * 4 * tb.words for mm in tb.mems.values())
    for addr in (0x18, tb.manifest["bus"]["size"] // 2 - 4, last):
        got = await axi.read(addr, 4)
        assert (got.resp, got.data) == (AxiResp.SLVERR, bytes(4)), hex(addr)
        assert (await axi.write(addr, b"\xff" * 4)).resp == AxiResp.SLVERR, hex(addr)
    assert (await axi.write(tb.regs["ID"]["offset"], bytes(4))).resp == AxiResp.SLVERR


async def wait_idle(tb, step):
    """Poll STATUS until ``step`` (running) is no longer busy, within the watchdog's bound."""
    busy = tb.field("STATUS", "busy")["lsb"]

    async def pause():
        pass  # a read takes cycles of its own

    await poll(lambda: tb.read_reg("STATUS"), lambda word: not word >> busy & 1, pause, tb.now, step,
               tb.manifest["cycles"][step])


async def watchdog_fires(tb, step):
    """With the core idle and no start, a wait for ``step``'s irq fails within the bound,
    naming the step: no wait of these testbenches can hang."""
    assert not tb.dut.irq.value
    limit = bound(tb.manifest["cycles"][step])
    try:
        await wait_irq(tb.dut, Watchdog(step, tb.manifest["cycles"][step], tb.now()), tb.now)
    except Expired as exc:
        assert f"step {step} " in str(exc) and f"bound {limit} " in str(exc), str(exc)
        assert limit < exc.waited <= limit + 2, (exc.waited, limit)
    else:
        raise AssertionError(f"the watchdog let a wait for {step} end without irq")
