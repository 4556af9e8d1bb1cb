"""A float64 extended Kalman filter, written from the textbook equations with numpy's linear
algebra, its Jacobians computed independently of the core's differentiation: central finite
differences of the application's own numpy f and h (:class:`FiniteDifferences`), or any
functions the caller supplies (hand-written analytic Jacobians in the tests).

One iteration (the core's order, :mod:`kfgen.hdl.ekf.programs`):
x^- = f(x, 0, u), P^- = F P F^T + L Q L^T; z^ = h(x^-, 0), S = H P^- H^T + M R M^T,
K = P^- H^T S^-1, x = x^- + K (z - z^), P = P^- - K H P^- (symmetrised).
"""

from __future__ import annotations

import numpy as np

__all__ = ["central_differences", "FiniteDifferences", "ekf_step", "run_reference", "measurements"]


def measurements(app, steps: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """The application's scenario of ``steps`` iterations: its control inputs (K, nu; an empty
    column without any) and measurements (K, m)."""
    sc = app.scenario(steps, seed)
    us = np.zeros((steps, 0)) if sc.u is None else np.asarray(sc.u, dtype=np.float64).reshape(steps, -1)
    return us, np.asarray(sc.z, dtype=np.float64).reshape(steps, -1)


def central_differences(fn, at: np.ndarray, step: float) -> np.ndarray:
    """d fn / d at by central differences, each input's step ``step`` times max(1, |at_j|)."""
    cols = []
    for j in range(len(at)):
        h = step * max(1.0, abs(at[j]))
        e = np.zeros(len(at))
        e[j] = h
        cols.append((np.asarray(fn(at + e), dtype=np.float64) - np.asarray(fn(at - e), dtype=np.float64)) / (2 * h))
    return np.array(cols).T.reshape(-1, len(at))


class FiniteDifferences:
    """An application's Jacobians by central differences of its own f and h (float64):
    ``fx(x, u) -> (F, L)`` at w = 0, ``hx(x) -> (H, M)`` at v = 0."""

    def __init__(self, app, step: float = 1e-6):
        self.app, self.step = app, step

    def fx(self, x, u):
        app = self.app
        w0 = np.zeros(app.nw)
        F = central_differences(lambda xx: app.f(xx, w0, u, app.dt), np.asarray(x, dtype=np.float64), self.step)
        L = central_differences(lambda ww: app.f(x, ww, u, app.dt), w0, self.step)
        return F, L

    def hx(self, x):
        app = self.app
        v0 = np.zeros(app.nv)
        H = central_differences(lambda xx: app.h(xx, v0), np.asarray(x, dtype=np.float64), self.step)
        M = central_differences(lambda vv: app.h(x, vv), v0, self.step)
        return H, M


def ekf_step(app, x, P, u, z, jac) -> dict:
    """One iteration from ``x``, ``P`` with the control input ``u`` and the measurement ``z``;
    ``jac`` has ``fx(x, u) -> (F, L)`` and ``hx(x) -> (H, M)``. Returns ``x``, ``P`` (after
    the update) and ``x_prior``, ``P_prior``, ``F``, ``H``."""
    x = np.asarray(x, dtype=np.float64)
    F, L = jac.fx(x, u)
    xp = np.asarray(app.f(x, np.zeros(app.nw), u, app.dt), dtype=np.float64)
    Pp = F @ P @ F.T + L @ app.Q @ L.T
    H, M = jac.hx(xp)
    zp = np.asarray(app.h(xp, np.zeros(app.nv)), dtype=np.float64)
    S = H @ Pp @ H.T + M @ app.R @ M.T
    K = np.linalg.solve(S, H @ Pp).T  # P^- H^T S^-1, S and P^- symmetric
    Pn = Pp - K @ H @ Pp
    return {"x": xp + K @ (np.asarray(z, dtype=np.float64) - zp), "P": (Pn + Pn.T) / 2,
            "x_prior": xp, "P_prior": Pp, "F": F, "H": H}


def run_reference(app, us, zs, jac=None, x0=None, P0=None) -> dict:
    """The filter over the control inputs ``us`` (K, nu) and measurements ``zs`` (K, m) from
    ``app.x0``, ``app.P0`` (or ``x0``, ``P0``), with ``jac`` (default
    :class:`FiniteDifferences` of ``app``): each :func:`ekf_step` result stacked, (K, ...)."""
    jac = jac or FiniteDifferences(app)
    x = np.asarray(app.x0 if x0 is None else x0, dtype=np.float64)
    P = np.asarray(app.P0 if P0 is None else P0, dtype=np.float64)
    out = []
    for u, z in zip(us, zs):
        step = ekf_step(app, x, P, u, z, jac)
        x, P = step["x"], step["P"]
        out.append(step)
    return {k: np.array([s[k] for s in out]) for k in out[0]}
