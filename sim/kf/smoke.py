"""The KF core's smoke testbench (``TOP_tb.v``): the script of a session on the golden device
(:mod:`kfgen.sim.engine.script`) that the testbench replays on the RTL, every word read
compared with the golden model's."""

from __future__ import annotations

import numpy as np

from kfgen.hdl.kf.steps import programs
from kfgen.sim.engine.script import Script

__all__ = ["ITERATIONS", "smoke_plan", "system"]

#: Filter iterations the testbench runs.
ITERATIONS = 2


def _riccati_gain(F, H, Q, R, rounds: int = 500) -> np.ndarray:
    """The steady gain of the Riccati recursion run to its fixed point (numpy only: generating
    needs no scipy)."""
    P = np.eye(len(F))
    for _ in range(rounds):
        P = F @ P @ F.T + Q
        K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
        P = (np.eye(len(F)) - K @ H) @ P
    P = F @ P @ F.T + Q
    return P @ H.T @ np.linalg.inv(H @ P @ H.T + R)


def system(params, rng, gain=_riccati_gain) -> dict:
    """A chain of integrators as F, H measuring every (n / m)-th state, B driving the last
    states, correlated R, a random positive definite P0 (a steady-gain core: its gain); float64
    arrays by region."""
    n, m, nu = params.n, params.m, params.nu
    F = np.eye(n) + 0.1 * np.eye(n, k=1)
    H = np.zeros((m, n))
    for i in range(m):
        H[i, (i * n) // m] = 1.0
    Q = np.eye(n) * 0.01
    R = np.eye(m) * 0.2 + 0.05 * (1 - np.eye(m))
    A = rng.normal(size=(n, n)) * 0.2
    B = np.zeros((n, nu))
    for j in range(nu):
        B[n - 1 - j % n, j] = 0.1
    values = {"x": rng.normal(size=n), "P": np.eye(n) * 0.5 + A @ A.T, "F": F, "B": B, "Q": Q, "H": H, "R": R}
    if params.steady_gain:
        values["K"] = gain(F, H, Q, R)
    return values


def smoke_plan(params, manifest: dict) -> dict:
    """Load the model, then ``ITERATIONS`` iterations (z, u where the core has one, start),
    x and P (where the core keeps P) read after each."""
    s = Script(manifest, params, programs)
    rng = np.random.default_rng(1)
    values = system(params, rng)
    s.begin()
    for name in s.mems:
        if name in values and s.mems[name]["role"] != "output":
            s.put(name, values[name])
    truth = values["x"] + rng.normal(0, 0.3, params.n)
    for it in range(ITERATIONS):
        u = rng.normal(size=params.nu)
        truth = values["F"] @ truth + values["B"] @ u
        s.put("z", values["H"] @ truth + rng.normal(0, 0.3, params.m))
        if params.nu:
            s.put("u", u)
        s.step("iterate")
        for name in ("x", "P"):
            if name in s.mems:
                s.get(name)
        s.end_iteration(it)
    read = "x and P" if "P" in s.mems else "x (a steady-gain core keeps no P)"
    return s.plan(f"{ITERATIONS} iterations of a chain of integrators, {read} against the golden model")
