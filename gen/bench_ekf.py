"""The EKF core's figures (docs/ekf.md): its iteration's cycles against the UKF's on-chip
iteration for the same shipped application, the Jacobians' multiply-adds before and after
zero-dropping, and, with ``--accuracy``, the EKF's accuracy against the UKF's and float64's
over many seeds.

    python -m kfgen.gen.bench_ekf [--pes 1,2] [--accuracy [--seeds 100]] [--workers N | --scheduler ADDRESS | --serial]

The cycles are the schedules' (what the manifests' ``cycles`` give: no synthesis, no
simulation, a few seconds). The accuracy runs, per application and seed, the bit-exact models
of both binary32 cores (the EKF's ``iterate``; the UKF's on-chip ``noise`` then one
``iteration`` a measurement; all seeds of a task at once, :func:`kfgen.sim.linalg.batch.run_batch`)
and the two float64 references (the EKF with finite-difference Jacobians,
:mod:`kfgen.sim.ekf.reference`; the augmented UKF, :mod:`kfgen.sim.ukf.reference`), each
block of seeds a task on Dask distributed (:mod:`kfgen.sim.cluster`). Measured, not tuned:
the applications' own Q, R, P0 and scenarios.

* nanosat (:class:`kfgen.sim.ukf.apps.nanosat.Nanosat`, its 1,000-iteration run): attitude
  error (degrees) averaged from 1 s on;
* tracker (:class:`kfgen.sim.ukf.apps.tracker.Tracker`, 200 iterations): position RMS (m).
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from kfgen.hdl.ekf.params import EkfParams
from kfgen.hdl.ekf.steps import programs as ekf_programs
from kfgen.hdl.ekf.steps import schedules as ekf_schedules
from kfgen.hdl.engine.app import load_app
from kfgen.hdl.linalg.engine import OVERHEAD
from kfgen.hdl.ukf.params import UkfParams
from kfgen.hdl.ukf.steps import programs as ukf_programs
from kfgen.hdl.ukf.steps import schedules as ukf_schedules
from kfgen.sim.cluster import add_arguments, collect, open_runner
from kfgen.sim.ekf.reference import run_reference as ekf_reference
from kfgen.sim.linalg.batch import BatchStatus, run_batch
from kfgen.sim.linalg.exec import from_words, to_words
from kfgen.sim.ukf.accuracy import run_reference as ukf_reference
from kfgen.sim.ukf.apps.nanosat import STEPS as NANOSAT_STEPS
from kfgen.sim.ukf.apps.nanosat import attitude_error_deg
from kfgen.sim.ukf.software import initial_words

__all__ = ["APPS", "cycles_rows", "jacobian_rows", "accuracy_block", "main"]

#: The shipped applications: name -> (spec, iterations of the accuracy run).
APPS = {"tracker": ("tracker:Tracker", 200), "nanosat": ("nanosat:Nanosat", NANOSAT_STEPS)}
#: Seconds after which the nanosatellite's attitude error is averaged (its filters settle).
SETTLE = 1.0
#: Seeds per accuracy task.
BLOCK = 50
#: The filters of the accuracy table, in its order.
FILTERS = ("ekf_b32", "ukf_b32", "ekf_f64", "ukf_f64")


def cycles_rows(pes=(1, 2)) -> list[dict]:
    """Per shipped application and P: the cycles of one EKF iteration and of the UKF's on-chip
    one (the manifests' ``cycles``), their ratio, and each program's multiply-adds."""
    rows = []
    for name, (spec, _) in APPS.items():
        for p in pes:
            ekf = EkfParams(spec, pes=p)
            ukf = UkfParams(**load_app(spec).core_parameters(), app=spec, on_chip=True, pes=p)
            e = ekf_schedules(ekf)["iterate"].cycles + OVERHEAD
            u = ukf_schedules(ukf)["iteration"].cycles + OVERHEAD
            rows.append({"app": name, "pes": p, "ekf": e, "ukf": u, "ratio": e / u,
                         "ekf_fma": ekf_programs(ekf).iteration.fma_count,
                         "ukf_fma": ukf_programs(ukf).steps["iteration"].fma_count})
    return rows


def jacobian_rows() -> list[dict]:
    """Per shipped application and Jacobian: its shape, nonzero and constant entries, and the
    multiply-adds of forward mode before (dense) and after zero-dropping (what its entries add
    to the function's own)."""
    rows = []
    for name, (spec, _) in APPS.items():
        for j in EkfParams(spec).models.jacobians.values():
            rows.append({"app": name, "jacobian": j.name, "shape": f"{j.rows}x{j.cols}", "nonzero": len(j.entries),
                         "constant": j.constants, "dense": j.dense, "sparse": j.sparse})
    return rows


def _batch(progs, main: str, pre: str | None, app, scenarios, initial: dict) -> tuple[np.ndarray, np.ndarray]:
    """The golden model of ``progs`` on every scenario at once: ``initial`` (region -> words)
    loaded, ``pre`` run once, then per iteration u and z written and ``main`` run; the
    estimates x (seeds, K, n) and the iteration of each seed's first fault (-1: none)."""
    fmt, lay = progs.fmt, progs.layout
    words = lay.initial_memory()
    for name, w in initial.items():
        reg = lay[name]
        words[reg.base:reg.base + reg.size] = w
    seeds, steps = len(scenarios), len(scenarios[0].z)
    mem = np.tile(np.array(from_words(fmt, words)), (seeds, 1))
    if pre is not None:
        run_batch(progs.steps[pre], mem)
    fault = np.full(seeds, -1)
    x = lay["x"]
    est = np.empty((seeds, steps, app.n))
    for k in range(steps):
        inputs = [("z", [sc.z[k] for sc in scenarios])]
        if app.nu:
            inputs.append(("u", [sc.u[k] for sc in scenarios]))
        for name, values in inputs:
            reg = lay[name]
            mem[:, reg.base:reg.base + reg.size] = [from_words(fmt, to_words(fmt, v)) for v in values]
        st = run_batch(progs.steps[main], mem, BatchStatus(seeds))
        fault[(fault < 0) & (st.pivot | st.nan)] = k
        est[:, k] = mem[:, x.base:x.base + app.n]
    return est, fault


def _error(name: str, app, est: np.ndarray, truth: np.ndarray) -> float:
    """The application's figure of one seed's run: the nanosatellite's mean attitude error
    (degrees) from :data:`SETTLE` on, the tracker's position RMS (m)."""
    if name == "nanosat":
        first = int(round(SETTLE / app.dt))
        return float(np.mean(attitude_error_deg(est[first:, :4], truth[first:, :4])))
    return float(np.sqrt(np.mean(np.sum((est[:, :2] - truth[:, :2]) ** 2, axis=1))))


def accuracy_block(name: str, first_seed: int, seeds: int) -> dict:
    """Seeds ``first_seed ..`` of application ``name``: per filter of :data:`FILTERS` the
    figure of each seed (NaN for a core's seed that faulted) and the faults of the cores."""
    spec, steps = APPS[name]
    app = load_app(spec)
    scenarios = [app.scenario(steps, s) for s in range(first_seed, first_seed + seeds)]
    ekf = ekf_programs(EkfParams(spec))
    ukf_params = UkfParams(**app.core_parameters(), app=spec, on_chip=True)
    ukf = ukf_programs(ukf_params)
    out = {"seeds": seeds}
    fmt = ekf.fmt
    start = {"x": to_words(fmt, app.x0), "P": to_words(fmt, np.ravel(app.P0)), "Q": to_words(fmt, np.ravel(app.Q)),
             "R": to_words(fmt, np.ravel(app.R))}
    for key, (progs, main, pre, initial) in {
            "ekf_b32": (ekf, "iterate", None, start),
            "ukf_b32": (ukf, "iteration", "noise", initial_words(app, ukf.fmt))}.items():
        est, fault = _batch(progs, main, pre, app, scenarios, initial)
        out[key] = [np.nan if f >= 0 else _error(name, app, e, sc.truth) for e, f, sc in zip(est, fault, scenarios)]
        out[f"{key}_faults"] = int(np.sum(fault >= 0))
    out["ekf_f64"], out["ukf_f64"] = [], []
    for sc in scenarios:
        us = np.zeros((steps, 0)) if sc.u is None else sc.u
        out["ekf_f64"].append(_error(name, app, ekf_reference(app, us, sc.z)["x"], sc.truth))
        out["ukf_f64"].append(_error(name, app, ukf_reference(app, sc), sc.truth))
    return out


def accuracy(runner, seeds: int) -> dict:
    """Application name -> per filter the figures of ``seeds`` seeds (from seed 0) and the
    cores' faults, the blocks run as tasks of ``runner``."""
    jobs = {(name, s): runner.submit(accuracy_block, name, s, min(BLOCK, seeds - s), name=f"ekf_acc_{name}")
            for name in APPS for s in range(0, seeds, BLOCK)}
    out = {}
    for (name, _), job in jobs.items():
        block = job.result()
        acc = out.setdefault(name, {k: [] for k in FILTERS} | {f"{k}_faults": 0 for k in FILTERS[:2]})
        for k in FILTERS:
            acc[k] += block[k]
        for k in FILTERS[:2]:
            acc[f"{k}_faults"] += block[f"{k}_faults"]
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m kfgen.gen.bench_ekf", description=__doc__.split("\n\n")[0])
    ap.add_argument("--pes", default="1,2", help="processing elements of the cycles table (default 1,2)")
    ap.add_argument("--accuracy", action="store_true", help="also the accuracy over seeds (minutes)")
    ap.add_argument("--seeds", type=int, default=100, help="seeds of the accuracy run (default 100)")
    add_arguments(ap)
    args = ap.parse_args(sys.argv[1:] if argv is None else argv)
    try:
        pes = [int(p) for p in args.pes.split(",")]
    except ValueError:
        print(f"error: --pes must be integers separated by commas, not {args.pes!r}", file=sys.stderr)
        return 2
    if args.seeds < 1:
        print(f"error: --seeds must be a positive integer, not {args.seeds}", file=sys.stderr)
        return 2
    print("EKF iteration against the UKF's on-chip iteration (cycles, binary32; the manifests' cycles)")
    print(f"{'app':8} {'P':>2} {'EKF':>6} {'UKF':>6} {'EKF/UKF':>8} {'EKF FMAs':>9} {'UKF FMAs':>9}")
    for r in cycles_rows(pes):
        print(f"{r['app']:8} {r['pes']:>2} {r['ekf']:>6} {r['ukf']:>6} {r['ratio']:>8.2f} {r['ekf_fma']:>9} "
              f"{r['ukf_fma']:>9}")
    print("\nJacobians: multiply-adds of forward mode before (dense) and after zero-dropping (compiled)")
    print(f"{'app':8} {'J':>2} {'shape':>6} {'nonzero':>8} {'constant':>9} {'dense':>6} {'compiled':>9}")
    for r in jacobian_rows():
        print(f"{r['app']:8} {r['jacobian']:>2} {r['shape']:>6} {r['nonzero']:>8} {r['constant']:>9} {r['dense']:>6} "
              f"{r['sparse']:>9}")
    if not args.accuracy:
        return 0
    with open_runner(args) as runner:
        acc = accuracy(runner, args.seeds)
    print(f"\nAccuracy over {args.seeds} seeds (mean, and worst seed; cores' faulted seeds left out and counted)")
    units = {"nanosat": "attitude error from 1 s on, deg", "tracker": "position RMS, m"}
    print(f"{'app':8} {'filter':22} {'mean':>10} {'worst':>10} {'faults':>7}")
    labels = {"ekf_b32": "EKF core, binary32", "ukf_b32": "UKF core, binary32", "ekf_f64": "EKF float64",
              "ukf_f64": "UKF float64"}
    for name, figs in acc.items():
        print(f"{name} ({units[name]})")
        for k in FILTERS:
            v = np.array(figs[k])
            ok = v[np.isfinite(v)]
            faults = figs.get(f"{k}_faults", 0)
            print(f"{'':8} {labels[k]:22} {np.mean(ok):>10.5g} {np.max(ok):>10.5g} {faults:>7}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
