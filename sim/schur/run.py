"""Run generated Schur-complement units side by side in one Verilator build under cocotb
(:mod:`kfgen.sim.schur.tb`), every result checked against the golden model."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from kfgen.hdl.arith.float.format import FloatFormat
from kfgen.hdl.schur.params import SchurParams
from kfgen.hdl.schur.program import schur_program

from ..fpu.run import fpu_group_wrapper
from ..verilator import build, run_test
from .model import golden_many

__all__ = ["expected", "run_schur_group"]


def _pack(words: list[int], width: int) -> int:
    return sum(w << (k * width) for k, w in enumerate(words))


def expected(params: SchurParams, matrices: list[list[int]]) -> tuple[list[int], list[int], list[int]]:
    """``(s_axis_tdata, m_axis_tdata, m_axis_tuser)`` words for ``matrices`` (upper-triangle
    words each), the results from :func:`~kfgen.sim.schur.model.golden`."""
    fmt: FloatFormat = params.fmt
    results, status = golden_many(schur_program(params.d), fmt, matrices)
    return ([_pack(m, fmt.width) for m in matrices], [_pack(r, fmt.width) for r in results],
            [s.word for s in status])


def run_schur_group(build_dir, cores: dict, *, calm: int = 50, gap: float = 0.3, stall: float = 0.3,
                    seed: int = 1, name: str = "schur", cache_dir=None, waves: bool = False,
                    test: str = "stream", env: dict | None = None) -> dict:
    """Simulate generated units in one Verilator build and check every result.

    ``cores`` maps an instance prefix to ``(rtl_dir, top, matrices)``, ``matrices`` a list of
    upper-triangle word lists; each core's parameters are read from its manifest. The first
    ``calm`` matrices go without idle cycles or backpressure, the rest with the probabilities
    ``gap`` and ``stall``. Raises ``AssertionError`` on any difference; returns per-prefix
    records (``tdata``, ``tuser``, ``in_cycle``, ``out_cycle``, ...). Files go to ``build_dir``,
    the Verilator build to ``cache_dir`` (default ``build_dir``). ``test`` names the testbench's
    case: ``stream`` (this run) or ``fault_campaign`` (``env``'s ``KFGEN_TB_SEQUENCES``
    sequences of random traffic and resets, each followed by this run checked; returns
    nothing).
    """
    build_dir = Path(build_dir).resolve()
    build_dir.mkdir(parents=True, exist_ok=True)
    manifests, sources, specs, cycles = {}, [], [], 0
    for k, (prefix, (rtl_dir, top, matrices)) in enumerate(cores.items()):
        rtl_dir = Path(rtl_dir).resolve()
        man = json.loads((rtl_dir / f"{top}.json").read_text())
        manifests[prefix] = man
        params = SchurParams(**man["parameters"])
        tdata, expect_tdata, expect_tuser = expected(params, matrices)
        stim = build_dir / f"{name}_{prefix}_stim.npz"
        np.savez(stim, tdata=np.asarray(tdata, dtype=object), expect_tdata=np.asarray(expect_tdata, dtype=object),
                 expect_tuser=np.asarray(expect_tuser), calm=calm, gap=gap, stall=stall, seed=seed + k)
        sources.append(rtl_dir / f"{top}.v")
        specs.append({"prefix": prefix, "manifest": str(rtl_dir / f"{top}.json"), "stim": str(stim),
                      "out": str(build_dir / f"{name}_{prefix}_out.npz")})
        cycles = max(cycles, int(len(matrices) * man["initiation_interval"] / ((1 - gap) * (1 - stall))))
    wrapper = build_dir / f"{name}_top.v"
    wrapper.write_text(fpu_group_wrapper(f"{name}_top", manifests))
    model = build(sources + [wrapper], f"{name}_top", cache_dir or build_dir, waves=waves, cycles=cycles)
    group = build_dir / f"{name}_group.json"
    group.write_text(json.dumps({"cores": specs}))
    run_test(model, "kfgen.sim.schur.tb", build_dir, name,
             {"KFGEN_TB_GROUP": str(group), "COCOTB_TEST_FILTER": rf"kfgen\.sim\.schur\.tb\.{test}\b", **(env or {})})
    if test != "stream":
        return {}
    return {s["prefix"]: dict(np.load(s["out"], allow_pickle=True)) for s in specs}
