"""cocotb testbench of a generated linear Kalman filter core (``kfgen kf``), driven as software
would drive it through the engine's harness (:class:`kfgen.sim.engine.tb.TB`: cocotbext-axi's
``AxiMaster``, bursts for the buffer, single beats for the registers, random idle cycles and
backpressure on every channel, AXI handshake checkers).

Every word read back is compared with the bit-exact golden model
(:func:`kfgen.sim.linalg.exec.run` on the same programs), every iteration's cycles with the
manifest's ``cycles`` (with a steady gain, ``gain`` + ``iterate`` after a write to F, B, H or K).

Environment: ``KFGEN_TB_MANIFEST``, the core's ``TOP.json``; ``KFGEN_TB_SEED`` (default 1);
``KFGEN_TB_ITERATIONS`` (default 4).
"""

from __future__ import annotations

import os

import cocotb
import numpy as np
from cocotb.triggers import ClockCycles, FallingEdge, RisingEdge
from cocotbext.axi import AxiResp

from kfgen.hdl.kf.params import KfParams
from kfgen.hdl.kf.steps import programs
from kfgen.sim.engine.campaign import engine_campaign
from kfgen.sim.engine.driver_tb import golden, python_driver as run_python_driver
from kfgen.sim.engine.tb import CLOCK_NS, TB, holes, setup, wait_idle, watchdog_fires
from kfgen.sim.linalg.exec import to_words
from kfgen.sim.streams import StreamChecker

from .reference import steady_gain
from .smoke import system as smoke_system

__all__ = ["TB_MODULE", "KfTB", "system"]

#: This testbench as :func:`kfgen.sim.engine.run.run_tb`'s ``module``.
TB_MODULE = "kfgen.sim.kf.tb"


class KfTB(TB):
    PARAMS = KfParams
    PROGRAMS = staticmethod(programs)


def system(params, rng) -> dict:
    """A test model for any n, m, nu (:func:`kfgen.sim.kf.smoke.system`'s: a chain of
    integrators; with a steady gain K, scipy's DARE). Float64 arrays keyed by region name: the
    regions the buffer holds but z and u."""
    values = smoke_system(params, rng, gain=steady_gain)
    lay = programs(params).layout
    return {name: values[name] for name, reg in lay.regions.items() if name in values and reg.kind == "bus"}


async def load(tb, values):
    for name, v in values.items():
        await tb.put(name, v)


async def iterate(tb, z, u=()):
    """Write z (and u), run one iteration (checked: status, cycles), read x (and P) word for
    word against the golden model; the status, the cycles and the values read by region."""
    await tb.put("z", z)
    if tb.params.nu:
        await tb.put("u", u)
    st, cycles = await tb.step("iterate")
    out = {name: await tb.check(name) for name in ("x", "P") if name in tb.mems}
    return st, cycles, out


class Truth:
    """The simulated system the measurements come from."""

    def __init__(self, tb, values):
        self.tb, self.values = tb, values
        self.x = values["x"] + tb.rng.normal(0, 0.3, tb.params.n)

    def next(self):
        """The next (z, u)."""
        p, v, rng = self.tb.params, self.values, self.tb.rng
        u = rng.normal(size=p.nu)
        self.x = v["F"] @ self.x + (v["B"] @ u if p.nu else 0)  # (no B without inputs)
        return v["H"] @ self.x + rng.normal(0, 0.3, p.m), u


@cocotb.test()
async def iterations(dut):
    """ID, then several iterations with every word checked and the cycles measured; P stays
    exactly symmetric."""
    tb = await setup(dut, KfTB)
    p = tb.params
    ident = await tb.read_reg("ID") | await tb.read_reg("ID", 1) << 32
    for fd in tb.regs["ID"]["fields"]:
        assert ident >> fd["lsb"] & ((1 << fd["width"]) - 1) == fd["reset"], fd["name"]
    assert (ident >> 32 & 0xFF, ident >> 40 & 0xFF, ident >> 48 & 0xFF) == (p.n, p.m, p.nu)
    values = system(p, tb.rng)
    await load(tb, values)
    truth = Truth(tb, values)
    for it in range(int(os.environ.get("KFGEN_TB_ITERATIONS", "4"))):
        st, cycles, out = await iterate(tb, *truth.next())
        assert not (st.pivot or st.nan), st
        if "P" in out:
            assert np.array_equal(out["P"], out["P"].T)  # one triangle, mirrored
        dut._log.info("iteration %d: %d cycles, x %s", it, cycles, np.round(out["x"].ravel(), 3))
    if p.steady_gain:  # a new gain: the prologue runs again before the next iteration
        await tb.put("K", values["K"] * 0.5)
        st, cycles, _ = await iterate(tb, *truth.next())
        assert cycles == tb.manifest["cycles"]["gain"] + tb.manifest["cycles"]["iterate"]


async def clean_iteration(tb):
    """Freshly loaded model and one iteration, every word against the golden model (what a
    fault campaign's sequence must leave the core able to do)."""
    values = system(tb.params, tb.rng)
    await load(tb, values)
    st, _, _ = await iterate(tb, *Truth(tb, values).next())
    assert not (st.pivot or st.nan), st


@cocotb.test()
async def fault_campaign(dut):
    """Seeded random sequences of bus traffic, starts, soft and bus resets, each followed by a
    clean iteration (:mod:`kfgen.sim.engine.campaign`)."""
    tb = await setup(dut, KfTB)
    counts = await engine_campaign(tb, clean_iteration, CLOCK_NS)
    dut._log.info("fault campaign: %s", counts)


@cocotb.test()
async def errors(dut):
    """Holes, the read-only ID, strobes, writes and start while busy, reads while busy, soft
    reset mid-iteration, an innovation covariance S that is not positive definite
    (err_pivot); a wait with no start ends at the watchdog's bound."""
    tb = await setup(dut, KfTB)
    p = tb.params
    axi = tb.axi
    await holes(tb)
    assert (await axi.write(tb.mems["z"]["offset"] + 1, b"\x12")).resp == AxiResp.SLVERR
    values = system(p, tb.rng)
    await load(tb, values)
    z, u = Truth(tb, values).next()
    await tb.put("z", z)
    if p.nu:
        await tb.put("u", u)
    # while busy: a buffer write answers SLVERR and changes nothing; start is refused with
    # err_busy; reads wait for a free port and answer OKAY (an iteration never writes F, H, z)
    ran = tb.prologue.steps("iterate")
    assert await tb.start("iterate") == AxiResp.OKAY
    assert await tb.read_reg("STATUS") & 1, "busy"
    await tb.put("z", np.ones(p.m), expect=AxiResp.SLVERR)
    assert await tb.start("iterate") == AxiResp.SLVERR
    assert dut.irq.value == 1  # err_busy
    for name in ("F", "H", "z"):
        await tb.check(name)
    tb.prologue.run("iterate", tb.gold, ran)
    await wait_idle(tb, "iterate")
    status = await tb.read_reg("STATUS")
    assert status == tb.bits("STATUS", done=1, err_busy=1), hex(status)
    for name in ("x", "P"):
        if name in tb.mems:
            await tb.check(name)
    await tb.write_reg("STATUS", status)
    # soft reset mid-iteration: idle at once, STATUS clear, no done, no irq
    cycles = tb.manifest["cycles"]["iterate"]
    assert await tb.start("iterate") == AxiResp.OKAY
    await ClockCycles(dut.clk, cycles // 2)
    assert await tb.write_reg("CTRL", tb.bits("CTRL", reset=1)) == AxiResp.OKAY
    assert await tb.read_reg("STATUS") == 0
    await ClockCycles(dut.clk, cycles)
    assert await tb.read_reg("STATUS") == 0 and dut.irq.value == 0
    # the buffer now holds some state of the stopped iteration (the soft reset makes a
    # prologue run again): load it again, and run
    tb.prologue.stale = True
    await load(tb, values)
    await iterate(tb, z, u)
    if not p.steady_gain:  # a measurement noise that is not positive definite makes S indefinite
        await load(tb, values)
        await tb.put("R", -np.eye(p.m) * 50.0)
        st, _, _ = await iterate(tb, z, u)
        assert st.pivot
        assert not await tb.read_reg("STATUS") & 1
    await watchdog_fires(tb, "iterate")


@cocotb.test()
async def stream_iterations(dut):
    """A core with stream ports (``--streams``), fed as a design without a processor would:
    the model through the bus once, then (z, u) on ``s_axis`` (cocotbext-axi's
    AxiStreamSource) and the estimates from ``m_axis`` (AxiStreamSink, with backpressure):
    every field word for word against the golden model, ``tuser`` against its status, the
    latency from the transfer to the result against the manifest."""
    from cocotbext.axi import AxiStreamBus, AxiStreamFrame, AxiStreamSink, AxiStreamSource

    tb = await setup(dut, KfTB)
    p, lay = tb.params, tb.layout
    spec = tb.manifest["streams"]
    values = system(p, tb.rng)
    await load(tb, values)
    truth = Truth(tb, values)
    source = AxiStreamSource(AxiStreamBus.from_prefix(dut, "s_axis"), dut.clk, dut.rst)
    sink = AxiStreamSink(AxiStreamBus.from_prefix(dut, "m_axis"), dut.clk, dut.rst)
    sink.set_pause_generator(iter(([1] * 5 + [0] * 2) * 1000))  # backpressure
    checks = [StreamChecker.axis(dut, "s_axis"), StreamChecker.axis(dut, "m_axis")]
    tb.checkers += checks
    steps = int(os.environ.get("KFGEN_TB_ITERATIONS", "3"))
    for it in range(steps):
        z, u = truth.next()
        words = to_words(tb.fmt, np.r_[z, u])
        base = lay["z"].base
        tb.gold[base:base + len(words)] = words  # z then u: one run of the buffer
        ran = tb.prologue.steps("iterate")
        st = tb.prologue.run("iterate", tb.gold, ran)
        data = 0
        for f, w in zip(spec["s_axis"]["fields"], words):
            data |= w << f["lsb"]
        await source.send(AxiStreamFrame(data.to_bytes(spec["s_axis"]["tdata_width"] // 8, "little")))
        await FallingEdge(dut.s_axis_tready)
        taken = tb.now()
        await RisingEdge(dut.m_axis_tvalid)
        latency = tb.now() - taken + 1
        frame = await sink.recv()
        value = int.from_bytes(bytes(frame.tdata), "little")
        got = [value >> f["lsb"] & ((1 << f["width"]) - 1) for f in spec["m_axis"]["fields"]]
        x = lay["x"]
        want = [tb.gold[x(i)] for i in range(p.n)]
        if not p.steady_gain:
            want += [tb.gold[lay["P"](i, i)] for i in range(p.n)]
        assert got == want, (it, [hex(g) for g in got], [hex(w) for w in want])
        user = frame.tuser if isinstance(frame.tuser, int) else frame.tuser[0]
        assert user == (st.pivot | st.nan << 1), (it, user, st)
        extra = sum(tb.manifest["cycles"][s] for s in ran if s != "iterate")
        assert latency == spec["latency_cycles"] + extra, (latency, spec["latency_cycles"], extra)
        dut._log.info("measurement %d: estimate after %d cycles", it, latency)
        status = await tb.read_reg("STATUS")
        assert status & tb.bits("STATUS", done=1) and not status & 1, hex(status)
        await tb.write_reg("STATUS", status)
    for name in ("x", "P", "z", "u"):
        if name in tb.mems:
            await tb.check(name)
    assert [c.transfers for c in checks] == [steps, steps], [c.transfers for c in checks]
    assert checks[1].waits > 0  # the sink's backpressure held the estimate at least once


def driver_session(core, tb, module, iterations=4):
    """The generated driver's session (:func:`kfgen.sim.engine.driver_tb.python_driver`, in its
    thread): load, ``iterations`` iterations (half waiting on irq, half polling STATUS), each
    estimate equal to the golden model's; with a covariance, R not positive definite raises
    ``CoreFault`` (err_pivot)."""
    p = tb.params
    values = system(p, tb.rng)
    core.load(**{arg: values[name] for arg, name, _ in module.LOAD})
    truth = Truth(tb, values)
    for it in range(iterations):
        if it == iterations // 2:
            core.wait_event = None  # poll STATUS from now on
        z, u = truth.next()
        x, P = core.step(z, u if p.nu else None)
        assert np.array_equal(x, golden(tb, "x").ravel()), (it, x)
        if p.steady_gain:
            assert P is None
        else:
            assert np.array_equal(P, golden(tb, "P")), (it, P)
    if not p.steady_gain:
        core.write_region("R", -np.eye(p.m) * 50.0)
        try:
            core.step(*truth.next())
        except module.CoreFault as exc:
            assert exc.bits == ["err_pivot"], exc.bits
        else:
            raise AssertionError("R = -50 I: no CoreFault")
    return iterations


@cocotb.test()
async def python_driver(dut):
    """The generated Python driver ``TOP_driver.py`` runs the filter through AXI4
    (:mod:`kfgen.sim.engine.driver_tb`): every word it reads equals the golden model's, its
    estimates too, err_pivot raises its CoreFault."""
    done = await run_python_driver(dut, KfTB, driver_session)
    dut._log.info("python driver: %d iterations", done)


def c_driver_session(driver, tb, iterations=4):
    """The generated C driver's session (:func:`kfgen.sim.engine.cdriver.c_driver`, in its
    thread): ``TOP_load``, ``iterations`` of ``TOP_iterate`` (half waiting on irq, half polling
    STATUS), each estimate equal to the golden model's; with a steady gain ``TOP_set_gain``
    (the gain step, then iterations without it); with a covariance, R not positive definite
    returns err_pivot."""
    p = tb.params
    v = system(p, tb.rng)
    B = v["B"] if p.nu else None
    if p.steady_gain:
        driver("load", v["x"], v["F"], B, v["H"], v["K"])
    else:
        driver("load", v["x"], v["P"], v["F"], B, v["Q"], v["H"], v["R"])
    truth = Truth(tb, v)
    x, P = np.zeros(p.n), np.zeros(p.n * p.n)
    for it in range(iterations):
        if it == iterations // 2:
            driver.wait = False  # poll STATUS from now on
        if p.steady_gain and it == iterations - 1:
            assert driver("set_gain", v["K"] * 0.5) == 0
            assert not tb.prologue.stale  # set_gain started the gain step: the iteration runs alone
        z, u = truth.next()
        assert driver("iterate", u if p.nu else None, z) == 0, it
        if p.steady_gain:
            driver("estimate", x)
        else:
            driver("estimate", x, P)
            assert np.array_equal(P.reshape(p.n, p.n), golden(tb, "P")), (it, P)
        assert np.array_equal(x, golden(tb, "x").ravel()), (it, x)
    if not p.steady_gain:
        R = tb.mems["R"]
        driver("write", R["offset"], -np.eye(p.m) * 50.0, p.m * p.m)
        err = driver("iterate", u if p.nu else None, z)
        assert err == tb.bits("STATUS", err_pivot=1), err
    return iterations


@cocotb.test()
async def c_driver(dut):
    """The generated C driver ``TOP_driver.c`` (compiled with its MMIO hooks) runs the filter
    through AXI4 (:mod:`kfgen.sim.engine.cdriver`): every word it reads equals the golden
    model's, its estimates too, err_pivot is its return."""
    from kfgen.sim.engine.cdriver import c_driver as run_c_driver

    done = await run_c_driver(dut, KfTB, c_driver_session)
    dut._log.info("C driver: %d iterations", done)
