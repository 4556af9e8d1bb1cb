"""Run a generated EKF core (``kfgen ekf``) on Verilator: its testbench's ``iterations``
(:mod:`kfgen.sim.ekf.tb`) over the application's scenario, every word checked against the
golden model, the estimates kept. Generating the core and running it in one command is gen's
(``python -m kfgen.gen.cosim ekf``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..engine.run import run_tb
from ..verilator import Build

__all__ = ["TB", "run_iterations"]

#: The EKF's cocotb testbench (:func:`kfgen.sim.engine.run.run_tb`'s ``module``).
TB = "kfgen.sim.ekf.tb"


def run_iterations(model: Build, rtl_dir, top: str, steps: int, *, seed: int = 1, app_dir=None,
                   name: str = "cosim") -> dict:
    """``steps`` iterations of the application's scenario (seed ``seed``) on a build of the
    core generated into ``rtl_dir`` (the testbench calm: no per-clock monitor, no random
    pauses), its application found from ``app_dir`` (for a file's spec); ``x`` (K, n), ``P``
    (K, n, n) read back and ``flags`` (K,) of each iteration's status (1 err_pivot, 2 err_nan),
    from the iteration on which a fault is raised the words still equal to the golden model's.

    Raises
    ------
    AssertionError
        A word unlike the golden model's, or a build or run that fails (the log's tail).
    """
    rtl_dir = Path(rtl_dir).resolve()
    npz = rtl_dir / f"{name}.npz"
    npz.unlink(missing_ok=True)  # a run that fails leaves none
    env = {"KFGEN_TB_CALM": "1", "KFGEN_TB_ITERATIONS": str(steps), "KFGEN_TB_SEED": str(seed),
           "KFGEN_EKF_OUT": str(npz)}
    if app_dir is not None:
        env["KFGEN_APP_DIR"] = str(Path(app_dir).resolve())
    run_tb(model, rtl_dir, top, TB, ["iterations"], name, env)
    with np.load(npz) as d:
        return {k: d[k] for k in ("x", "P", "flags")}
