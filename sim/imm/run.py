"""Generate, build and run the IMM core under cocotb (:mod:`kfgen.sim.imm.tb`) on Verilator: the
satellite-link scenario through the RTL, for the figures and the long drift test."""

from __future__ import annotations

from pathlib import Path

__all__ = ["run_scenario"]

TB = "kfgen.sim.imm.tb"


def run_scenario(out_dir, steps: int, *, pes: int = 4, seed: int | None = None, cache_dir=None) -> dict:
    """Generate the default IMM core (the scenario's R = 5, n = 6, d = 2) with ``pes`` PEs in
    ``out_dir``, build it, run ``steps`` steps of the scenario with every word checked against
    the golden model (the testbench calm: no per-clock monitor, no random pauses; the bus
    cases and cycle counts are the regression's other runs); the trace (``mu`` T x R, ``x``
    T x n, ``xs`` T x R x n, ``P``, ``cycles``). The model is built for about 2000 cycles a
    step (an iteration and its bus transfers at P = 4: 1,721), optimised above 250 steps."""
    import numpy as np

    from kfgen.gen.synth import write_core
    from kfgen.hdl.imm.descriptor import CORE
    from kfgen.hdl.imm.params import ImmParams
    from kfgen.sim.ukf.run import build_ukf_core, run_ukf

    out_dir = Path(out_dir).resolve()
    top = f"imm_scenario_p{pes}"
    work, _ = write_core(CORE, ImmParams(pes=pes, name=top), out_dir)
    model = build_ukf_core(work, top, cache_dir or out_dir / "verilator", cycles=2000 * steps)
    npz = work / "scenario.npz"
    env = {"KFGEN_STEPS": str(steps), "KFGEN_IMM_OUT": str(npz), "KFGEN_TB_CALM": "1"}
    if seed is not None:
        env["KFGEN_SEED"] = str(seed)
    run_ukf(model, work, top, ["scenario"], "scenario", env=env, module=TB)
    with np.load(npz) as d:
        return {k: d[k] for k in d.files}
