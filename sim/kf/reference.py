"""Float64 reference of the linear Kalman filter (filterpy-style pure functions), the
steady-state gain, and the bit-exact golden model over a run.

The reference checks the core's program, not its rounding: written from the textbook
equations with numpy's own linear algebra (K by a solve of S, not by the core's LDL^T).
``predict`` and ``update`` are pure functions as filterpy's ``kalman.predict``/``update``;
:func:`run_reference` keeps ``x_prior``/``P_prior`` and ``x_post``/``P_post`` of every
iteration. The covariance update is the textbook P^- - K S K^T, symmetrised: equal in exact
arithmetic to the core's Joseph form (the gain is the optimal one) and to filterpy's, whose
``update`` takes Joseph's.

The golden model (:func:`run_golden`) runs the core's own program
(:mod:`kfgen.hdl.kf.programs`) word by word through :func:`kfgen.sim.linalg.exec.run`, or
through its batch twin :func:`kfgen.sim.linalg.batch.run_batch` (the same bits, for formats
of at most 25 significand bits) over many runs at once, the buffer loaded as software loads
the core's.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from kfgen.hdl.kf.programs import KfPrograms
from kfgen.sim.linalg.batch import run_batch
from kfgen.sim.linalg.exec import from_words, run, to_words

__all__ = ["predict", "update", "KfRun", "run_reference", "steady_gain", "buffer_values", "run_golden",
           "run_golden_batch"]


def _sym(A: np.ndarray) -> np.ndarray:
    return (A + np.swapaxes(A, -1, -2)) / 2


def predict(x, P, F, Q, B=None, u=None):
    """x^- = F x + B u, P^- = F P F^T + Q (symmetrised)."""
    x = F @ x
    if B is not None and np.size(B):
        x = x + B @ u
    return x, _sym(F @ P @ F.T + Q)


def update(x, P, z, H, R):
    """The update from the prediction ``x``, ``P``: ``(x, P, K, y, S)``."""
    y = z - H @ x
    S = _sym(H @ P @ H.T + R)
    K = np.linalg.solve(S, H @ P).T  # P H^T S^-1, S symmetric
    return x + K @ y, _sym(P - K @ S @ K.T), K, y, S


class KfRun(NamedTuple):
    """Every iteration's prior and posterior: x (T, n), P (T, n, n), and K (T, n, m)."""

    x_prior: np.ndarray
    P_prior: np.ndarray
    x_post: np.ndarray
    P_post: np.ndarray
    K: np.ndarray


def run_reference(F, H, Q, R, x0, P0, zs, B=None, us=None, K=None) -> KfRun:
    """The filter over the measurements ``zs`` (T, m) (and inputs ``us`` (T, nu)); with a
    fixed gain ``K`` the steady-state filter (P is then not propagated: zeros)."""
    x, P = np.asarray(x0, float), np.asarray(P0, float)
    out = {k: [] for k in KfRun._fields}
    for k, z in enumerate(np.asarray(zs, float)):
        u = None if us is None else np.asarray(us[k], float)
        if K is None:
            xp, Pp = predict(x, P, F, Q, B, u)
            x, P, Kk, _, _ = update(xp, Pp, z, H, R)
        else:
            xp, Pp = predict(x, np.zeros_like(F), F, np.zeros_like(F), B, u)
            Kk, P = np.asarray(K, float), Pp
            x = xp + Kk @ (z - H @ xp)
        for name, v in zip(KfRun._fields, (xp, Pp, x, P, Kk)):
            out[name].append(v)
    return KfRun(*(np.array(v) for v in out.values()))


def steady_gain(F, H, Q, R) -> np.ndarray:
    """The steady-state gain K = P H^T (H P H^T + R)^-1, P the prior covariance solving the
    discrete algebraic Riccati equation (scipy, float64): what software writes into a
    ``steady_gain`` core's K."""
    from scipy.linalg import solve_discrete_are  # deferred: scipy only for the steady gain
    P = solve_discrete_are(np.asarray(F, float).T, np.asarray(H, float).T, Q, R)
    return np.linalg.solve(H @ P @ H.T + R, H @ P).T


def buffer_values(progs: KfPrograms, F, H, x0, B=None, Q=None, R=None, P0=None, K=None) -> dict:
    """The regions software writes before the first iteration, by name (those the layout
    has: P, Q, R for the full filter, K for the steady gain's, B with inputs)."""
    given = {"F": F, "H": H, "x": x0, "B": B, "Q": Q, "R": R, "P": P0, "K": K}
    lay = progs.layout
    out = {}
    for name, v in given.items():
        if name in lay.regions and (name != "K" or lay[name].kind == "bus"):
            if v is None:
                raise ValueError(f"the layout holds {name}: give its value")
            out[name] = np.asarray(v, float)
    return out


def _inputs(progs: KfPrograms, zs, us):
    zs = np.asarray(zs, float).reshape(len(zs), -1)
    if progs.sizes.nu:
        if us is None:
            raise ValueError("the filter has inputs: give us")
        us = np.asarray(us, float).reshape(len(zs), -1)
    return zs, us


def _prologue(progs: KfPrograms):
    """The prologue step's program (run once: the buffer's values are written once), or None."""
    return None if progs.prologue is None else progs.steps[progs.prologue[0]]


def _flags(st):
    """The status as the runners' flags (1 pivot, 2 NaN): an int, or an array per run."""
    return (st.pivot * 1) | (st.nan * 2)


def run_golden(progs: KfPrograms, values: dict, zs, us=None, keep=("x", "P")) -> dict:
    """The golden model over the measurements ``zs`` (T, m) and inputs ``us`` (T, nu):
    each region of ``keep`` (T, rows, cols) as the core's buffer holds it after each
    iteration, and ``flags`` (T,) of its status (1 pivot, 2 NaN; the prologue's, which runs
    once after the values are written, in the first iteration's)."""
    lay, f = progs.layout, progs.fmt
    zs, us = _inputs(progs, zs, us)
    mem = lay.initial_memory()

    def put(name, v):
        r = lay[name]
        mem[r.base:r.base + r.size] = to_words(f, np.ravel(v))

    def get(name):
        r = lay[name]
        return np.array(from_words(f, mem[r.base:r.base + r.size])).reshape(r.rows, r.cols)

    for name, v in values.items():
        put(name, v)
    pre = _prologue(progs)
    flags = 0 if pre is None else _flags(run(pre, mem))
    out = {k: [] for k in (*keep, "flags")}
    for k, z in enumerate(zs):
        put("z", z)
        if us is not None:
            put("u", us[k])
        out["flags"].append(flags | _flags(run(progs.iterate, mem)))
        flags = 0
        for name in keep:
            out[name].append(get(name))
    return {k: np.array(v) for k, v in out.items()}


def run_golden_batch(progs: KfPrograms, values: dict, zs, us=None, keep=("x", "P")) -> dict:
    """:func:`run_golden` over S runs at once (binary32 and narrower), every run from the
    same ``values``: ``zs`` (S, T, m) and ``us`` (S, T, nu); the regions of ``keep``
    (S, T, rows, cols) and ``flags`` (S, T)."""
    lay, f = progs.layout, progs.fmt
    zs = np.asarray(zs, float)
    runs, T = zs.shape[:2]
    mem = np.tile(np.array(from_words(f, lay.initial_memory())), (runs, 1))

    def put(name, v):  # v: one value for every run, or (S, size)
        r = lay[name]
        v = np.broadcast_to(np.asarray(v, float).reshape(-1, r.size), (runs, r.size))
        mem[:, r.base:r.base + r.size] = np.reshape(from_words(f, to_words(f, v.ravel())), (runs, r.size))

    for name, v in values.items():
        put(name, v)
    pre = _prologue(progs)
    flags = 0 if pre is None else _flags(run_batch(pre, mem))
    out = {k: [] for k in (*keep, "flags")}
    for k in range(T):
        put("z", zs[:, k])
        if us is not None:
            put("u", np.asarray(us, float)[:, k])
        out["flags"].append(flags | _flags(run_batch(progs.iterate, mem)))
        flags = 0
        for name in keep:
            r = lay[name]
            out[name].append(mem[:, r.base:r.base + r.size].reshape(runs, r.rows, r.cols).copy())
    return {k: np.swapaxes(np.array(v), 0, 1) for k, v in out.items()}
