"""Run generated floating-point units side by side in one Verilator build under cocotb
(:mod:`kfgen.sim.fpu.tb`), every result checked against the exact reference."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..verilator import build, run_test

__all__ = ["fpu_group_wrapper", "run_fpu_group"]


def fpu_group_wrapper(top: str, manifests: dict[str, dict]) -> str:
    """Verilog of a test top that instantiates generated units side by side.

    ``manifests`` maps an instance prefix to a unit's manifest; each port ``p`` of the unit
    becomes ``<prefix>_<p>`` of the wrapper (``clk`` and ``rst`` are shared).
    """
    ports, body = ["input wire clk", "input wire rst"], []
    for prefix, man in manifests.items():
        conns = [".clk(clk)", ".rst(rst)"]
        for p in man["ports"]:
            if p["name"] in ("clk", "rst"):
                continue
            rng = f"[{p['width'] - 1}:0] " if p["width"] > 1 else ""
            ports.append(f"{p['direction']} wire {rng}{prefix}_{p['name']}")
            conns.append(f".{p['name']}({prefix}_{p['name']})")
        body.append(f"  {man['top']} {prefix} ({', '.join(conns)});")
    return (f"// test wrapper written by kfgen.sim.fpu.run\nmodule {top} (\n  "
            + ",\n  ".join(ports) + "\n);\n" + "\n".join(body) + "\nendmodule\n")


def run_fpu_group(build_dir, units: dict, *, gap: float = 0.2, seed: int = 1, name: str = "group",
                  cache_dir=None, waves: bool = False) -> dict:
    """Simulate several generated units in one Verilator build and check every result.

    ``units`` maps an instance prefix to ``(rtl_dir, top, operands, expected)`` where
    ``operands`` is a dict of word lists ``a``/``b``/``c`` and ``expected`` a pair of lists
    ``(y, flags)``. Raises ``AssertionError`` on any difference; returns per-prefix results.
    The run's files go to ``build_dir``, the Verilator build to ``cache_dir`` (default
    ``build_dir``). ``waves`` writes ``build_dir/<name>.fst``.
    """
    build_dir = Path(build_dir).resolve()
    build_dir.mkdir(parents=True, exist_ok=True)
    manifests, sources, specs = {}, [], []
    for k, (prefix, (rtl_dir, top, operands, (y, flags))) in enumerate(units.items()):
        rtl_dir = Path(rtl_dir).resolve()
        manifests[prefix] = json.loads((rtl_dir / f"{top}.json").read_text())
        sources.append(rtl_dir / f"{top}.v")
        stim = build_dir / f"{name}_{prefix}_stim.npz"
        np.savez(stim, **{key: np.asarray(v, dtype=object) for key, v in operands.items()},
                 y=np.asarray(y, dtype=object), flags=np.asarray(flags), gap=gap, seed=seed + k)
        specs.append({"prefix": prefix, "manifest": str(rtl_dir / f"{top}.json"), "stim": str(stim),
                      "out": str(build_dir / f"{name}_{prefix}_out.npz")})
    wrapper = build_dir / f"{name}_top.v"
    wrapper.write_text(fpu_group_wrapper(f"{name}_top", manifests))
    # units run side by side; an iterative one takes an operation every initiation_interval
    cycles = max(len(y) * manifests[p]["initiation_interval"] for p, (_, _, _, (y, _)) in units.items())
    model = build(sources + [wrapper], f"{name}_top", cache_dir or build_dir, waves=waves,
                  cycles=int(cycles / (1 - gap)))
    group = build_dir / f"{name}_group.json"
    group.write_text(json.dumps({"units": specs}))
    run_test(model, "kfgen.sim.fpu.tb", build_dir, name, {"KFGEN_TB_GROUP": str(group)})
    return {s["prefix"]: dict(np.load(s["out"], allow_pickle=True)) for s in specs}
