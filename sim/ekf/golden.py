"""The EKF core's bit-exact golden model: the core's own program
(:mod:`kfgen.hdl.ekf.programs`) executed word by word by :func:`kfgen.sim.linalg.exec.run`,
the buffer loaded as software loads the core's; and a linearised function
(:class:`kfgen.hdl.ekf.jacobian.Linearised`) evaluated alone, its values and Jacobians read
back, to check the differentiation itself."""

from __future__ import annotations

import numpy as np

from kfgen.hdl.arith.float.format import FloatFormat
from kfgen.hdl.linalg.matrix import const
from kfgen.hdl.linalg.program import Layout, Program
from kfgen.sim.linalg.exec import from_words, run, to_words

__all__ = ["evaluate", "run_golden"]


def _io(lay, fmt, mem):
    def put(name, values):
        r = lay[name]
        mem[r.base:r.base + r.size] = to_words(fmt, np.ravel(values))

    def get(name):
        r = lay[name]
        return np.array(from_words(fmt, mem[r.base:r.base + r.size])).reshape(r.rows, r.cols)
    return put, get


def _read(fmt, mem, rows, cols, view) -> np.ndarray:
    """A matrix read through a view (``None``: a structural zero)."""
    out = np.zeros((rows, cols))
    for i in range(rows):
        for j in range(cols):
            a = view(i, j)
            if a is not None:
                out[i, j] = from_words(fmt, [mem[a]])[0]
    return out


def evaluate(lin, inputs: dict, fmt="binary64") -> tuple[np.ndarray, dict]:
    """``lin``'s values and Jacobians (name -> matrix) at ``inputs`` (input name -> values; the
    inputs it was linearised at 0 are not read), through the golden executor in ``fmt``."""
    fmt = FloatFormat.parse(fmt)
    model = lin.model
    lay = Layout()
    regions = {name: lay.add(f"in_{name}", max(1, len(v))) for name, v in inputs.items()}
    out = lay.add("out", max(1, model.outputs))
    temps = lay.add("temps", max(1, model.temps))
    words = list(dict.fromkeys(model.consts + [w[1] for j in lin.jacobians.values()
                                               for w in j.entries.values() if w[0] == "const"]))
    cw = const(lay, fmt, "consts", words) if words else None

    def addr(w):
        if w[0] == "const":
            return cw(0, words.index(w[1]))
        if w[0] == "out":
            return out(w[1])
        if w[0] == "tmp":
            return temps(w[1])
        return regions[w[1]](w[2])
    prog = Program("evaluate", lay, fmt)
    for op in model.program_ops(addr, shared_done=False):
        prog.emit(op)
    mem = lay.initial_memory()
    put, get = _io(lay, fmt, mem)
    for name, v in inputs.items():
        if len(v):
            put(f"in_{name}", v)
    run(prog, mem)
    jacs = {j.name: _read(fmt, mem, j.rows, j.cols, lambda i, k, j=j: None if j.word(i, k) is None
                          else addr(j.word(i, k))) for j in lin.jacobians.values()}
    return get("out").ravel()[:model.outputs], jacs


def run_golden(progs, x0, P0, Q, R, us, zs) -> dict:
    """The golden model over the iterations' control inputs ``us`` (K, nu) and measurements
    ``zs`` (K, m) from ``x0``, ``P0`` with the noise covariances ``Q``, ``R``: ``x`` (K, n),
    ``P`` (K, n, n) as the core's buffer holds them after each iteration, ``x_prior``,
    ``P_prior`` (the predictions), ``H`` (the Jacobian the update used: its words read
    only ``x_pred``, which the update leaves alone; F's may read ``x``, which it overwrites:
    :func:`evaluate` checks F) and ``flags`` (K,) of its status (1 pivot, 2 NaN)."""
    lay, fmt = progs.layout, progs.fmt
    n, _, _, m, nu = progs.params.sizes
    mem = lay.initial_memory()
    put, get = _io(lay, fmt, mem)
    for name, v in (("x", x0), ("P", P0), ("Q", Q), ("R", R)):
        put(name, v)
    out = {k: [] for k in ("x", "P", "x_prior", "P_prior", "H", "flags")}
    for u, z in zip(us, zs):
        if nu:
            put("u", u)
        put("z", z)
        st = run(progs.iteration, mem)
        out["flags"].append(int(st.pivot) | 2 * int(st.nan))
        out["x"].append(get("x").ravel())
        out["P"].append(get("P"))
        out["x_prior"].append(get("x_pred").ravel())
        out["P_prior"].append(get("P_pred"))
        out["H"].append(_read(fmt, mem, m, n, progs.jacobians["H"]))
    return {k: np.array(v) for k, v in out.items()}
