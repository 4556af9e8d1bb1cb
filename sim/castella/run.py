"""Run a generated Castella core in Verilator under cocotb (:mod:`kfgen.sim.castella.tb`).

``run_castella`` is what the regression, the plots and the Monte Carlo run use: give it the
directory ``kfgen castella -o DIR`` wrote and a stream of measurements; it returns every
output word and the cycle of every handshake. Builds are cached by content
(:func:`kfgen.sim.verilator.build`), so runs of one configuration share one.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..verilator import build, pack_fields, run_test, unpack_fields

__all__ = ["run_castella"]


def run_castella(rtl_dir, top: str, tid, y, restart, *, expected: dict | None = None,
                 gap: float = 0.0, stall: float = 0.0, seed: int = 1, build_dir=None,
                 cache_dir=None, waves: bool = False, name: str = "run", test: str = "stream",
                 env: dict | None = None) -> dict:
    """Stream measurements through the core in Verilator and collect the results.

    ``expected`` (``tdata``, ``tid``, ``tuser`` word arrays) makes the testbench compare
    every result as it arrives; a difference fails the run (``AssertionError``).
    Returns the output words (``tdata``, ``tid``, ``tuser``), the decoded fields, and
    ``in_cycle``/``out_cycle`` of every handshake. The run's files go to ``build_dir``
    (default ``rtl_dir/sim_build``), the Verilator build to ``cache_dir`` (default
    ``build_dir``). ``waves`` writes ``build_dir/<name>.fst``. ``test`` names the testbench's
    case: ``stream`` (this run), or ``fault_campaign`` (``env``'s ``KFGEN_TB_SEQUENCES``
    sequences of random traffic and resets, each followed by this run checked; returns
    nothing).
    """
    rtl_dir = Path(rtl_dir).resolve()
    build_dir = Path(build_dir or rtl_dir / "sim_build").resolve()
    build_dir.mkdir(parents=True, exist_ok=True)
    manifest_path = rtl_dir / f"{top}.json"
    manifest = json.loads(manifest_path.read_text())
    # about how long the run takes (picks the build's optimisation): a track takes a measurement
    # every track_interval cycles, tracks interleave, gaps and stalls idle cycles
    per = max(1.0, manifest["track_interval_cycles"] / manifest["parameters"]["tracks"])
    cycles = int(len(y) * per / max(1e-3, (1 - gap) * (1 - stall)))
    model = build([rtl_dir / f"{top}.v"], top, cache_dir or build_dir, waves=waves, cycles=cycles)

    stim = build_dir / f"{name}_stim.npz"
    out = build_dir / f"{name}_out.npz"
    arrays = {
        "tid": np.asarray(tid, dtype=np.int64),
        "tdata": pack_fields(manifest, "s_axis_tdata", {"range": y}),
        "tuser": pack_fields(manifest, "s_axis_tuser", {"restart": np.asarray(restart, dtype=np.int64)}),
        "gap": gap, "stall": stall, "seed": seed,
    }
    for k, v in (expected or {}).items():
        arrays[f"expect_{k}"] = np.asarray(v, dtype=object)
    np.savez(stim, **arrays)
    if out.exists():
        out.unlink()
    run_test(model, "kfgen.sim.castella.tb", build_dir, name,
             {"KFGEN_TB_MANIFEST": str(manifest_path), "KFGEN_TB_STIM": str(stim), "KFGEN_TB_OUT": str(out),
              "COCOTB_TEST_FILTER": rf"kfgen\.sim\.castella\.tb\.{test}\b", **(env or {})})
    if test != "stream":
        return {}
    res = dict(np.load(out, allow_pickle=True))
    res.update(unpack_fields(manifest, "m_axis_tdata", res["tdata"]))
    res.update(unpack_fields(manifest, "m_axis_tuser", res["tuser"]))
    return res
