"""HW/SW co-simulation of an IMM application (:mod:`kfgen.sim.imm.app`): a simulated processor
drives the generated core (Verilog in Verilator) through ``s_axi`` on the engine's harness
(:class:`kfgen.sim.engine.tb.TB`: cocotbext-axi's ``AxiMaster``, random idle cycles and
backpressure), and every word it reads back is held against the bit-exact golden model
(:func:`kfgen.sim.linalg.exec.run` on the core's program).

Two processors run the same steps:

* ``python_processor``: loads the buffer from the application (pi, mu0, the models' F, Q, H,
  R, the initial states and covariances), then each step writes z, starts, waits for ``irq``
  and reads mu, the per-model states and covariances and the combined x and P, every word
  checked (:func:`kfgen.sim.imm.tb.iterate`), the step's cycles against the manifest's;
* ``c_processor``: the generated C driver (``TOP_driver.c`` built with
  ``-DKFGEN_MMIO_HOOKS``: ``TOP_init``, ``TOP_load``, ``TOP_step``, ``TOP_estimate``,
  ``TOP_models``), its MMIO hooks on the same AXI master (:class:`kfgen.sim.engine.mmio.TbMmio`:
  every access mirrored on the golden model, every word read checked).

Environment: ``KFGEN_TB_MANIFEST`` (the core's ``TOP.json``), ``KFGEN_APP`` (``module:Class``
or an absolute ``file.py:Class``), ``KFGEN_APP_DIR`` (put on ``sys.path``), ``KFGEN_STEPS``,
``KFGEN_SEED``, ``KFGEN_DRIVER_LIB`` (the C driver's shared library, for ``c_processor``),
``KFGEN_COSIM_OUT`` (an ``.npz``: ``mu``, ``x``, ``P``, ``xs``, ``Ps`` after every step, the
measurements ``z``, the ``truth`` if the scenario gives it, the ``cycles`` of every step's
iteration and ``total`` cycles from its first transfer to its last), ``KFGEN_COSIM_FAULT`` (a
``.json`` written when a step raises ``err_pivot`` or ``err_nan``: ``{"step", "bit",
"iteration"}``, the test then fails).
"""

from __future__ import annotations

import ctypes
import json
import os
import time

import cocotb
import numpy as np
from cocotb.task import bridge

from kfgen.sim.engine.mmio import Dev, Guard, TbMmio, c_function, set_hooks
from kfgen.sim.engine.tb import setup

from .app import checked_scenario, load_imm_app
from .golden import buffer_values
from .tb import INPUTS, ImmTB, iterate, load

#: The IMM's one step.
STEP = "iterate"


class Run:
    """One co-simulation: the application, its scenario, the testbench and the trace."""

    def __init__(self, tb):
        self.tb = tb  # its manifest's loading put KFGEN_APP_DIR on sys.path
        self.app = load_imm_app(os.environ["KFGEN_APP"])
        self.steps = int(os.environ.get("KFGEN_STEPS", "20"))
        self.scenario = checked_scenario(self.app, self.steps, int(os.environ.get("KFGEN_SEED", "1")))
        self.values = buffer_values(self.app.system(), *self.app.initial())
        self.trace = {k: [] for k in ("mu", "x", "P", "xs", "Ps", "cycles", "total")}

    def fault(self, status, k):
        """Leave the fault of step ``k`` for the runner in ``KFGEN_COSIM_FAULT``; fail."""
        bit = "err_pivot" if status.pivot else "err_nan"
        path = os.environ.get("KFGEN_COSIM_FAULT")
        if path:
            with open(path, "w") as f:
                json.dump({"step": STEP, "bit": bit, "iteration": k}, f)
        raise AssertionError(f"iteration {k}: {bit}")

    def record(self, mu, x, P, xs, Ps, cycles, total):
        p = self.tb.params
        for key, v in (("mu", np.ravel(mu)), ("x", np.ravel(x)), ("P", np.reshape(P, (p.n, p.n))),
                       ("xs", np.reshape(xs, (p.R, p.n))), ("Ps", np.reshape(Ps, (p.R, p.n, p.n))),
                       ("cycles", cycles), ("total", total)):
            self.trace[key].append(v)

    def finish(self, wall):
        tb = self.tb
        cyc = np.array(self.trace["total"])
        tb.dut._log.info("%d steps, %d cycles in %.1f s; %.0f cycles a step from its first transfer to its last",
                         self.steps, tb.now(), wall, cyc.mean())
        out = os.environ.get("KFGEN_COSIM_OUT")
        if out:
            truth = {} if self.scenario.truth is None else {"truth": self.scenario.truth}
            # (the C processor does not measure an iteration's cycles alone: no "cycles")
            trace = {k: np.array(v) for k, v in self.trace.items() if not any(e is None for e in v)}
            np.savez(out, **trace, z=self.scenario.z, **truth,
                     wall_s=wall, sim_cycles=tb.now())


@cocotb.test()
async def python_processor(dut):
    """The application's steps by Python software over AXI."""
    tb = await setup(dut, ImmTB)
    r = Run(tb)
    wall = time.monotonic()
    await load(tb, r.values)
    for k, z in enumerate(r.scenario.z):
        t0 = tb.now()
        st, cycles, out = await iterate(tb, z)
        if st.pivot or st.nan:
            r.fault(st, k)
        r.record(out["mu"], out["x"], out["P"], out["x_model"], out["P_model"], cycles, tb.now() - t0)
    r.finish(time.monotonic() - wall)


@cocotb.test()
async def c_processor(dut):
    """The same steps by the generated C driver, its MMIO hooks on the same AXI master."""
    tb = await setup(dut, ImmTB)
    r = Run(tb)
    p = tb.params
    lib = ctypes.CDLL(os.environ["KFGEN_DRIVER_LIB"])
    top = tb.manifest["parameters"]["name"]
    mmio, guard = TbMmio(tb), Guard()
    hooks = set_hooks(lib, top, guard, mmio.read32, mmio.write32, mmio.read_block, mmio.write_block, mmio.wait_event)
    init, step = c_function(lib, top, "init"), c_function(lib, top, "step")
    load_c, estimate, models = (c_function(lib, top, s, None) for s in ("load", "estimate", "models"))
    dbl = ctypes.POINTER(ctypes.c_double)

    def arr(values):
        a = np.ascontiguousarray(np.ravel(np.asarray(values, dtype=np.float64)))
        return a, a.ctypes.data_as(dbl)

    dev = Dev()
    wall = time.monotonic()
    ok = await bridge(init)(ctypes.byref(dev), ctypes.c_size_t(0))
    guard.check()
    assert ok == 0, "the core's ID does not match the driver's header"
    inputs = [arr(r.values[name]) for name in INPUTS]
    await bridge(load_c)(ctypes.byref(dev), *(ptr for _, ptr in inputs))
    guard.check()
    mu, x, P = arr(np.zeros(p.R)), arr(np.zeros(p.n)), arr(np.zeros(p.n * p.n))
    xs, Ps = arr(np.zeros(p.R * p.n)), arr(np.zeros(p.R * p.n * p.n))
    for k, z in enumerate(r.scenario.z):
        t0 = tb.now()
        z_arr = arr(z)
        err = await bridge(step)(ctypes.byref(dev), z_arr[1])
        guard.check()
        if err:  # the STATUS bits the step ended with (TOP_run's return)
            r.fault(mmio.last, k)
        await bridge(estimate)(ctypes.byref(dev), mu[1], x[1], P[1])
        await bridge(models)(ctypes.byref(dev), xs[1], Ps[1])
        guard.check()
        r.record(mu[0].copy(), x[0].copy(), P[0].copy(), xs[0].copy(), Ps[0].copy(), None, tb.now() - t0)
    assert hooks  # the callbacks lived while the driver ran
    r.finish(time.monotonic() - wall)
