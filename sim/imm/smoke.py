"""The IMM core's smoke testbench (``TOP_tb.v``): the script of a session on the golden device
(:mod:`kfgen.sim.engine.script`) that the testbench replays on the RTL, every word read
compared with the golden model's."""

from __future__ import annotations

import numpy as np

from kfgen.hdl.imm.steps import programs
from kfgen.sim.engine.script import Script

from .golden import buffer_values
from .scenario import SEED, satlink

__all__ = ["ITERATIONS", "smoke_plan"]

#: Filter iterations the testbench runs.
ITERATIONS = 2


def _generic(params, rng) -> tuple[dict, np.ndarray]:
    """Models of any R, n, d that differ in their noise (a chain of integrators, H measuring
    every (n / d)-th state, a sticky transition matrix), and measurements of the first."""
    R, n, d = params.R, params.n, params.d
    F = np.eye(n) + 0.1 * np.eye(n, k=1)
    H = np.zeros((d, n))
    for i in range(d):
        H[i, (i * n) // d] = 1.0
    pi = np.full((R, R), 0.1 / max(R - 1, 1))
    np.fill_diagonal(pi, 0.9)
    Ps = [np.eye(n) * 0.5 + A @ A.T for A in (rng.normal(size=(n, n)) * 0.2 for _ in range(R))]
    values = {"pi": pi, "mu": np.full(R, 1.0 / R), "F": np.vstack([F] * R),
              "Q": np.vstack([np.eye(n) * 0.01 * 4.0 ** r for r in range(R)]), "H": np.vstack([H] * R),
              "R": np.vstack([np.eye(d) * 0.2 * 2.0 ** r + 0.05 * (1 - np.eye(d)) for r in range(R)]),
              "x_model": rng.normal(size=(R, n)), "P_model": np.vstack(Ps)}
    truth, zs = values["x_model"][0].copy(), []
    for _ in range(ITERATIONS):
        truth = F @ truth
        zs.append(H @ truth + rng.normal(0, 0.3, d))
    return values, np.array(zs)


def smoke_plan(params, manifest: dict) -> dict:
    """Load the models (the satellite-link scenario's where the core has its sizes), then
    ``ITERATIONS`` iterations (z, start), the model probabilities mu and the combined x and P
    read after each."""
    sc = satlink(ITERATIONS, SEED)
    if (len(sc.system.models), sc.system.n, sc.system.d) == (params.R, params.n, params.d):
        values, zs = buffer_values(sc.system, sc.mu0, sc.xs0, sc.Ps0), sc.zs
        about = "the satellite-link scenario"
    else:
        values, zs = _generic(params, np.random.default_rng(1))
        about = f"{params.R} models of a chain of integrators"
    s = Script(manifest, params, programs)
    s.begin()
    for name in s.mems:
        if name in values:
            s.put(name, values[name])
    for it, z in enumerate(zs[:ITERATIONS]):
        s.put("z", z)
        s.step("iterate")
        for name in ("mu", "x", "P"):
            s.get(name)
        s.end_iteration(it)
    return s.plan(f"{ITERATIONS} iterations of {about}, mu, x and P against the golden model")
