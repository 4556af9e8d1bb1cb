"""The paper's 50-run Monte Carlo through the generated core in Verilator (for the plots).

``python -m kfgen.sim.castella.mc BUILD_DIR`` generates a 64-track core with the default
parameters, streams all 50 runs of each scenario through it at once (one run per track,
interleaved in random order, with random input gaps and output backpressure), checks every
result word against the golden model, and writes ``BUILD_DIR/verilator_mc.npz`` with
``<scenario>_range`` and ``<scenario>_velocity`` code arrays (runs, steps) for
``python -m kfgen.sim.castella.plots --verilator``. The scenarios run side by side as tasks
on Dask distributed (:mod:`kfgen.sim.cluster`: ``--workers``, ``--scheduler``, ``--serial``).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

from kfgen.hdl.castella.params import CastellaParams

from kfgen.sim.cluster import add_arguments, open_runner

from . import model
from .plots import RUNS, SEED, monte_carlo
from .scenarios import SCENARIOS, interleave
from ..verilator import pack_fields
from .run import run_castella

TOP = "castella_mc"


def _scenario(rtl: Path, manifest: dict, name: str, runs: int, seed: int) -> dict:
    """One scenario's runs through the core, in its own build directory (scenarios run as
    tasks side by side)."""
    p = CastellaParams(tracks=64, name=TOP)
    codes = monte_carlo(p, name, runs, seed)["codes"]
    tids, ys, rs = interleave(codes, np.random.default_rng(seed), "random")
    rows, _ = model.expected_stream(p, tids, ys, rs)
    cols = {k: np.array([r[k] for r in rows]) for k in rows[0]}
    expected = {"tdata": pack_fields(manifest, "m_axis_tdata", cols),
                "tuser": pack_fields(manifest, "m_axis_tuser", cols), "tid": tids}
    res = run_castella(rtl, TOP, tids, ys, rs, expected=expected, gap=0.1, stall=0.1,
                       seed=seed, name=f"mc_{name}", build_dir=rtl / f"sim_build_{name}")
    # back from stream order to (run, step)
    rng_codes = np.zeros(codes.shape, dtype=np.int64)
    vel_codes = np.zeros(codes.shape, dtype=np.int64)
    for t in range(codes.shape[0]):
        sel = res["tid"] == t
        rng_codes[t], vel_codes[t] = res["range"][sel], res["velocity"][sel]
    return {f"{name}_range": rng_codes, f"{name}_velocity": vel_codes}


def run(build_dir: Path, runs: int = RUNS, seed: int = SEED, runner=None) -> dict:
    """Every scenario, each a task on ``runner`` (:mod:`kfgen.sim.cluster`; default: this
    process), into ``build_dir/verilator_mc.npz``."""
    build_dir = Path(build_dir)
    rtl = build_dir / TOP
    subprocess.run([str(Path(sys.executable).parent / "kfgen"), "castella", "--tracks", "64",
                    "--name", TOP, "-o", str(rtl)], check=True, capture_output=True)
    manifest = json.loads((rtl / f"{TOP}.json").read_text())
    with contextlib.ExitStack() as stack:
        if runner is None:
            runner = stack.enter_context(open_runner(argparse.Namespace(serial=True)))
        jobs = [runner.submit(_scenario, rtl, manifest, name, runs, seed, name=f"castella-mc-{name}")
                for name in SCENARIOS]
        out = {k: v for job in jobs for k, v in job.result().items()}
    np.savez(build_dir / "verilator_mc.npz", **out)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m kfgen.sim.castella.mc", description=__doc__.split("\n\n")[0])
    ap.add_argument("build_dir", type=Path)
    add_arguments(ap)
    args = ap.parse_args(argv)
    args.build_dir.mkdir(parents=True, exist_ok=True)
    with open_runner(args) as runner:
        run(args.build_dir, runner=runner)
    print(args.build_dir / "verilator_mc.npz")


if __name__ == "__main__":
    main()
