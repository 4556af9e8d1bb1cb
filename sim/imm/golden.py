"""The IMM core's bit-exact golden model over a scenario: the core's own program
(:mod:`kfgen.hdl.imm.programs`) executed word by word by :func:`kfgen.sim.linalg.exec.run`,
the buffer loaded as software loads the core's."""

from __future__ import annotations

import numpy as np

from kfgen.hdl.imm.programs import ImmSizes, build_imm
from kfgen.sim.linalg.exec import from_words, run, to_words

__all__ = ["buffer_values", "run_golden"]


def buffer_values(system, mu0, xs0, Ps0) -> dict:
    """The regions software writes before the first iteration, by name, from an
    :class:`~kfgen.sim.imm.reference.ImmSystem` and the initial estimates."""
    return {"pi": system.pi, "mu": mu0,
            "F": np.vstack([m.F for m in system.models]), "Q": np.vstack([m.Q for m in system.models]),
            "H": np.vstack([m.H for m in system.models]), "R": np.vstack([m.R for m in system.models]),
            "x_model": np.asarray(xs0), "P_model": np.vstack(list(Ps0))}


def run_golden(system, mu0, xs0, Ps0, zs, fmt: str = "binary32") -> dict:
    """The golden model over the measurements ``zs`` (T, d): ``mu`` (T, R), ``x`` (T, n),
    ``xs`` (T, R, n), ``P`` (T, n, n) as the core's buffer holds them after each iteration,
    and ``flags`` (T,) of its status (1 pivot, 2 NaN)."""
    progs = build_imm(ImmSizes(system.R, system.n, system.d), fmt)
    lay, f = progs.layout, progs.fmt
    mem = lay.initial_memory()

    def put(name, values):
        r = lay[name]
        mem[r.base:r.base + r.size] = to_words(f, np.ravel(values))

    def get(name):
        r = lay[name]
        return np.array(from_words(f, mem[r.base:r.base + r.size])).reshape(r.rows, r.cols)

    for name, values in buffer_values(system, mu0, xs0, Ps0).items():
        put(name, values)
    out = {k: [] for k in ("mu", "x", "xs", "P", "flags")}
    for z in zs:
        put("z", z)
        st = run(progs.iterate, mem)
        out["flags"].append(int(st.pivot) | 2 * int(st.nan))
        out["mu"].append(get("mu").ravel())
        out["x"].append(get("x").ravel())
        out["xs"].append(get("x_model"))
        out["P"].append(get("P"))
    return {k: np.array(v) for k, v in out.items()}
