"""cocotb testbench of a generated EKF core (``kfgen ekf --app ...``), driven as software would
drive it through the engine's harness (:class:`kfgen.sim.engine.tb.TB`: cocotbext-axi's
``AxiMaster``, bursts for the buffer, single beats for the registers, random idle cycles and
backpressure on every channel, AXI handshake checkers).

Every word read back is compared with the bit-exact golden model
(:func:`kfgen.sim.linalg.exec.run` on the core's own program), every iteration's cycles with
the manifest's ``cycles``. The measurements are the application's own scenario.

Environment: ``KFGEN_TB_MANIFEST``, the core's ``TOP.json``; ``KFGEN_TB_SEED`` (default 1);
``KFGEN_TB_ITERATIONS`` (default 4); ``KFGEN_APP_DIR`` (put on ``sys.path``: where the
file name a core records for its application, ``file.py:Class``, is found); ``KFGEN_EKF_OUT``: ``iterations`` saves the estimates
read back there (``.npz``: ``x`` K x n, ``P`` K x n x n, ``flags`` K of err_pivot | 2 err_nan,
``cycles``), and a fault (err_pivot, err_nan) is then recorded, not failed.
"""

from __future__ import annotations

import os
import sys

import cocotb
import numpy as np
from cocotb.triggers import ClockCycles, FallingEdge, RisingEdge
from cocotbext.axi import AxiResp

from kfgen.hdl.ekf.params import EkfParams
from kfgen.hdl.ekf.steps import programs
from kfgen.hdl.engine.app import load_app
from kfgen.sim.engine.campaign import engine_campaign
from kfgen.sim.engine.driver_tb import golden, python_driver as run_python_driver
from kfgen.sim.ekf.reference import measurements
from kfgen.sim.engine.tb import CLOCK_NS, TB, holes, setup, wait_idle, watchdog_fires
from kfgen.sim.linalg.exec import run, to_words
from kfgen.sim.streams import StreamChecker

__all__ = ["EkfTB"]

STEP = "iterate"


class EkfTB(TB):
    PARAMS = EkfParams
    PROGRAMS = staticmethod(programs)

    def __init__(self, dut):
        if os.environ.get("KFGEN_APP_DIR"):  # the parameters load the application by its recorded name
            sys.path.insert(0, os.environ["KFGEN_APP_DIR"])
        super().__init__(dut)


async def load(tb, app):
    """The application's x0, P0, Q and R into the buffer."""
    for name, value in (("x", app.x0), ("P", app.P0), ("Q", app.Q), ("R", app.R)):
        await tb.put(name, value)


async def iterate(tb, u, z):
    """Write u and z, run one iteration (checked: status, cycles), read x and P back word for
    word against the golden model: the status, the cycles and x, P."""
    if tb.params.nu:
        await tb.put("u", u)
    await tb.put("z", z)
    st, cycles = await tb.step(STEP)
    return st, cycles, await tb.check("x"), await tb.check("P")


@cocotb.test()
async def iterations(dut):
    """ID, then the application's scenario, one start an iteration, every word checked and
    the cycles measured."""
    tb = await setup(dut, EkfTB)
    p = tb.params
    ident = await tb.read_reg("ID") | await tb.read_reg("ID", 1) << 32
    for fd in tb.regs["ID"]["fields"]:
        assert ident >> fd["lsb"] & ((1 << fd["width"]) - 1) == fd["reset"], fd["name"]
    assert [ident >> s & 0xFF for s in (32, 40, 48, 56)] == [p.n, p.nw, p.nv, p.m]
    app = load_app(p.app)
    await load(tb, app)
    steps = int(os.environ.get("KFGEN_TB_ITERATIONS", "4"))
    us, zs = measurements(app, steps, int(os.environ.get("KFGEN_TB_SEED", "1")))
    out = os.environ.get("KFGEN_EKF_OUT")
    xs, Ps, flags, cycles = [], [], [], []
    for it, (u, z) in enumerate(zip(us, zs)):
        st, measured, x, P = await iterate(tb, u, z)
        assert out or not (st.pivot or st.nan), (it, st)
        assert np.array_equal(P, P.T, equal_nan=True)  # one triangle, mirrored
        xs.append(x.ravel())
        Ps.append(P)
        flags.append(int(st.pivot) | 2 * int(st.nan))
        if measured is not None:  # (a calm run measures none)
            cycles.append(measured)
        dut._log.info("iteration %d: %s cycles", it, measured)
    if out:
        np.savez(out, x=np.array(xs), P=np.array(Ps), flags=np.array(flags), cycles=np.array(cycles))


async def clean_iteration(tb):
    """Freshly loaded x0, P0, Q, R and one iteration, every word against the golden model (what
    a fault campaign's sequence must leave the core able to do)."""
    app = load_app(tb.params.app)
    await load(tb, app)
    us, zs = measurements(app, 1, int(tb.rng.integers(1 << 16)))
    st, _, _, _ = await iterate(tb, us[0], zs[0])
    assert not (st.pivot or st.nan), st


@cocotb.test()
async def fault_campaign(dut):
    """Seeded random sequences of bus traffic, starts, soft and bus resets, each followed by a
    clean iteration (:mod:`kfgen.sim.engine.campaign`)."""
    tb = await setup(dut, EkfTB)
    counts = await engine_campaign(tb, clean_iteration, CLOCK_NS)
    dut._log.info("fault campaign: %s", counts)


@cocotb.test()
async def errors(dut):
    """Holes, strobes, writes and start while busy, reads while busy, soft reset mid-iteration,
    an innovation covariance that is not positive definite (err_pivot); a wait with no start
    ends at the watchdog's bound."""
    tb = await setup(dut, EkfTB)
    p = tb.params
    axi = tb.axi
    await holes(tb)
    assert (await axi.write(tb.mems["z"]["offset"] + 1, b"\x12")).resp == AxiResp.SLVERR
    app = load_app(p.app)
    await load(tb, app)
    us, zs = measurements(app, 2, 5)
    if p.nu:
        await tb.put("u", us[0])
    await tb.put("z", zs[0])
    # while busy: a buffer write answers SLVERR and changes nothing; start is refused with
    # err_busy; reads wait for a free port and answer OKAY (the iteration never writes Q, R, z)
    assert await tb.start(STEP) == AxiResp.OKAY
    assert await tb.read_reg("STATUS") & 1, "busy"
    await tb.put("z", zs[1], expect=AxiResp.SLVERR)
    assert await tb.start(STEP) == AxiResp.SLVERR
    assert dut.irq.value == 1  # err_busy
    for name in ("Q", "R", "z"):
        await tb.check(name)
    run(tb.programs.steps[STEP], tb.gold)
    await wait_idle(tb, STEP)
    status = await tb.read_reg("STATUS")
    assert status == tb.bits("STATUS", done=1, err_busy=1), hex(status)
    for name in ("x", "P"):
        await tb.check(name)
    await tb.write_reg("STATUS", status)
    # soft reset mid-iteration: idle at once, STATUS clear, no done, no irq
    assert await tb.start(STEP) == AxiResp.OKAY
    await ClockCycles(dut.clk, tb.manifest["cycles"][STEP] // 2)
    assert await tb.write_reg("CTRL", tb.bits("CTRL", reset=1)) == AxiResp.OKAY
    assert await tb.read_reg("STATUS") == 0
    await ClockCycles(dut.clk, tb.manifest["cycles"][STEP])
    assert await tb.read_reg("STATUS") == 0 and dut.irq.value == 0
    # the buffer holds some state of the stopped iteration: load it again, and run
    await load(tb, app)
    st, _, _, _ = await iterate(tb, us[1], zs[1])
    assert not (st.pivot or st.nan), st
    # a measurement noise far from positive definite makes S indefinite: err_pivot (the
    # iteration runs to its end, x and P read back as the golden model computed them)
    await load(tb, app)
    await tb.put("R", -1e9 * np.eye(p.nv))
    st, _, _, _ = await iterate(tb, us[1], zs[1])
    assert st.pivot
    assert not await tb.read_reg("STATUS") & 1
    await watchdog_fires(tb, STEP)


@cocotb.test()
async def stream_iterations(dut):
    """A core with stream ports (``--streams``), fed as a design without a processor would:
    the application's measurements on ``s_axis`` (cocotbext-axi's AxiStreamSource), the
    estimates taken from ``m_axis`` (AxiStreamSink, with backpressure); every field word for
    word against the golden model, ``tuser`` against its status, the latency from the
    transfer to the result against the manifest."""
    from cocotbext.axi import AxiStreamBus, AxiStreamFrame, AxiStreamSink, AxiStreamSource

    tb = await setup(dut, EkfTB)
    p, fmt, lay = tb.params, tb.fmt, tb.layout
    spec = tb.manifest["streams"]
    app = load_app(p.app)
    await load(tb, app)
    source = AxiStreamSource(AxiStreamBus.from_prefix(dut, "s_axis"), dut.clk, dut.rst)
    sink = AxiStreamSink(AxiStreamBus.from_prefix(dut, "m_axis"), dut.clk, dut.rst)
    sink.set_pause_generator(iter(([1] * 5 + [0] * 2) * 1000))  # backpressure
    checks = [StreamChecker.axis(dut, "s_axis"), StreamChecker.axis(dut, "m_axis")]
    tb.checkers += checks
    steps = int(os.environ.get("KFGEN_TB_ITERATIONS", "3"))
    us, zs = measurements(app, steps, int(os.environ.get("KFGEN_TB_SEED", "1")))
    z_reg, x, P = lay["z"], lay["x"], lay["P"]

    def pack(words):
        value = 0
        for f, w in zip(spec["s_axis"]["fields"], words):
            value |= w << f["lsb"]
        return value.to_bytes(spec["s_axis"]["tdata_width"] // 8, "little")

    for it, (u, z) in enumerate(zip(us, zs)):
        words = to_words(fmt, np.r_[z, u])
        tb.gold[z_reg.base:z_reg.base + len(words)] = words  # z then u: one run of the buffer
        st = run(tb.programs.steps[STEP], tb.gold)
        await source.send(AxiStreamFrame(pack(words)))
        await FallingEdge(dut.s_axis_tready)
        taken = tb.now()
        await RisingEdge(dut.m_axis_tvalid)
        latency = tb.now() - taken + 1
        frame = await sink.recv()
        value = int.from_bytes(bytes(frame.tdata), "little")
        got = [value >> f["lsb"] & ((1 << f["width"]) - 1) for f in spec["m_axis"]["fields"]]
        want = [tb.gold[x(i)] for i in range(p.n)] + [tb.gold[P(i, i)] for i in range(p.n)]
        assert got == want, (it, [hex(g) for g in got], [hex(w) for w in want])
        user = frame.tuser if isinstance(frame.tuser, int) else frame.tuser[0]
        assert user == (st.pivot | st.nan << 1), (it, user, st)
        assert latency == spec["latency_cycles"], (latency, spec["latency_cycles"])
        dut._log.info("measurement %d: estimate after %d cycles", it, latency)
        status = await tb.read_reg("STATUS")
        assert status & tb.bits("STATUS", done=1) and not status & 1, hex(status)
        await tb.write_reg("STATUS", status)
    for name in ("x", "P", "z"):
        await tb.check(name)
    assert [c.transfers for c in checks] == [steps, steps], [c.transfers for c in checks]
    assert checks[1].waits > 0  # the sink's backpressure held the estimate at least once


def driver_session(core, tb, module, iterations=4):
    """The generated driver's session (:func:`kfgen.sim.engine.driver_tb.python_driver`, in its
    thread): the application's x0, P0, Q, R, then ``iterations`` of its scenario (half waiting
    on irq, half polling STATUS), each estimate equal to the golden model's."""
    app = load_app(tb.params.app)
    core.load(app.x0, app.P0, app.Q, app.R)
    us, zs = measurements(app, iterations, int(tb.rng.integers(1 << 16)))
    for it, (u, z) in enumerate(zip(us, zs)):
        if it == iterations // 2:
            core.wait_event = None  # poll STATUS from now on
        x, P = core.step(z, u if tb.params.nu else None)
        assert np.array_equal(x, golden(tb, "x").ravel()) and np.array_equal(P, golden(tb, "P")), it
    return iterations


@cocotb.test()
async def python_driver(dut):
    """The generated Python driver ``TOP_driver.py`` runs the EKF through AXI4
    (:mod:`kfgen.sim.engine.driver_tb`): every word it reads equals the golden model's, its
    estimates too."""
    done = await run_python_driver(dut, EkfTB, driver_session)
    dut._log.info("python driver: %d iterations", done)


def c_driver_session(driver, tb, iterations=4):
    """The generated C driver's session (:func:`kfgen.sim.engine.cdriver.c_driver`, in its
    thread): ``TOP_load`` of the application's x0, P0, Q, R, then ``iterations`` of its
    scenario by ``TOP_iterate`` (half waiting on irq, half polling STATUS), each estimate equal
    to the golden model's; R far from positive definite returns err_pivot."""
    p = tb.params
    app = load_app(p.app)
    driver("load", app.x0, app.P0, app.Q, app.R)
    us, zs = measurements(app, iterations, int(tb.rng.integers(1 << 16)))
    x, P = np.zeros(p.n), np.zeros(p.n * p.n)
    for it, (u, z) in enumerate(zip(us, zs)):
        if it == iterations // 2:
            driver.wait = False  # poll STATUS from now on
        assert driver("iterate", u if p.nu else None, z) == 0, it
        driver("estimate", x, P)
        assert np.array_equal(x, golden(tb, "x").ravel()) and np.array_equal(P.reshape(p.n, p.n), golden(tb, "P")), it
    driver("write", tb.mems["R"]["offset"], -1e9 * np.eye(p.nv), p.nv * p.nv)
    err = driver("iterate", us[0] if p.nu else None, zs[0])
    assert err & tb.bits("STATUS", err_pivot=1), err
    return iterations


@cocotb.test()
async def c_driver(dut):
    """The generated C driver ``TOP_driver.c`` (compiled with its MMIO hooks) runs the EKF
    through AXI4 (:mod:`kfgen.sim.engine.cdriver`): every word it reads equals the golden
    model's, its estimates too, err_pivot is its return."""
    from kfgen.sim.engine.cdriver import c_driver as run_c_driver

    done = await run_c_driver(dut, EkfTB, c_driver_session)
    dut._log.info("C driver: %d iterations", done)
