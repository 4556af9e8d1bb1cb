"""The paper's 50-run Monte Carlo through the generated core in Verilator (for the plots).

``python -m kfgen.sim.castella.mc BUILD_DIR`` generates a 64-track core with the default
parameters, streams all 50 runs of each scenario through it at once (one run per track,
interleaved in random order, with random input gaps and output backpressure), checks every
result word against the golden model, and writes ``BUILD_DIR/verilator_mc.npz`` with
``<scenario>_range`` and ``<scenario>_velocity`` code arrays (runs, steps) for
``python -m kfgen.sim.castella.plots --verilator``.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import numpy as np

from kfgen.hdl.castella.params import CastellaParams

from . import model
from .plots import RUNS, SEED, monte_carlo
from .scenarios import SCENARIOS, interleave
from ..verilator import pack_fields
from .run import run_castella

TOP = "castella_mc"


def run(build_dir: Path, runs: int = RUNS, seed: int = SEED) -> dict:
    build_dir = Path(build_dir)
    p = CastellaParams(tracks=64, name=TOP)
    rtl = build_dir / TOP
    subprocess.run([str(Path(sys.executable).parent / "kfgen"), "castella", "--tracks", "64",
                    "--name", TOP, "-o", str(rtl)], check=True, capture_output=True)
    import json
    manifest = json.loads((rtl / f"{TOP}.json").read_text())
    out = {}
    for name in SCENARIOS:
        codes = monte_carlo(p, name, runs, seed)["codes"]
        tids, ys, rs = interleave(codes, np.random.default_rng(seed), "random")
        rows, _ = model.expected_stream(p, tids, ys, rs)
        cols = {k: np.array([r[k] for r in rows]) for k in rows[0]}
        expected = {"tdata": pack_fields(manifest, "m_axis_tdata", cols),
                    "tuser": pack_fields(manifest, "m_axis_tuser", cols), "tid": tids}
        res = run_castella(rtl, TOP, tids, ys, rs, expected=expected, gap=0.1, stall=0.1,
                           seed=seed, name=f"mc_{name}")
        # back from stream order to (run, step)
        rng_codes = np.zeros(codes.shape, dtype=np.int64)
        vel_codes = np.zeros(codes.shape, dtype=np.int64)
        for t in range(codes.shape[0]):
            sel = res["tid"] == t
            rng_codes[t], vel_codes[t] = res["range"][sel], res["velocity"][sel]
        out[f"{name}_range"], out[f"{name}_velocity"] = rng_codes, vel_codes
    np.savez(build_dir / "verilator_mc.npz", **out)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m kfgen.sim.castella.mc", description=__doc__.split("\n\n")[0])
    ap.add_argument("build_dir", type=Path)
    args = ap.parse_args(argv)
    args.build_dir.mkdir(parents=True, exist_ok=True)
    run(args.build_dir)
    print(args.build_dir / "verilator_mc.npz")


if __name__ == "__main__":
    main()
