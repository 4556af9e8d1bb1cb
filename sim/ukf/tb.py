"""cocotb testbench of a generated UKF core, driven as software would drive it through the
engine's harness (:class:`kfgen.sim.engine.tb.TB`: cocotbext-axi's ``AxiMaster``, bursts for
the buffer's matrices, single beats for the registers, random idle cycles and backpressure on
every channel).

Every word read back is compared with the bit-exact golden model
(:func:`kfgen.sim.linalg.exec.run` on the same step programs), every step's cycles with the
manifest's ``cycles``; the estimates after the iterations are held against the float64
reference (:class:`kfgen.sim.ukf.reference.AugmentedUKF`).

Environment: ``KFGEN_TB_MANIFEST``, the core's ``TOP.json``; ``KFGEN_TB_SEED`` (default 1);
``KFGEN_TB_ITERATIONS`` (default 5).
"""

from __future__ import annotations

import os

import cocotb
import numpy as np
from cocotb.triggers import ClockCycles, FallingEdge, RisingEdge
from cocotbext.axi import AxiResp, AxiStreamBus, AxiStreamFrame, AxiStreamSink, AxiStreamSource

from kfgen.hdl.ukf.params import UkfParams, covariance_region
from kfgen.hdl.ukf.steps import programs
from kfgen.sim.engine.campaign import engine_campaign
from kfgen.sim.engine.driver_tb import golden, python_driver as run_python_driver
from kfgen.sim.engine.tb import CLOCK_NS, TB, holes, setup, wait_idle, watchdog_fires
from kfgen.sim.linalg.exec import from_words, to_words
from kfgen.sim.streams import StreamChecker
from kfgen.sim.ukf.app import checked_scenario, load_app
from kfgen.sim.ukf.reference import AugmentedUKF, SquareRootUKF
from kfgen.sim.ukf.software import initial_words

X0 = [0.5, -1.25]
P0 = [[0.4, 0.1], [0.1, 0.3]]


# ------------------------------------------------------------------ the application's models

def f(x, w, u=None, dt=None):
    """A nonlinear motion model on the state x and its process noise w (software's f)."""
    x = np.asarray(x, dtype=np.float64)
    out = np.array(x)
    out[0] = x[0] + 0.1 * x[-1] + 0.01 * np.sin(x[0])
    out[-1] = 0.95 * x[-1]
    out[: len(w)] += w
    return out


def h(x, v):
    """A range-like observation of the moved state with its measurement noise (software's h)."""
    x = np.asarray(x, dtype=np.float64)
    m = len(v)
    return np.array([np.sqrt(x[i % len(x)] ** 2 + 1.0 + i) for i in range(m)]) + v


class UkfTB(TB):
    PARAMS = UkfParams
    PROGRAMS = staticmethod(programs)


def noise(tb):
    p = tb.params
    Q = np.diag(np.linspace(0.02, 0.03, p.nw))
    R = np.diag(np.linspace(0.05, 0.06, p.nv))
    return Q, R


async def check_cov(tb):
    """The covariance's region word for word; P (float64) from it."""
    got = await tb.check(covariance_region(tb.params.form))
    return np.tril(got) @ np.tril(got).T if tb.params.form == "sqrt" else got


async def load(tb, x, P):
    Q, R = noise(tb)
    await tb.put("x", x)
    await tb.put(covariance_region(tb.params.form), np.linalg.cholesky(P) if tb.params.form == "sqrt" else P)
    await tb.put("Q", Q)
    await tb.put("R", R)


def start_values(tb):
    """x0 and P0 of the testbench's runs, for any n."""
    n = tb.params.n
    P0m = np.eye(n) * 0.3
    P0m[:2, :2] = np.array(P0)[:n, :n] if n >= 2 else P0m[:2, :2]
    return np.resize(X0, n), P0m


async def iteration(tb, truth):
    """One three-step iteration (sig_gen, f in software, predict, h, update) with every word
    checked against the golden model; (truth, z, x, P, cycles) after it."""
    p = tb.params
    n, m, nw, nv = p.n, p.m, p.nw, p.nv
    cycles = {}
    st, cycles["sig_gen"] = await tb.step("sig_gen")
    assert not st.pivot
    chi = await tb.check("sigma_points")  # N points x M
    pts_f = np.array([f(c[:n], c[n:n + nw]) for c in chi])
    words_f = await tb.put("sigma_points_f", pts_f)
    _, cycles["predict"] = await tb.step("predict")
    await tb.check("x")
    await check_cov(tb)
    moved = np.array(from_words(tb.fmt, words_f)).reshape(p.N, n)
    await tb.put("sigma_points_h", np.array([h(xf, c[n + nw:]) for xf, c in zip(moved, chi)]))
    truth = f(truth, np.zeros(nw))
    z = h(truth, np.zeros(nv)) + tb.rng.normal(0, 0.1, m)
    await tb.put("z", z)
    _, cycles["update"] = await tb.step("update")
    x = await tb.check("x")
    P = await check_cov(tb)
    return truth, z, x, P, cycles


async def clean_iteration(tb):
    """Freshly loaded x, P, Q, R and one whole iteration, every word against the golden model
    (what a fault campaign's sequence must leave the core able to do)."""
    x0, P0m = start_values(tb)
    await load(tb, x0, P0m)
    await iteration(tb, np.array(x0))


@cocotb.test()
async def fault_campaign(dut):
    """Seeded random sequences of bus traffic, starts, soft and bus resets, each followed by a
    clean iteration (:mod:`kfgen.sim.engine.campaign`)."""
    tb = await setup(dut, UkfTB)
    counts = await engine_campaign(tb, clean_iteration, CLOCK_NS)
    dut._log.info("fault campaign: %s", counts)


@cocotb.test()
async def iterations(dut):
    """ID, then several UKF iterations (sig_gen, f, predict, h, update) with every word
    checked, the cycles measured, and the result against the float64 reference."""
    tb = await setup(dut, UkfTB)
    p = tb.params
    n, m = p.n, p.m
    ident = await tb.read_reg("ID") | await tb.read_reg("ID", 1) << 32
    for fd in tb.regs["ID"]["fields"]:
        assert ident >> fd["lsb"] & ((1 << fd["width"]) - 1) == fd["reset"], fd["name"]
    assert (ident >> 32 & 0xFF, ident >> 56 & 0xFF, ident >> 22 & 0x3FF) == (n, m, p.pes)
    x0, P0m = start_values(tb)
    Q, R = noise(tb)
    await load(tb, x0, P0m)
    ref = AugmentedUKF_ref(p, x0, P0m, Q, R)
    truth = np.array(x0)
    for it in range(int(os.environ.get("KFGEN_TB_ITERATIONS", "5"))):
        truth, z, x, P, cycles = await iteration(tb, truth)
        ref.predict()
        ref.update(z)
        dut._log.info("iteration %d: cycles %s, x %s", it, cycles, x.ravel())
    # the bit-exact model's estimate (binary32 or whatever format) against the float64 one
    scale = max(1.0, float(np.max(np.abs(ref.x))))
    tol = {"binary64": 1e-12, "binary32": 1e-4}.get(p.format.name, 5e-2)
    assert np.max(np.abs(x.ravel() - ref.x)) <= tol * scale, (x.ravel(), ref.x)
    assert np.max(np.abs(P - ref.P)) <= tol * max(1.0, float(np.max(np.abs(ref.P)))), (P, ref.P)
    assert cycles == {k: tb.manifest["cycles"][k] for k in cycles}  # (the last sig_gen without noise)


@cocotb.test()
async def on_chip_iterations(dut):
    """A core with f and h on chip (``kfgen ukf --app ... --on-chip``): the application's
    scenario, one start of ``iteration`` per measurement (software writes u and z only),
    every region checked word for word, each iteration's cycles against the manifest; a start
    of a reserved step does nothing."""
    tb = await setup(dut, UkfTB)
    p = tb.params
    app = load_app(p.app)
    for name, words in initial_words(app, tb.fmt, p.form).items():
        await tb.put(name, from_words(tb.fmt, words))
    # CTRL.step 0..2 and 5..7 are reserved on this core: start does nothing (no done, no error)
    for reserved in (0, 1, 2, 5, 6, 7):
        f_step = next(fd for fd in tb.regs["CTRL"]["fields"] if fd["name"] == "step")
        word = tb.bits("CTRL", start=1) | reserved << f_step["lsb"]
        assert await tb.write_reg("CTRL", word) == AxiResp.OKAY
        await ClockCycles(dut.clk, 4)
        assert await tb.read_reg("STATUS") == 0 and dut.irq.value == 0
    steps = int(os.environ.get("KFGEN_TB_ITERATIONS", "5"))
    sc = checked_scenario(app, steps, int(os.environ.get("KFGEN_TB_SEED", "1")))
    Q = from_words(tb.fmt, initial_words(app, tb.fmt)["Q"])
    for it, (u, z) in enumerate(sc.inputs()):
        if p.nu:
            await tb.put("u", u)
        await tb.put("z", z)
        if it == 1:  # Q written again: this iteration runs noise first (the first did, after the load)
            await tb.put("Q", Q)
        elif it == 2:  # noise started ahead: the iteration runs alone
            await tb.put("R", from_words(tb.fmt, initial_words(app, tb.fmt)["R"]))
            await tb.step("noise")
        st, measured = await tb.step("iteration")
        assert not (st.pivot or st.nan), (it, st)
        for name in ("x", covariance_region(tb.params.form), "sigma_points", "sigma_points_f", "sigma_points_h"):
            await tb.check(name)
        dut._log.info("iteration %d: %s cycles", it, measured)


@cocotb.test()
async def stream_iterations(dut):
    """A core with stream ports (``--on-chip --streams``), fed as a design without a
    processor would: the application's measurements on ``s_axis`` (cocotbext-axi's
    AxiStreamSource), the estimates taken from ``m_axis`` (AxiStreamSink, with backpressure);
    every field word for word against the golden model, ``tuser`` against its status, the
    latency from the transfer to the result against the manifest."""
    tb = await setup(dut, UkfTB)
    p, fmt = tb.params, tb.fmt
    spec = tb.manifest["streams"]
    app = load_app(p.app)
    for name, words in initial_words(app, fmt, p.form).items():
        await tb.put(name, from_words(fmt, words))
    source = AxiStreamSource(AxiStreamBus.from_prefix(dut, "s_axis"), dut.clk, dut.rst)
    sink = AxiStreamSink(AxiStreamBus.from_prefix(dut, "m_axis"), dut.clk, dut.rst)
    sink.set_pause_generator(iter(([1] * 5 + [0] * 2) * 1000))  # backpressure
    checks = [StreamChecker.axis(dut, "s_axis"), StreamChecker.axis(dut, "m_axis")]
    tb.checkers += checks  # the core's m_axis transmitter, and the source's s_axis, once a clock
    lay = tb.layout
    steps = int(os.environ.get("KFGEN_TB_ITERATIONS", "3"))
    sc = checked_scenario(app, steps, int(os.environ.get("KFGEN_TB_SEED", "1")))

    def pack(fields, words):
        value = 0
        for f, w in zip(fields, words):
            value |= w << f["lsb"]
        return value.to_bytes(spec["s_axis"]["tdata_width"] // 8, "little")

    for it, (u, z) in enumerate(sc.inputs()):
        words = to_words(fmt, np.r_[z, u])
        z_reg = lay["z"]
        tb.gold[z_reg.base:z_reg.base + len(words)] = words  # z then u: one run of the buffer
        ran = tb.prologue.steps("iteration")  # noise first after the loads of Q and R
        st = tb.prologue.run("iteration", tb.gold, ran)
        await source.send(AxiStreamFrame(pack(spec["s_axis"]["fields"], words)))
        await FallingEdge(dut.s_axis_tready)
        taken = tb.now()
        await RisingEdge(dut.m_axis_tvalid)
        latency = tb.now() - taken + 1
        frame = await sink.recv()
        value = int.from_bytes(bytes(frame.tdata), "little")
        got = [value >> f["lsb"] & ((1 << f["width"]) - 1) for f in spec["m_axis"]["fields"]]
        x = lay["x"]
        if p.form == "sqrt":  # the variances P_ii, which the sqrt form computes into P_diag
            want = [tb.gold[x(i)] for i in range(p.n)] + [tb.gold[lay["P_diag"](i)] for i in range(p.n)]
        else:
            want = [tb.gold[x(i)] for i in range(p.n)] + [tb.gold[lay["P"](i, i)] for i in range(p.n)]
        assert got == want, (it, [hex(g) for g in got], [hex(w) for w in want])
        user = frame.tuser if isinstance(frame.tuser, int) else frame.tuser[0]
        assert user == (st.pivot | st.nan << 1), (it, user, st)
        extra = sum(tb.manifest["cycles"][s] for s in ran if s != "iteration")
        assert latency == spec["latency_cycles"] + extra, (latency, spec["latency_cycles"], extra)
        dut._log.info("measurement %d: estimate after %d cycles", it, latency)
        # the status as the bus sees it: done, and the stream idle again
        status = await tb.read_reg("STATUS")
        assert status & tb.bits("STATUS", done=1) and not status & 1, hex(status)
        await tb.write_reg("STATUS", status)
    for name in ("x", covariance_region(tb.params.form), "z", "sigma_points_f", "sigma_points_h"):
        await tb.check(name)
    # one transfer in and one out per measurement: nothing lost, duplicated or extra
    assert [c.transfers for c in checks] == [steps, steps], [c.transfers for c in checks]
    assert checks[1].waits > 0  # the sink's backpressure held the estimate at least once


def AugmentedUKF_ref(p, x0, P0, Q, R):
    return (SquareRootUKF if p.form == "sqrt" else AugmentedUKF)(p.n, p.nw, p.nv, p.m, f, h, p.w0, x0, P0, Q, R)


@cocotb.test()
async def errors(dut):
    """Holes, read-only blocks, writes while busy, start while busy, reads while busy, soft
    reset mid-step, a P that is not positive definite; a wait with no start ends at the
    watchdog's bound."""
    tb = await setup(dut, UkfTB)
    p = tb.params
    axi = tb.axi
    await holes(tb)
    # read-only: sigma_points (and ID, in holes)
    await tb.put("sigma_points", np.zeros((p.N, p.M)), expect=AxiResp.SLVERR)
    # a partial strobe on the buffer is refused (whole words only)
    x = tb.mems["x"]["offset"]
    assert (await axi.write(x + 1, b"\x12")).resp == AxiResp.SLVERR
    Q, R = noise(tb)
    await load(tb, [0.5] * p.n, np.eye(p.n) * 0.4)
    # while busy: a buffer write answers SLVERR and changes nothing; start is refused
    assert await tb.start("sig_gen") == AxiResp.OKAY
    assert await tb.read_reg("STATUS") & 1, "busy"
    await tb.put("x", [9.0] * p.n, expect=AxiResp.SLVERR)
    assert await tb.start("predict") == AxiResp.SLVERR
    assert await tb.read_reg("STATUS") & 1
    assert dut.irq.value == 1  # err_busy
    # reads while busy wait for a free memory port and answer OKAY: sig_gen writes none of these
    for name in ("x", "Q", "R"):  # (written by this test; z keeps an earlier test's words)
        await tb.check(name)
    tb.prologue.run("sig_gen", tb.gold)  # (the sqrt form's noise first: Q and R were loaded)
    await wait_idle(tb, "sig_gen")
    status = await tb.read_reg("STATUS")
    assert status == tb.bits("STATUS", done=1, err_busy=1), hex(status)
    await tb.check("x")
    await tb.check("sigma_points")
    await tb.write_reg("STATUS", status)
    # soft reset mid-step: idle at once, STATUS clear, no done, no irq
    assert await tb.start("sig_gen") == AxiResp.OKAY
    await ClockCycles(dut.clk, tb.manifest["cycles"]["sig_gen"] // 2)
    assert await tb.write_reg("CTRL", tb.bits("CTRL", reset=1)) == AxiResp.OKAY
    tb.prologue.stale = True  # a soft reset: the next sig_gen of the sqrt form runs noise first
    assert await tb.read_reg("STATUS") == 0
    await ClockCycles(dut.clk, tb.manifest["cycles"]["sig_gen"])
    assert await tb.read_reg("STATUS") == 0 and dut.irq.value == 0
    await tb.step("sig_gen")  # usable again, and the step ends as one run would
    await tb.check("sigma_points")
    # a P that is not positive definite (the sqrt form: a Q, factored by noise, started
    # here by itself: before a sig_gen, its err_pivot would raise irq at noise's end)
    if p.form == "sqrt":
        await tb.put("Q", -np.eye(p.nw))
        st, _ = await tb.step("noise")
        assert st.pivot
    else:
        await tb.put("P", np.eye(p.n) - 2 * (1 - np.eye(p.n)))
    st, _ = await tb.step("sig_gen")
    assert st.pivot != (p.form == "sqrt")  # (noise has run: the sqrt form's sig_gen runs alone)
    assert not await tb.read_reg("STATUS") & 1
    await tb.check("sigma_points")
    await watchdog_fires(tb, "sig_gen")


def driver_session(core, tb, module, iterations=4):
    """The generated driver's session (:func:`kfgen.sim.engine.driver_tb.python_driver`, in its
    thread) on a core of the chapter's three steps: load, ``iterations`` iterations with f and
    h in the driver (half waiting on irq, half polling STATUS), each estimate equal to the
    golden model's."""
    p = tb.params
    assert "sig_gen" in module.STEPS, "the driver's session runs the three-step form"
    x0, P0 = start_values(tb)
    core.load(x0, P0, *noise(tb))
    truth = np.array(x0)
    for it in range(iterations):
        if it == iterations // 2:
            core.wait_event = None  # poll STATUS from now on
        truth = f(truth, np.zeros(p.nw))
        z = h(truth, np.zeros(p.nv)) + tb.rng.normal(0, 0.1, p.m)
        x, P = core.step(z, f=lambda x, w, u: f(x, w), h=h)
        assert np.array_equal(x, golden(tb, "x").ravel()), (it, x)
        S = golden(tb, covariance_region(p.form))
        assert np.array_equal(P, np.tril(S) @ np.tril(S).T if p.form == "sqrt" else S), (it, P)
    return iterations


@cocotb.test()
async def python_driver(dut):
    """The generated Python driver ``TOP_driver.py`` runs the filter through AXI4, f and h in
    it (:mod:`kfgen.sim.engine.driver_tb`): every word it reads equals the golden model's,
    its estimates too."""
    done = await run_python_driver(dut, UkfTB, driver_session)
    dut._log.info("python driver: %d iterations", done)
