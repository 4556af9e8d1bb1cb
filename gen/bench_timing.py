"""``--target-mhz`` against nextpnr: ``python -m kfgen.gen.bench_timing``.

For each target clock (default 75, 100, 125 and 150 MHz) every binary32 unit with stage
choices (add, sub, mul, div, sqrt, fma, i2f, f2i, exp) and the UKF core at P = 1 are
generated with ``--target-mhz``, placed and routed on the ECP5-85 at that clock (nextpnr
``--freq`` = the target, the median of the seeds), and the measured Fmax is set beside the
target and the model's prediction: the model holds when the measured Fmax is within 10 % of
the target or above it. Configurations two targets share (the same stages) are measured
once. From every unit's points the calibration of :data:`kfgen.hdl.arith.float.timing.CALIBRATION`
is fitted again and printed (``--calibrate`` prints only that, from the default stages).
``make bench`` runs this as part of the FPU bench; the jobs run on Dask
(:mod:`kfgen.sim.cluster`).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

from kfgen.hdl.arith.float.descriptor import CORE as FPU
from kfgen.hdl.arith.float.params import FpuParams, _unit_args, _unit_class, check_target, unit_timing
from kfgen.hdl.describe import ParamError
from kfgen.hdl.ukf.descriptor import CORE as UKF
from kfgen.hdl.ukf.params import UkfParams
from kfgen.hdl.arith.float.timing import CALIBRATION, MEASURED_MHZ
from kfgen.sim.cluster import add_arguments, collect, failed, open_runner

from .synth import ecp5_fmax, md_table, short_path, write_core

__all__ = ["OPS", "TARGETS", "main", "fit", "verdict"]

#: The binary32 units ``--target-mhz`` pipelines (sin, cos and atan2 have one pipeline).
OPS = ("add", "sub", "mul", "div", "sqrt", "fma", "i2f", "f2i", "exp")
TARGETS = (75.0, 100.0, 125.0, 150.0)
#: The model holds for a target when the measured Fmax is at least this share of it.
HOLDS = 0.9


def verdict(target: float, measured: float | None) -> str:
    """``yes`` when ``measured`` is within 10 % of ``target`` or above, else ``no``."""
    if measured is None:
        return "-"
    return "yes" if measured >= HOLDS * target else "no"


def fit(points: list[dict]) -> dict:
    """``CALIBRATION`` from measured points (``op``, ``model_ns``, ``fmax_mhz``): per op the
    median of measured period over model delay; ``other``, the median of the ops'."""
    by_op: dict[str, list[float]] = {}
    for p in points:
        if p.get("fmax_mhz"):
            by_op.setdefault(p["op"], []).append(1000.0 / p["fmax_mhz"] / p["model_ns"])
    scales = {op: round(statistics.median(v), 2) for op, v in by_op.items()}
    if scales:
        scales["other"] = round(statistics.median(scales.values()), 2)
    return scales


def _model_ns(op: str, stages: int) -> float:
    return _unit_class(op).stage_delays("binary32", **_unit_args(op, "ieee", None, 1))[stages]


def _engine_rows(targets, out: Path) -> tuple[list[dict], dict]:
    """The UKF core at P = 1 for each target: its rows, and the cores to measure, one per
    distinct choice of the units' stages (``key`` of the rows)."""
    rows, cores = [], {}
    for t in targets:
        params = UkfParams(target_mhz=t, name=f"ukf_p1_t{t:g}")
        work, manifest = write_core(UKF, params, out)
        tm = manifest["timing"]
        key = ", ".join([f"{k} {u['stages']}" for k, u in tm["units"].items()]
                        + (["fetch register"] if tm["fetch_register"] else []))
        rows.append({"op": "ukf P=1", "target": t, "stages": key, "predicted": tm["predicted_fmax_mhz"]})
        if key not in cores:
            cores[key] = {"work": work, "top": params.name, "target": t,
                          "cycles": sum(manifest["cycles"][k] for k in ("sig_gen", "predict", "update"))}
    return rows, cores


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m kfgen.gen.bench_timing", description=__doc__.split("\n\n")[0])
    ap.add_argument("--targets", type=float, nargs="+", default=list(TARGETS), help="clocks in MHz (default 75 100 125 150)")
    ap.add_argument("--ops", nargs="+", choices=OPS, default=list(OPS), help="binary32 units (default all nine)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3], help="nextpnr seeds of the units (default 1 2 3)")
    ap.add_argument("--engine-seeds", type=int, nargs="+", default=[1],
                    help="nextpnr seeds of the UKF core (default 1: 3 minutes a seed)")
    ap.add_argument("--no-engine", action="store_true", help="skip the UKF core")
    ap.add_argument("--calibrate", action="store_true",
                    help="only the units' default stages, and print the fitted CALIBRATION")
    ap.add_argument("-o", "--out", default="build/bench_timing", help="work directory (default build/bench_timing)")
    add_arguments(ap)
    args = ap.parse_args(argv)
    try:
        for t in args.targets:
            check_target(t)
    except ParamError as exc:
        print(f"bench_timing: --targets: {exc.message}", file=sys.stderr)
        return 2
    out = Path(args.out).resolve()
    start = time.monotonic()
    targets = [None] if args.calibrate else args.targets
    rows, measured = [], {}
    with open_runner(args) as runner:
        jobs = []
        for op in args.ops:
            for t in targets:
                params = FpuParams(op=op, target_mhz=t)
                stages = params.stages
                _, predicted = unit_timing(op, "binary32", stages=stages)
                row = {"op": op, "target": t, "stages": stages, "predicted": predicted, "model_ns": _model_ns(op, stages)}
                rows.append(row)
                key = (op, stages)
                if key not in measured:
                    measured[key] = {"op": op, "stages": stages, "model_ns": row["model_ns"]}
                    name = f"fpu_{op}_s{stages}"
                    work, _ = write_core(FPU, FpuParams(op=op, stages=stages, name=name), out)
                    # nextpnr aims at the target (the default's at 125, as bench_fpu)
                    jobs.append((measured[key], "ecp5", ecp5_fmax(work, name, t or 125.0, tuple(args.seeds),
                                                                  runner=runner)))
        engine, cores = ([], {}) if args.no_engine or args.calibrate else _engine_rows(targets, out / "engine")
        jobs += [(c, "ecp5", ecp5_fmax(c["work"], c["top"], c["target"], tuple(args.engine_seeds), runner=runner))
                 for c in cores.values()]
        collect(jobs, label=lambda r: f"{r.get('op', r.get('top'))} {r.get('stages', '')}", tool="bench_timing")
    for r in rows:  # configurations two targets share were measured once
        r.update({k: v for k, v in measured[(r["op"], r["stages"])].items() if k not in r})
    for r in engine:
        r.update({k: v for k, v in cores[r["stages"]].items() if k not in r})
    calibration = fit(list(measured.values()))
    report = _render(rows, engine, calibration, args, time.monotonic() - start)
    print(report, end="")
    out.mkdir(parents=True, exist_ok=True)
    (out / "bench_timing.md").write_text(report)
    (out / "bench_timing.json").write_text(json.dumps({"rows": rows, "engine": engine, "calibration": calibration},
                                                      indent=2, sort_keys=True, default=str) + "\n")
    return 1 if failed(rows + engine) else 0


def _render(rows, engine, calibration, args, seconds) -> str:
    head = ["unit", "target (MHz)", "stages", "predicted (MHz)", "measured Fmax (MHz)", "within 10 % or above"]
    lines = [[r["op"], "default" if r["target"] is None else f"{r['target']:g}", str(r["stages"]),
              f"{r['predicted']:.1f}", f"{r['fmax_mhz']:.1f}" if r.get("fmax_mhz") else f"error: {r.get('ecp5_error', '-')}",
              "-" if r["target"] is None else verdict(r["target"], r.get("fmax_mhz"))] for r in rows]
    lines += [[r["op"], f"{r['target']:g}", r["stages"], f"{r['predicted']:.1f}",
               f"{r['fmax_mhz']:.1f}" if r.get("fmax_mhz") else f"error: {r.get('ecp5_error', '-')}",
               verdict(r["target"], r.get("fmax_mhz"))] for r in engine]
    held = [r for r in rows + engine if r["target"] is not None and r.get("fmax_mhz")]
    ok = sum(verdict(r["target"], r["fmax_mhz"]) == "yes" for r in held)
    notes = [
        "",
        f"* The model holds (measured within 10 % of the target or above) for {ok} of {len(held)} target rows.",
        *(f"* Critical path, {r['op']} at {r['stages']} stages: {short_path(r['critical_path'])}."
          for r in {(x["op"], x["stages"]): x for x in rows + engine if "critical_path" in x}.values()),
        f"* Fitted again from these points: CALIBRATION = {calibration} (in use: {CALIBRATION}).",
        f"* sin, cos and atan2 take no target: one pipeline each, measured {MEASURED_MHZ} MHz.",
        f"* ECP5: LFE5U-85F CABGA381, nextpnr --freq = the target (125 for the defaults), seeds "
        f"{' '.join(map(str, args.seeds))} (the UKF core {' '.join(map(str, args.engine_seeds))}), median.",
        f"* Work files in {args.out}/ ({seconds:.0f} s).",
    ]
    return md_table(head, lines) + "\n" + "\n".join(notes) + "\n"


if __name__ == "__main__":
    sys.exit(main())
