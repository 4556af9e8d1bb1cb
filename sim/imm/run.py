"""Run a generated IMM core (``kfgen imm``) under cocotb (:mod:`kfgen.sim.imm.tb`) on Verilator: the
satellite-link scenario through the RTL, for the figures and the long drift test. Generating the
core and running it in one call is gen's (:func:`kfgen.gen.cosim.imm_scenario`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..engine.run import build_core, run_tb

__all__ = ["TB", "run_scenario"]

#: The IMM's cocotb testbench (:func:`kfgen.sim.engine.run.run_tb`'s ``module``).
TB = "kfgen.sim.imm.tb"


def run_scenario(rtl_dir, top: str, steps: int, *, seed: int | None = None, cache_dir=None) -> dict:
    """Build the IMM core generated into ``rtl_dir`` (the scenario's R = 5, n = 6, d = 2: the
    default sizes), run ``steps`` steps of the scenario with every word checked against the
    golden model (the testbench calm: no per-clock monitor, no random pauses; the bus cases and
    cycle counts are the regression's other runs); the trace (``mu`` T x R, ``x`` T x n, ``xs``
    T x R x n, ``P``, ``cycles``). The model is built for about 2000 cycles a step (an iteration
    and its bus transfers at P = 4: 1,721), optimised above 250 steps, in ``cache_dir``
    (default ``rtl_dir/verilator``)."""
    rtl_dir = Path(rtl_dir).resolve()
    model = build_core(rtl_dir, top, cache_dir or rtl_dir / "verilator", cycles=2000 * steps)
    npz = rtl_dir / "scenario.npz"
    env = {"KFGEN_STEPS": str(steps), "KFGEN_IMM_OUT": str(npz), "KFGEN_TB_CALM": "1"}
    if seed is not None:
        env["KFGEN_SEED"] = str(seed)
    run_tb(model, rtl_dir, top, TB, ["scenario"], "scenario", env=env)
    with np.load(npz) as d:
        return {k: d[k] for k in d.files}
