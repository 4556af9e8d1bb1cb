"""The UKF core's smoke testbench (``TOP_tb.v``): the script of a session on the golden device
(:mod:`kfgen.sim.engine.script`) that the testbench replays on the RTL, every word read
compared with the golden model's.

The session is the processor's software of :mod:`kfgen.sim.ukf.software`, run unchanged on the
script: with f and h in software (the chapter's three steps) the script holds every word the
software reads (the sigma points) and writes (f's and h's results, rounded to the core's
format); on chip, u and z and one start an iteration."""

from __future__ import annotations

import numpy as np

from kfgen.hdl.ukf.params import covariance_region
from kfgen.hdl.ukf.steps import programs
from kfgen.sim.engine.script import Script

from .app import UkfApplication, checked_scenario, load_app
from .software import complete, initial_words, iteration

__all__ = ["ITERATIONS", "SEED", "smoke_plan"]

#: Filter iterations the testbench runs.
ITERATIONS = 2
#: The scenario's seed.
SEED = 1


class GenericModel(UkfApplication):
    """A nonlinear model of any size for a core without an application: a motion model with a
    sine term and range-like observations."""

    dt = 0.1

    def __init__(self, params):
        self.n, self.nw, self.nv, self.m, self.W0 = params.n, params.nw, params.nv, params.m, params.w0
        self.x0 = np.resize([0.5, -1.25], self.n)
        self.P0 = np.eye(self.n) * 0.3 + 0.05 * (np.eye(self.n, k=1) + np.eye(self.n, k=-1))
        self.Q = np.diag(np.linspace(0.02, 0.03, self.nw))
        self.R = np.diag(np.linspace(0.05, 0.06, self.nv))

    def f(self, x, w, u, dt):
        out = np.array(x, dtype=np.float64)
        out[0] = x[0] + dt * x[-1] + 0.01 * np.sin(x[0])
        out[-1] = 0.95 * x[-1]
        out[: len(w)] += w
        return out

    def h(self, x, v):
        return np.array([np.sqrt(x[i % len(x)] ** 2 + 1.0 + i) for i in range(self.m)]) + np.resize(v, self.m)

    def scenario(self, steps, seed):
        rng = np.random.default_rng(seed)
        truth, states, zs = np.array(self.x0, dtype=np.float64), [], []
        for _ in range(steps):
            truth = self.f(truth, np.zeros(self.nw), None, self.dt)
            states.append(truth)
            zs.append(self.h(truth, np.zeros(self.nv)) + rng.normal(0, 0.1, self.m))
        return (np.arange(1, steps + 1) * self.dt, np.array(states), None, np.array(zs))


class _Io:
    """:class:`kfgen.sim.ukf.software.CoreIO` on a :class:`~kfgen.sim.engine.script.Script`."""

    def __init__(self, script):
        self.script = script

    async def step(self, name):
        return self.script.step(name)

    async def read(self, name):
        return self.script.get_words(name)

    async def write(self, name, words):
        self.script.put_words(name, words)


def _application(params) -> UkfApplication:
    """The core's application where the core has its sizes (an option such as
    ``--measurement-noise`` may override one); without one, the nanosatellite's where the core
    has its sizes (the chapter's configuration, the default); else a generic model."""
    app = load_app(params.app if params.app is not None else "nanosat:Nanosat")
    if (app.n, app.nw, app.nv, app.m, app.W0) == (params.n, params.nw, params.nv, params.m, params.w0):
        return app
    return GenericModel(params)


def smoke_plan(params, manifest: dict) -> dict:
    """x0, P0 (or its Cholesky factor), Q, R, then ``ITERATIONS`` iterations of the
    application's scenario as software runs them, x and the covariance read after each."""
    app = _application(params)
    s = Script(manifest, params, programs)
    s.begin()
    for name, words in initial_words(app, s.fmt, params.form).items():
        s.put_words(name, words)
    io = _Io(s)
    sc = checked_scenario(app, ITERATIONS, SEED)
    for it, (u, z) in enumerate(sc.inputs()):
        complete(iteration(io, app, s.fmt, u, z, on_chip=params.on_chip))
        s.get("x")
        s.get(covariance_region(params.form))
        s.end_iteration(it)
    how = "one start" if params.on_chip else "sig_gen, f, predict, h, update"
    return s.plan(f"{ITERATIONS} iterations of {type(app).__name__}'s scenario ({how}), x and "
                  f"{covariance_region(params.form)} against the golden model")
