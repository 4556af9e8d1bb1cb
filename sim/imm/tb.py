"""cocotb testbench of a generated IMM core, driven as software would drive it through the
engine's harness (:class:`kfgen.sim.engine.tb.TB`: cocotbext-axi's ``AxiMaster``, bursts for
the buffer, single beats for the registers, random idle cycles and backpressure on every
channel, AXI handshake checkers).

Every word read back is compared with the bit-exact golden model
(:func:`kfgen.sim.linalg.exec.run` on the same program), every iteration's cycles with the
manifest's ``cycles``.

Environment: ``KFGEN_TB_MANIFEST``, the core's ``TOP.json``; ``KFGEN_TB_SEED`` (default 1);
``KFGEN_TB_ITERATIONS`` (default 4).
"""

from __future__ import annotations

import os

import cocotb
import numpy as np
from cocotb.triggers import ClockCycles
from cocotb.utils import get_sim_time
from cocotbext.axi import AxiResp

from kfgen.hdl.imm.params import ImmParams
from kfgen.hdl.imm.steps import programs
from kfgen.sim.engine.campaign import engine_campaign
from kfgen.sim.engine.driver_tb import golden, python_driver as run_python_driver
from kfgen.sim.engine.tb import CLOCK_NS, TB, holes, setup, wait_idle, watchdog_fires
from kfgen.sim.imm.golden import buffer_values
from kfgen.sim.imm.scenario import SEED, satlink
from kfgen.sim.linalg.exec import run

#: The regions software writes before the first iteration, in buffer order.
INPUTS = ("pi", "mu", "F", "Q", "H", "R", "x_model", "P_model")


class ImmTB(TB):
    PARAMS = ImmParams
    PROGRAMS = staticmethod(programs)


def system(params, rng):
    """A generic test system for any R, n, d: models that differ in their noise levels, a
    chain of integrators as F, H measuring every (n / d)-th state, a sticky transition
    matrix; the initial per-model states and covariances. Values as float64 arrays keyed by
    region name."""
    R, n, d = params.R, params.n, params.d
    F = np.eye(n) + 0.1 * np.eye(n, k=1)
    H = np.zeros((d, n))
    for i in range(d):
        H[i, (i * n) // d] = 1.0
    pi = np.full((R, R), 0.1 / (R - 1))
    np.fill_diagonal(pi, 0.9)
    Ps = []
    for _ in range(R):
        A = rng.normal(size=(n, n)) * 0.2
        Ps.append(np.eye(n) * 0.5 + A @ A.T)
    return {
        "pi": pi, "mu": np.full(R, 1.0 / R),
        "F": np.vstack([F] * R),
        "Q": np.vstack([np.eye(n) * 0.01 * 4.0 ** r for r in range(R)]),
        "H": np.vstack([H] * R),
        "R": np.vstack([np.eye(d) * 0.2 * 2.0 ** r + 0.05 * (1 - np.eye(d)) for r in range(R)]),
        "x_model": rng.normal(size=(R, n)),
        "P_model": np.vstack(Ps),
    }


async def load(tb, values):
    for name in INPUTS:
        await tb.put(name, values[name])


async def iterate(tb, z, check=("mu", "x_model", "P_model", "x", "P")):
    """Write z, run one iteration (checked: status, cycles), read every output region word
    for word against the golden model; the values read, by region."""
    await tb.put("z", z)
    st, cycles = await tb.step("iterate")
    out = {name: await tb.check(name) for name in check}
    return st, cycles, out


@cocotb.test()
async def iterations(dut):
    """ID, then several IMM iterations with every word checked and the cycles measured."""
    tb = await setup(dut, ImmTB)
    p = tb.params
    ident = await tb.read_reg("ID") | await tb.read_reg("ID", 1) << 32
    for fd in tb.regs["ID"]["fields"]:
        assert ident >> fd["lsb"] & ((1 << fd["width"]) - 1) == fd["reset"], fd["name"]
    assert (ident >> 32 & 0xFF, ident >> 40 & 0xFF, ident >> 48 & 0xFF) == (p.R, p.n, p.d)
    values = system(p, tb.rng)
    await load(tb, values)
    H = values["H"][:p.d]
    truth = values["x_model"][0].copy()
    F = values["F"][:p.n]
    for it in range(int(os.environ.get("KFGEN_TB_ITERATIONS", "4"))):
        truth = F @ truth
        st, cycles, out = await iterate(tb, H @ truth + tb.rng.normal(0, 0.3, p.d))
        assert not (st.pivot or st.nan), st
        mu = out["mu"].ravel()
        assert abs(mu.sum() - 1) < 1e-3 and (mu >= 0).all(), mu
        assert np.array_equal(out["P"], out["P"].T)  # one triangle, mirrored
        dut._log.info("iteration %d: %d cycles, mu %s", it, cycles, np.round(mu, 4))
    # a measurement far from every model: every unscaled likelihood would underflow to 0
    # (exp(-q/2) with q in the thousands); the scaled normalisation keeps mu a distribution
    st, _, out = await iterate(tb, H @ truth + 1e3)
    mu = out["mu"].ravel()
    assert not (st.pivot or st.nan) and np.isfinite(mu).all() and abs(mu.sum() - 1) < 1e-3, (st, mu)


async def clean_iteration(tb):
    """Freshly loaded models and one iteration, every word against the golden model (what a
    fault campaign's sequence must leave the core able to do)."""
    values = system(tb.params, tb.rng)
    await load(tb, values)
    st, _, _ = await iterate(tb, values["H"][:tb.params.d] @ values["x_model"][0])
    assert not (st.pivot or st.nan), st


@cocotb.test()
async def fault_campaign(dut):
    """Seeded random sequences of bus traffic, starts, soft and bus resets, each followed by a
    clean iteration (:mod:`kfgen.sim.engine.campaign`)."""
    tb = await setup(dut, ImmTB)
    counts = await engine_campaign(tb, clean_iteration, CLOCK_NS)
    dut._log.info("fault campaign: %s", counts)


@cocotb.test()
async def errors(dut):
    """Holes, read-only regions, strobes, writes and start while busy, reads while busy, soft
    reset mid-iteration, an innovation covariance that is not positive definite; a wait with
    no start ends at the watchdog's bound."""
    tb = await setup(dut, ImmTB)
    p = tb.params
    axi = tb.axi
    await holes(tb)
    for name in ("x", "P"):  # the combined estimate is the core's to write
        await tb.put(name, np.zeros(tb.layout[name].size), expect=AxiResp.SLVERR)
    assert (await axi.write(tb.mems["z"]["offset"] + 1, b"\x12")).resp == AxiResp.SLVERR
    values = system(p, tb.rng)
    await load(tb, values)
    await tb.put("z", np.zeros(p.d))
    # while busy: a buffer write answers SLVERR and changes nothing; start is refused with
    # err_busy; reads wait for a free port and answer OKAY (the iteration never writes F, H)
    assert await tb.start("iterate") == AxiResp.OKAY
    assert await tb.read_reg("STATUS") & 1, "busy"
    await tb.put("z", np.ones(p.d), expect=AxiResp.SLVERR)
    assert await tb.start("iterate") == AxiResp.SLVERR
    assert dut.irq.value == 1  # err_busy
    for name in ("F", "H", "z"):
        await tb.check(name)
    run(tb.programs.steps["iterate"], tb.gold)
    await wait_idle(tb, "iterate")
    status = await tb.read_reg("STATUS")
    assert status == tb.bits("STATUS", done=1, err_busy=1), hex(status)
    for name in ("mu", "x_model", "P_model", "x", "P"):
        await tb.check(name)
    await tb.write_reg("STATUS", status)
    # soft reset mid-iteration: idle at once, STATUS clear, no done, no irq
    assert await tb.start("iterate") == AxiResp.OKAY
    await ClockCycles(dut.clk, tb.manifest["cycles"]["iterate"] // 2)
    assert await tb.write_reg("CTRL", tb.bits("CTRL", reset=1)) == AxiResp.OKAY
    assert await tb.read_reg("STATUS") == 0
    await ClockCycles(dut.clk, tb.manifest["cycles"]["iterate"])
    assert await tb.read_reg("STATUS") == 0 and dut.irq.value == 0
    # the buffer now holds some state of the stopped iteration: load it again, and run
    await load(tb, values)
    await tb.step("iterate")
    await tb.check("P_model")
    # a measurement noise that is not positive definite makes S indefinite: err_pivot
    await load(tb, values)
    bad = values["R"].copy()
    bad[:p.d] = -np.eye(p.d) * 50.0
    await tb.put("R", bad)
    st, _ = await tb.step("iterate")
    assert st.pivot
    assert not await tb.read_reg("STATUS") & 1
    await tb.check("mu")
    await watchdog_fires(tb, "iterate")


@cocotb.test()
async def scenario(dut):
    """The slides' satellite-link scenario (:func:`kfgen.sim.imm.scenario.satlink`) on the
    core, as software would run it: the models once, then a measurement and a start an
    iteration; every output word read back and checked against the golden model. Saves the
    model probabilities, combined and per-model states to ``KFGEN_IMM_OUT`` (``.npz``).

    Environment: ``KFGEN_STEPS`` (default 50), ``KFGEN_SEED`` (the scenario's, default its own)."""
    tb = await setup(dut, ImmTB)
    p = tb.params
    steps = int(os.environ.get("KFGEN_STEPS", "50"))
    sc = satlink(steps, int(os.environ.get("KFGEN_SEED", str(SEED))))
    sysm = sc.system
    if (len(sysm.models), sysm.n, sysm.d) != (p.R, p.n, p.d):
        raise ValueError(f"the scenario needs R = {len(sysm.models)}, n = {sysm.n}, d = {sysm.d}")
    await load(tb, buffer_values(sysm, sc.mu0, sc.xs0, sc.Ps0))
    mu, x, xs, P = [], [], [], []
    t0 = get_sim_time("ns")
    for k in range(steps):
        st, _, out = await iterate(tb, sc.zs[k])
        assert not (st.pivot or st.nan), (k, st)
        mu.append(out["mu"].ravel())
        x.append(out["x"].ravel())
        xs.append(out["x_model"])
        P.append(out["P"])
        if k % 100 == 0:
            dut._log.info("step %d: mu %s", k, np.round(mu[-1], 4))
    if os.environ.get("KFGEN_IMM_OUT"):
        np.savez(os.environ["KFGEN_IMM_OUT"], mu=np.array(mu), x=np.array(x), xs=np.array(xs), P=np.array(P),
                 seed=sc.seed, cycles=int((get_sim_time("ns") - t0) // CLOCK_NS))


def driver_session(core, tb, module, iterations=4):
    """The generated driver's session (:func:`kfgen.sim.engine.driver_tb.python_driver`, in its
    thread): load the model set, ``iterations`` iterations (half waiting on irq, half polling
    STATUS), each combined estimate and the model probabilities equal to the golden model's."""
    p = tb.params
    values = system(p, tb.rng)
    core.load(**{arg: values[name] for arg, name, _ in module.LOAD})
    H, F = values["H"][:p.d], values["F"][:p.n]
    truth = values["x_model"][0].copy()
    for it in range(iterations):
        if it == iterations // 2:
            core.wait_event = None  # poll STATUS from now on
        truth = F @ truth
        x, P = core.step(H @ truth + tb.rng.normal(0, 0.3, p.d))
        assert np.array_equal(x, golden(tb, "x").ravel()) and np.array_equal(P, golden(tb, "P")), it
        assert np.array_equal(core.read_region("mu"), golden(tb, "mu")), it
    return iterations


@cocotb.test()
async def python_driver(dut):
    """The generated Python driver ``TOP_driver.py`` runs the IMM through AXI4
    (:mod:`kfgen.sim.engine.driver_tb`): every word it reads equals the golden model's, its
    estimates too."""
    done = await run_python_driver(dut, ImmTB, driver_session)
    dut._log.info("python driver: %d iterations", done)
