"""Choosing a filter (docs/choosing.md): one application as every core that runs it, side by
side: the linear Kalman filter (``kfgen kf``, where the model is linear), the EKF (``kfgen ekf``)
and the UKF with f and h on chip in its LDLᵀ and square-root forms (``kfgen ukf --on-chip
[--form sqrt]``).

    python -m kfgen.gen.bench_filters [--apps cv,tracker] [--pes 1] [--seeds 100] [--steps 200]
        [--pnr-seeds 1,2,3] [--freq 125] [--no-synth | --no-pnr] [-o build/bench_filters]
        [--workers N | --scheduler ADDRESS | --serial]

Per application and filter: the cycles of one iteration (the schedules', what the manifests'
``cycles`` give), Yosys ``synth_xilinx`` LUT, FF, DSP48E1 and 36 Kb BRAM, the ECP5-85 Fmax after
nextpnr-ecp5 (median of the placer seeds), an iteration's microseconds at that Fmax, and the
accuracy: position RMS (m) over 200 iterations, mean and worst over the seeds, of the bit-exact
binary32 golden model of each core and of each filter's float64 reference (the KF's,
:mod:`kfgen.sim.kf.reference`; the EKF's with finite-difference Jacobians; the augmented and
square-root UKFs). Every generation, synthesis, placer seed and block of seeds is a task on
Dask distributed (:mod:`kfgen.sim.cluster`).

* ``cv``: :class:`kfgen.sim.ukf.apps.tracker.PositionTracker`, a constant-velocity target whose
  position is measured (linear: the KF's F, H, Q, R from its ``linear_model``);
* ``tracker``: :class:`kfgen.sim.ukf.apps.tracker.Tracker`, the same target seen in range and
  bearing (nonlinear: no KF).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from kfgen.hdl.ekf.params import EkfParams
from kfgen.hdl.ekf.steps import programs as ekf_programs
from kfgen.hdl.ekf.steps import schedules as ekf_schedules
from kfgen.hdl.engine.app import load_app
from kfgen.hdl.kf.params import KfParams
from kfgen.hdl.kf.steps import programs as kf_programs
from kfgen.hdl.kf.steps import schedules as kf_schedules
from kfgen.hdl.linalg.engine import OVERHEAD
from kfgen.hdl.ukf.params import UkfParams
from kfgen.hdl.ukf.steps import programs as ukf_programs
from kfgen.hdl.ukf.steps import schedules as ukf_schedules
from kfgen.sim.cluster import _usage, add_arguments, open_runner
from kfgen.sim.ekf.reference import run_reference as ekf_reference
from kfgen.sim.kf.reference import run_reference as kf_reference
from kfgen.sim.linalg.exec import to_words
from kfgen.sim.ukf.accuracy import run_reference as ukf_reference
from kfgen.sim.ukf.software import initial_words

from .bench_ekf import _batch, _error
from .cores import discover
from .synth import ecp5_fmax, write_cores, xilinx_task

__all__ = ["APPS", "FILTERS", "filter_params", "cycles", "accuracy_block", "main"]

#: The applications: name -> (spec, linear: a KF runs it).
APPS = {"cv": ("tracker:PositionTracker", True), "tracker": ("tracker:Tracker", False)}
#: The filters, in the table's order: name -> (core, label).
FILTERS = {"kf": ("kf", "KF"), "ekf": ("ekf", "EKF"), "ukf_ldl": ("ukf", "UKF ldl"), "ukf_sqrt": ("ukf", "UKF sqrt")}
#: Seeds per accuracy task.
BLOCK = 25


def filters_of(app_name: str) -> list[str]:
    """The filters that run application ``app_name`` (the KF only where it is linear)."""
    return [f for f in FILTERS if f != "kf" or APPS[app_name][1]]


def filter_params(app_name: str, filt: str, pes: int = 1):
    """The core parameters of filter ``filt`` for application ``app_name`` at P = ``pes``
    (binary32), named ``<filter>_<app>``."""
    spec, _ = APPS[app_name]
    app = load_app(spec)
    name = f"{filt}_{app_name}_p{pes}"
    if filt == "kf":
        return KfParams(states=app.n, measurements=app.m, pes=pes, name=name)
    if filt == "ekf":
        return EkfParams(spec, pes=pes, name=name)
    return UkfParams(**app.core_parameters(), app=spec, on_chip=True, form=filt.split("_")[1], pes=pes, name=name)


def cycles(params) -> tuple[int, int]:
    """(cycles of one iteration, its multiply-adds) of a core's parameters."""
    if isinstance(params, KfParams):
        return kf_schedules(params)["iterate"].cycles + OVERHEAD, kf_programs(params).steps["iterate"].fma_count
    if isinstance(params, EkfParams):
        return ekf_schedules(params)["iterate"].cycles + OVERHEAD, ekf_programs(params).iteration.fma_count
    return ukf_schedules(params)["iteration"].cycles + OVERHEAD, ukf_programs(params).steps["iteration"].fma_count


def accuracy_block(app_name: str, first_seed: int, seeds: int, steps: int) -> dict:
    """Seeds ``first_seed ..`` of application ``app_name``, ``steps`` iterations each: per
    filter the position RMS (m) of each seed of its binary32 core (``<filter>_b32``; NaN for
    a seed whose core faulted) and its float64 reference (``<filter>_f64``), and each core's
    faulted seeds (``<filter>_faults``)."""
    spec, linear = APPS[app_name]
    app = load_app(spec)
    scenarios = [app.scenario(steps, s) for s in range(first_seed, first_seed + seeds)]
    out = {"seeds": seeds}
    cores = {}
    if linear:
        lm = app.linear_model()
        progs = kf_programs(filter_params(app_name, "kf"))
        values = {"x": app.x0, "P": app.P0, **lm}
        cores["kf"] = (progs, "iterate", None, {k: to_words(progs.fmt, np.ravel(v)) for k, v in values.items()})
    progs = ekf_programs(filter_params(app_name, "ekf"))
    cores["ekf"] = (progs, "iterate", None, {k: to_words(progs.fmt, np.ravel(v)) for k, v in
                                             (("x", app.x0), ("P", app.P0), ("Q", app.Q), ("R", app.R))})
    for form in ("ldl", "sqrt"):
        progs = ukf_programs(filter_params(app_name, f"ukf_{form}"))
        pre = progs.prologue[0] if progs.prologue else None
        cores[f"ukf_{form}"] = (progs, "iteration", pre, initial_words(app, progs.fmt, form))
    for key, (progs, main, pre, initial) in cores.items():
        est, fault = _batch(progs, main, pre, app, scenarios, initial)
        out[f"{key}_b32"] = [np.nan if f >= 0 else _error(app_name, app, e, sc.truth)
                             for e, f, sc in zip(est, fault, scenarios)]
        out[f"{key}_faults"] = int(np.sum(fault >= 0))
    for key in cores:
        out[f"{key}_f64"] = []
    for sc in scenarios:
        us = np.zeros((steps, 0)) if sc.u is None else sc.u
        if linear:
            run = kf_reference(lm["F"], lm["H"], lm["Q"], lm["R"], app.x0, app.P0, sc.z)
            out["kf_f64"].append(_error(app_name, app, run.x_post, sc.truth))
        out["ekf_f64"].append(_error(app_name, app, ekf_reference(app, us, sc.z)["x"], sc.truth))
        for form in ("ldl", "sqrt"):
            out[f"ukf_{form}_f64"].append(_error(app_name, app, ukf_reference(app, sc, form), sc.truth))
    return out


def accuracy(runner, apps, seeds: int, steps: int) -> dict:
    """Application -> the blocks of :func:`accuracy_block` over seeds 0 .. ``seeds`` - 1 joined
    (lists of per-seed figures, fault counts summed), each block a task of ``runner``."""
    jobs = {(name, s): runner.submit(accuracy_block, name, s, min(BLOCK, seeds - s), steps,
                                     name=f"filters_acc_{name}")
            for name in apps for s in range(0, seeds, BLOCK)}
    out = {}
    for (name, _), job in jobs.items():
        acc = out.setdefault(name, {})
        for k, v in job.result().items():
            acc[k] = acc.get(k, 0 if not isinstance(v, list) else []) + v
    return out


def _parse_ints(text: str, what: str, low: int, high: int) -> list[int]:
    try:
        values = [int(v) for v in text.split(",")]
    except ValueError:
        values = []
    if not values or any(not low <= v <= high for v in values):
        _usage(f"{what} must be integers from {low} to {high} separated by commas, not {text!r}")
    return values


def _parse_int(text: str, what: str, low: int, high: int) -> int:
    try:
        value = int(text)
    except ValueError:
        value = None
    if value is None or not low <= value <= high:
        _usage(f"{what} must be an integer from {low} to {high}, not {text!r}")
    return value


def _parse(argv):
    ap = argparse.ArgumentParser(prog="python -m kfgen.gen.bench_filters", description=__doc__.split("\n\n")[0])
    ap.add_argument("--apps", default="cv,tracker", help="applications: cv, tracker (default cv,tracker)")
    ap.add_argument("--pes", default="1", help="processing elements of every core (default 1)")
    ap.add_argument("--seeds", default="100", help="seeds of the accuracy run (default 100; 0: none)")
    ap.add_argument("--steps", default="200", help="iterations of each seed's run (default 200)")
    ap.add_argument("--pnr-seeds", default="1,2,3", help="nextpnr placer seeds, the median reported (default 1,2,3)")
    ap.add_argument("--freq", default="125", help="nextpnr's target clock, MHz (default 125)")
    ap.add_argument("--no-synth", action="store_true", help="no synthesis, no place and route (seconds)")
    ap.add_argument("--no-pnr", action="store_true", help="Xilinx resources, no ECP5 place and route")
    ap.add_argument("-o", "--out", default="build/bench_filters", help="work directory (default build/bench_filters)")
    add_arguments(ap)
    args = ap.parse_args(argv)
    args.apps = args.apps.split(",")
    bad = [a for a in args.apps if a not in APPS]
    if bad or not args.apps:
        _usage(f"--apps must be names from {', '.join(APPS)} separated by commas, not {','.join(args.apps)!r}")
    args.pes = _parse_ints(args.pes, "--pes", 1, 16)
    args.seeds = _parse_int(args.seeds, "--seeds", 0, 100_000)
    args.steps = _parse_int(args.steps, "--steps", 1, 100_000)
    args.pnr_seeds = _parse_ints(args.pnr_seeds, "--pnr-seeds", 1, 1_000_000)
    try:
        args.freq = float(args.freq)
    except ValueError:
        args.freq = -1.0
    if not 1 <= args.freq <= 1000:
        _usage(f"--freq must be a clock from 1 to 1000 MHz, not {args.freq!r}")
    if args.no_synth and args.no_pnr:
        _usage("--no-synth and --no-pnr: give one (--no-synth leaves out both syntheses)")
    return args


def _fmt(v, digits=1):
    return "-" if v is None else f"{v:,.{digits}f}"


def main(argv=None) -> int:
    args = _parse(sys.argv[1:] if argv is None else argv)
    rows = [(app, filt, p, filter_params(app, filt, p)) for app in args.apps for p in args.pes
            for filt in filters_of(app)]
    out = Path(args.out)
    with open_runner(args) as runner:
        synth = {}
        if not args.no_synth:
            cores = discover()
            for core in dict.fromkeys(FILTERS[r[1]][0] for r in rows):  # each core's configurations at once
                configs = [r[3] for r in rows if FILTERS[r[1]][0] == core]
                for params, (work, _) in zip(configs, write_cores(cores[core], configs, out, runner)):
                    name = params.name
                    synth[name] = (xilinx_task(runner, work, name),
                                   None if args.no_pnr else ecp5_fmax(work, name, args.freq, args.pnr_seeds, runner))
        acc = accuracy(runner, args.apps, args.seeds, args.steps) if args.seeds else {}
        synth = {k: (x.result(), f.result() if f is not None else None) for k, (x, f) in synth.items()}
    print("Choosing a filter: one application per core, binary32; cycles from the schedules (the manifests'), "
          "Xilinx 7 cells after Yosys synth_xilinx, ECP5-85 Fmax after nextpnr-ecp5 "
          f"(median of placer seeds {','.join(map(str, args.pnr_seeds))}, target {args.freq:g} MHz)")
    print(f"\n{'app':8} {'filter':9} {'P':>2} {'cycles':>7} {'FMAs':>6} {'LUT':>7} {'FF':>7} {'DSP':>4} {'BRAM':>5} "
          f"{'Fmax MHz':>9} {'us/iter':>8}")
    for app, filt, p, params in rows:
        cyc, fma = cycles(params)
        res, fmax = synth.get(params.name, (None, None))
        mhz = fmax["fmax_mhz"] if fmax else None
        print(f"{app:8} {FILTERS[filt][1]:9} {p:>2} {cyc:>7} {fma:>6} "
              f"{_fmt(res and res['lut'], 0):>7} {_fmt(res and res['ff'], 0):>7} {_fmt(res and res['dsp'], 0):>4} "
              f"{_fmt(res and res['bram36'], 1):>5} {_fmt(mhz):>9} {_fmt(mhz and cyc / mhz, 2):>8}")
    for name, (_, fmax) in synth.items():
        if fmax and fmax["failed_seeds"]:
            print(f"note: {name}: nextpnr failed seed(s) {fmax['failed_seeds']}")
    if acc:
        print(f"\nAccuracy: position RMS (m) over {args.seeds} seeds (0-{args.seeds - 1}) of {args.steps} iterations, "
              "mean / worst seed; binary32: the core's bit-exact golden model (faulted seeds left out, counted); "
              "float64: the filter's reference")
        print(f"{'app':8} {'filter':9} {'binary32 mean':>14} {'worst':>10} {'float64 mean':>14} {'worst':>10} "
              f"{'faults':>7}")
        for app, figs in acc.items():
            for filt in filters_of(app):
                b32, f64 = np.array(figs[f"{filt}_b32"]), np.array(figs[f"{filt}_f64"])
                ok = b32[np.isfinite(b32)]
                print(f"{app:8} {FILTERS[filt][1]:9} {np.mean(ok):>14.5g} {np.max(ok):>10.5g} {np.mean(f64):>14.5g} "
                      f"{np.max(f64):>10.5g} {figs[f'{filt}_faults']:>7}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
