"""A UKF application: the user's half of the chapter's HW/SW codesign.

The core computes everything that does not depend on the system (sigma points, means,
covariances, gain); the application supplies what does: the sizes, the process model f and
the observation model h (run in software on the processor, eqs. 1-2, 9, 12), the filter's
parameters (W0, x0, P0, Q, R) and, for simulation, a seeded scenario. One class describes
it; ``kfgen ukf --app module:Class`` sizes a core for it, and the float64 reference, the
bit-exact golden model and a co-simulation run it unchanged.

Write one subclass of :class:`UkfApplication`::

    class Pendulum(UkfApplication):
        n, nw, nv, m = 2, 2, 1, 1
        dt = 0.01
        x0 = [0.1, 0.0]
        P0 = np.eye(2)
        Q = np.eye(2) * 1e-4
        R = [[1e-2]]

        def f(self, x, w, u, dt):
            return x + dt * np.array([x[1], -9.81 * np.sin(x[0])]) + w

        def h(self, x, v):
            return np.array([np.sin(x[0])]) + v

        def scenario(self, steps, seed):
            ...

(``docs/examples/pendulum.py`` is this example complete, with its scenario) and load it
with :func:`load_app` (``"my_module:Pendulum"``, ``"path/to/file.py:Pendulum"``, or for the
applications shipped in :mod:`kfgen.sim.ukf.apps` the short ``"nanosat:Nanosat"``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from kfgen.hdl.engine.app import (AppError, UkfApplication, check_models, checked_array, load_app, one_line,
                                  portable_spec)

__all__ = ["AppError", "Scenario", "UkfApplication", "load_app", "portable_spec", "checked_scenario", "check_models"]


class Scenario(NamedTuple):
    """A seeded run of ``K`` filter iterations.

    Iteration k (from 0) predicts with the control input ``u[k]`` over ``dt``, then updates
    with the measurement ``z[k]`` taken at time ``t[k]`` of the true state ``truth[k]``: the
    filter's estimate after iteration k is to be compared with ``truth[k]``.

    Without a control input ``u`` is ``None`` (or an array of shape (K, 0)): f then gets an
    empty array, shape (0,), as its ``u`` (:meth:`inputs`).
    """

    t: np.ndarray  #: (K,) time of each measurement, s (the first at dt)
    truth: np.ndarray  #: (K, n) the true states
    u: np.ndarray | None  #: (K, p) control inputs passed to f (None or p = 0: none)
    z: np.ndarray  #: (K, m) measurements

    def inputs(self):
        """``(u[k], z[k])`` for each iteration k, ``u[k]`` an empty array when ``u`` is None."""
        z = np.asarray(self.z, dtype=np.float64)
        u = np.zeros((len(z), 0)) if self.u is None else np.asarray(self.u, dtype=np.float64)
        return zip(u, z)


def checked_scenario(app: UkfApplication, steps: int, seed: int) -> Scenario:
    """``app.scenario(steps, seed)``, checked: exactly ``steps`` iterations, ``t`` (K,),
    ``truth`` (K, n), ``u`` None or (K, p), ``z`` (K, m), u and z finite.

    Raises
    ------
    AppError
        With a one-line message: no ``scenario`` method, one that raises, or arrays that do
        not fit.
    """
    name = type(app).__name__
    if getattr(type(app), "scenario", None) is UkfApplication.scenario:
        raise AppError(f"{name} defines no scenario(steps, seed): a run needs its measurements "
                       f"(see kfgen.sim.ukf.app.Scenario)")
    try:
        sc = app.scenario(steps, seed)
    except Exception as exc:  # the user's code: whatever it raises, one line
        raise AppError(f"{name}.scenario({steps}, {seed}) failed: {type(exc).__name__}: {one_line(exc)}") from None
    if not isinstance(sc, tuple) or len(sc) != 4:
        raise AppError(f"{name}.scenario() must return a Scenario(t, truth, u, z), not {type(sc).__name__}")
    t, truth, u, z = sc
    what = f"{name}.scenario({steps}, {seed})"
    out = Scenario(checked_array(f"{what}.t", t, (steps,)), checked_array(f"{what}.truth", truth, (steps, app.n)),
                   None, checked_array(f"{what}.z", z, (steps, app.m)))
    if u is not None:
        try:
            shape = np.shape(u)
        except (TypeError, ValueError):
            shape = None
        if shape is None or len(shape) != 2:
            got = "not numbers" if shape is None else f"shape {shape}"
            raise AppError(f"{what}.u must be None (no control input) or an array of shape ({steps}, p), not {got}")
        width = shape[1]
        out = out._replace(u=checked_array(f"{what}.u", u, (steps, width)))
    return out
