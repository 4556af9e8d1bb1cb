"""Generate a core and simulate it, in one command: the co-simulation of a UKF application on
the core sized for it (``python -m kfgen.gen.cosim ukf --app MODULE:CLASS``), the same
application on its EKF core (``python -m kfgen.gen.cosim ekf --app ...``), an IMM application
(a model set and its scenario, ``python -m kfgen.gen.cosim imm --app FILE.py:CLASS``), and the
IMM's satellite-link scenario on a generated core (:func:`imm_scenario`).

Generation is gen's and simulation sim's (:mod:`kfgen.sim.ukf.run`, :mod:`kfgen.sim.imm.run`,
on a directory holding a generated core): these commands join the two, so that sim never
imports gen.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import textwrap
from pathlib import Path

import numpy as np

from kfgen.hdl.describe import ParamError
from kfgen.hdl.ekf.descriptor import CORE as EKF
from kfgen.hdl.ekf.params import EkfParams
from kfgen.hdl.imm.descriptor import CORE as IMM
from kfgen.hdl.imm.params import ImmParams
from kfgen.hdl.ukf.descriptor import CORE
from kfgen.hdl.ukf.params import UkfParams
from kfgen.sim.ekf.reference import measurements
from kfgen.sim.ekf.reference import run_reference as ekf_reference
from kfgen.sim.ekf.run import run_iterations
from kfgen.sim.engine.run import CosimFault, build_core, build_driver, run_cosim as engine_cosim
from kfgen.sim.imm.app import checked_scenario as imm_checked_scenario
from kfgen.sim.imm.app import load_imm_app
from kfgen.sim.imm.reference import run_reference as imm_reference
from kfgen.sim.imm.run import run_scenario
from kfgen.sim.ukf.accuracy import run_reference
from kfgen.sim.ukf.app import AppError, check_models, checked_scenario, load_app, portable_spec
from kfgen.sim.ukf.run import run_cosim
from kfgen.sim.ukf.software import StepError

from .cdriver import FORMATS as C_FORMATS
from .synth import write_core

__all__ = ["EXIT_CODES", "FAULTS", "ukf", "ekf", "imm", "imm_scenario", "main"]

#: The command, for its messages.
PROG = "python -m kfgen.gen.cosim"

#: Exit statuses of :func:`main`, for ``--help``'s epilog and the docs.
EXIT_CODES = """exit status:
  0  the run ended; every word the core returned equalled the golden model's
  1  the run failed otherwise (a word unlike the golden model's, a build): the log's tail
  2  bad arguments or application (one line, before anything is generated or built)
  3  the core raised a numerical fault (err_pivot: a covariance not positive definite;
     err_nan: a NaN or infinity): one line naming the iteration, the step and the bit"""

#: What each STATUS fault bit means, for the exit-3 line.
FAULTS = {"err_pivot": "a pivot not positive: a covariance that is not positive definite",
          "err_nan": "a NaN or infinity in a result"}


def ukf(argv) -> int:
    """``python -m kfgen.gen.cosim ukf --app MODULE:CLASS [...]``: size a core for an application,
    generate and build it, and co-simulate the application on it (every word checked against
    the golden model); prints the cycles of an iteration and the estimate's distance from the
    float64 reference.

    Before anything is generated: the application loads and passes its checks, f and h run
    once on x0 and a sigma point (:func:`kfgen.sim.ukf.app.check_models`), the scenario is
    well formed. A file's spec (``myapps/ctrv.py:Ctrv``) is resolved here, once: the core
    records the file's name (:func:`kfgen.sim.ukf.app.portable_spec`) and the simulation finds
    it in the file's directory, whatever the directory the command runs in.

    Returns the exit status (:data:`EXIT_CODES`)."""
    ap = _parser(ukf, "ukf", "the application, module:Class or path/file.py:Class (shipped: nanosat:Nanosat, "
                 "tracker:Tracker); it must define scenario(steps, seed)", c_driver=True)
    ap.add_argument("--beats", choices=("burst", "single"), default="burst",
                    help="AXI bursts or single beats (default burst)")
    ap.add_argument("--wait", choices=("irq", "poll"), default="irq",
                    help="wait for irq or poll STATUS (default irq)")
    ap.add_argument("--on-chip", action="store_true",
                    help="compile the application's f and h into the core: one start per iteration "
                         "(software writes u and z only)")
    ap.add_argument("--form", choices=("ldl", "sqrt"), default="ldl",
                    help="the core's covariance form (kfgen ukf --form; default ldl)")
    args = _with_output(ap, "build/cosim").parse_args(argv)
    try:
        if args.steps < 1:
            raise ValueError(f"--steps must be a positive integer, not {args.steps}")
        app = load_app(args.app)
        check_models(app)
        spec, app_dir = portable_spec(args.app)
    except (AppError, ValueError) as exc:
        print(f"cosim: error: {exc}", file=sys.stderr)
        return 2
    # the core loads the recorded file name (an on-chip core's f and h) from the file's directory
    with _on_path(app_dir):
        try:
            on_chip = {"app": spec, "on_chip": True} if args.on_chip else {}
            params = UkfParams(**app.core_parameters(), pes=args.pes, format=args.format, form=args.form,
                               name="ukf_app", **on_chip)
            if args.processor == "c" and params.format.name not in C_FORMATS:
                raise ValueError(f"--processor c: the C driver converts {' and '.join(C_FORMATS)} elements only, "
                                 f"not {params.format} (use --processor python)")
            scenario = checked_scenario(app, args.steps, args.seed)
        except (AppError, ParamError, ValueError) as exc:
            print(f"cosim: error: {exc}", file=sys.stderr)
            return 2
        work = Path(args.out)
        rtl, _ = write_core(CORE, params, work)
    model = build_core(rtl, params.name, work / "verilator", waves=args.waves,
                       cycles=args.steps * 5000)  # about 5,000 cycles an iteration at P = 1
    driver = build_driver(rtl, params.name) if args.processor == "c" else None
    npz = rtl / "cosim.npz"
    npz.unlink(missing_ok=True)  # a run that fails leaves none
    try:
        run_cosim(model, rtl, params.name, f"{args.processor}_processor", "cosim", spec, args.steps,
                  seed=args.seed, beats=args.beats, wait=args.wait, out=npz, driver=driver, app_dir=app_dir)
    except StepError as exc:
        print(f"cosim: error: the core raised a numerical fault at {exc} ({FAULTS[exc.bit]}); "
              f"log {rtl / 'runs' / 'cosim.log'}", file=sys.stderr)
        return 3
    with np.load(npz) as d:
        cycles, est, wall = d["cycles"], d["estimates"], float(d["wall_s"])
        columns = [str(c) for c in d["cycles_columns"]]
        total = int(d["sim_cycles"])
    ref = run_reference(app, scenario, params.form)
    mean = cycles.mean(axis=0)
    print(f"{args.steps} iterations of {args.app} on {params.name} (P = {params.pes}, {params.format}), "
          f"{args.processor} processor, {args.beats} transfers, {args.wait}: every word equal to the golden model's")
    each = ", ".join(f"{'transfers' if k == 'transfer' else k} {c:.0f}" for k, c in zip(columns, mean))
    print(f"cycles per iteration: {each}; total {mean.sum():.0f}")
    print(f"simulation: {total} cycles in {wall:.1f} s ({total / wall:,.0f} cycles/s)")
    print(f"largest |x - float64 reference| over the run: {np.max(np.abs(est - ref)):.3g}")
    print(f"files: {rtl} (cosim.npz, runs/cosim.log{', runs/cosim.fst' if args.waves else ''})")
    return 0


def ekf(argv) -> int:
    """``python -m kfgen.gen.cosim ekf --app MODULE:CLASS [...]``: generate the EKF core of an
    application (its f and h with their Jacobians), build it, and run the application's
    scenario on it, one start an iteration (every word checked against the golden model);
    prints the cycles of an iteration and the estimate's distance from the float64 reference EKF.

    Before anything is generated: the application loads, passes its checks and
    differentiates (:class:`kfgen.hdl.ekf.params.EkfParams`), f and h run once on x0 and a
    point of P0, the scenario is well formed.

    Returns the exit status (:data:`EXIT_CODES`)."""
    ap = _parser(ekf, "ekf", "the application, module:Class or path/file.py:Class (shipped: nanosat:Nanosat, "
                 "tracker:Tracker); it must define scenario(steps, seed)", c_driver=False)
    args = _with_output(ap, "build/cosim").parse_args(argv)
    try:
        if args.steps < 1:
            raise ValueError(f"--steps must be a positive integer, not {args.steps}")
        app = load_app(args.app)
        check_models(app)
        spec, app_dir = portable_spec(args.app)
    except (AppError, ValueError) as exc:
        print(f"cosim: error: {exc}", file=sys.stderr)
        return 2
    with _on_path(app_dir):  # the core loads its application by the file's recorded name
        try:
            params = EkfParams(app=spec, pes=args.pes, format=args.format, name="ekf_app")
            checked_scenario(app, args.steps, args.seed)
        except (AppError, ParamError, ValueError) as exc:
            print(f"cosim: error: {exc}", file=sys.stderr)
            return 2
        work = Path(args.out)
        rtl, manifest = write_core(EKF, params, work)
    model = build_core(rtl, params.name, work / "verilator", waves=args.waves, cycles=args.steps * 2000)
    got = run_iterations(model, rtl, params.name, args.steps, seed=args.seed, app_dir=app_dir or Path.cwd())
    faults = np.flatnonzero(got["flags"])
    if faults.size:
        k = int(faults[0])
        bit = "err_pivot" if got["flags"][k] & 1 else "err_nan"
        print(f"cosim: error: the core raised a numerical fault at iteration {k} ({bit}: {FAULTS[bit]}); "
              f"log {rtl / 'runs' / 'cosim.log'}", file=sys.stderr)
        return 3
    us, zs = measurements(app, args.steps, args.seed)
    ref = ekf_reference(app, us, zs)["x"]
    print(f"{args.steps} iterations of {args.app} on the EKF core {params.name} (P = {params.pes}, "
          f"{params.format}): every word equal to the golden model's")
    print(f"cycles per iteration: {manifest['cycles']['iterate']}")
    print(f"largest |x - float64 reference EKF| over the run: {np.max(np.abs(got['x'] - ref)):.3g}")
    print(f"files: {rtl} (runs/cosim.log{', runs/cosim.fst' if args.waves else ''})")
    return 0


def imm(argv) -> int:
    """``python -m kfgen.gen.cosim imm --app FILE.py:CLASS [...]``: size an IMM core for an
    application (its R models of n states, d measurements), generate and build it, and
    co-simulate the application's scenario on it (every word checked against the golden
    model); prints the cycles of an iteration and the combined estimate's distance from the
    float64 reference IMM.

    Before anything is generated: the application loads and passes its checks
    (:meth:`kfgen.sim.imm.app.ImmApplication.check`), its scenario is well formed. A file's
    spec is resolved here, once, as the UKF's (:func:`ukf`).

    Returns the exit status (:data:`EXIT_CODES`)."""
    ap = _parser(imm, "imm", "the application, path/file.py:Class or module:Class, a subclass of "
                 "kfgen.sim.imm.app.ImmApplication (shipped example: docs/examples/imm_cv.py:ConstantVelocity)",
                 c_driver=True)
    args = _with_output(ap, "build/cosim-imm").parse_args(argv)
    try:
        if args.steps < 1:
            raise ValueError(f"--steps must be a positive integer, not {args.steps}")
        app = load_imm_app(args.app)
        spec, app_dir = portable_spec(args.app)
        params = ImmParams(**app.core_parameters(), pes=args.pes, format=args.format, name="imm_app")
        if args.processor == "c" and params.format.name not in C_FORMATS:
            raise ValueError(f"--processor c: the C driver converts {' and '.join(C_FORMATS)} elements only, "
                             f"not {params.format} (use --processor python)")
        scenario = imm_checked_scenario(app, args.steps, args.seed)
    except (AppError, ParamError, ValueError) as exc:
        print(f"cosim: error: {exc}", file=sys.stderr)
        return 2
    work = Path(args.out)
    rtl, _ = write_core(IMM, params, work)
    model = build_core(rtl, params.name, work / "verilator", waves=args.waves,
                       cycles=args.steps * 5000)  # an iteration and its transfers: a few thousand cycles
    driver = build_driver(rtl, params.name) if args.processor == "c" else None
    npz = rtl / "cosim.npz"
    npz.unlink(missing_ok=True)  # a run that fails leaves none
    env = {"KFGEN_STEPS": str(args.steps), "KFGEN_SEED": str(args.seed)}
    try:
        engine_cosim(model, rtl, params.name, "kfgen.sim.imm.cosim", f"{args.processor}_processor", "cosim", spec,
                     app_dir=app_dir, out=npz, driver=driver, env=env)
    except CosimFault as exc:
        print(f"cosim: error: the core raised a numerical fault at {exc} ({FAULTS[exc.bit]}); "
              f"log {rtl / 'runs' / 'cosim.log'}", file=sys.stderr)
        return 3
    with np.load(npz) as d:
        x, mu, total, wall = d["x"], d["mu"], d["total"], float(d["wall_s"])
        iteration = d["cycles"] if "cycles" in d.files else None
        sim_cycles = int(d["sim_cycles"])
    ref = imm_reference(app.system(), *app.initial(), scenario.z)
    print(f"{args.steps} iterations of {args.app} on {params.name} (R = {params.R}, n = {params.n}, d = {params.d}, "
          f"P = {params.pes}, {params.format}), {args.processor} processor: every word equal to the golden model's")
    alone = "" if iteration is None else f"the iteration {iteration.mean():.0f}, "
    print(f"cycles per iteration: {alone}with the bus transfers {total.mean():.0f}")
    print(f"simulation: {sim_cycles} cycles in {wall:.1f} s ({sim_cycles / wall:,.0f} cycles/s)")
    print(f"largest |x - float64 reference| over the run: {np.max(np.abs(x - ref.x)):.3g}; "
          f"largest |mu - reference|: {np.max(np.abs(mu - ref.mu)):.3g}")
    print(f"files: {rtl} (cosim.npz, runs/cosim.log{', runs/cosim.fst' if args.waves else ''}"
          f"{f', {params.name}_driver.h/.c' if params.format.name in C_FORMATS else ''})")
    return 0


def _parser(command, name: str, app_help: str, *, c_driver: bool) -> argparse.ArgumentParser:
    """The options every co-simulation takes (``--app``, ``--steps``, ``--seed``, ``--pes``,
    ``--format``, and ``--processor`` where the core has a C driver); ``command``'s docstring's
    first paragraph is the description."""
    summary = textwrap.fill(" ".join(command.__doc__.split("\n\n")[0].split()), 88)
    ap = _Parser(prog=f"{PROG} {name}", description=summary, epilog=EXIT_CODES,
                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--app", required=True, help=app_help)
    ap.add_argument("--steps", type=int, default=20, help="iterations (default 20)")
    ap.add_argument("--seed", type=int, default=1, help="the scenario's seed (default 1)")
    ap.add_argument("--pes", type=int, default=1, help="processing elements (default 1)")
    if not c_driver:
        ap.add_argument("--format", default="binary32", help="the core's number format (default binary32)")
        return ap
    ap.add_argument("--format", default="binary32",
                    help="the core's number format (default binary32); the C processor takes binary32 or binary64")
    ap.add_argument("--processor", choices=("python", "c"), default="python",
                    help="the Python software side or the generated C driver (default python)")
    return ap


def _with_output(ap: argparse.ArgumentParser, out: str) -> argparse.ArgumentParser:
    """``ap`` with the options every co-simulation ends with: ``--waves`` and ``-o``."""
    ap.add_argument("--waves", action="store_true", help="write an FST waveform (runs/cosim.fst)")
    ap.add_argument("-o", "--out", default=out, help=f"work directory (default {out})")
    return ap


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, as every other refusal here, not the usage first
        print(f"cosim: error: {message}", file=sys.stderr)
        raise SystemExit(2)


@contextlib.contextmanager
def _on_path(directory):
    """``directory`` (if any) first on ``sys.path`` for the block: where the file name a core
    records (:func:`kfgen.sim.ukf.app.portable_spec`) is found."""
    if directory is None:
        yield
        return
    sys.path.insert(0, str(directory))
    try:
        yield
    finally:
        sys.path.remove(str(directory))


def imm_scenario(out_dir, steps: int, *, pes: int = 4, seed: int | None = None, cache_dir=None) -> dict:
    """Generate the default IMM core (the scenario's R = 5, n = 6, d = 2) with ``pes`` PEs in
    ``out_dir`` and run ``steps`` steps of the satellite-link scenario on it
    (:func:`kfgen.sim.imm.run.run_scenario`, built in ``cache_dir``, default
    ``out_dir/verilator``); the trace."""
    out_dir = Path(out_dir).resolve()
    rtl, _ = write_core(IMM, ImmParams(pes=pes, name=f"imm_scenario_p{pes}"), out_dir)
    return run_scenario(rtl, rtl.name, steps, seed=seed, cache_dir=cache_dir or out_dir / "verilator")


#: The commands, by core.
COMMANDS = {"ukf": ukf, "ekf": ekf, "imm": imm}


def main(argv=None) -> int:
    """``python -m kfgen.gen.cosim CORE ARGS``: the co-simulation command of ``CORE`` (``ukf``, ``imm``);
    its exit status."""
    argv = sys.argv[1:] if argv is None else list(argv)
    if not argv or argv[0] not in COMMANDS:
        if argv and argv[0] in ("-h", "--help"):
            print(f"usage: {PROG} {{{','.join(COMMANDS)}}} ARGS\n\nGenerate a core and co-simulate an "
                  f"application on it; {PROG} CORE --help for a core's options.")
            return 0
        got = f"not {argv[0]!r}" if argv else "none given"
        print(f"cosim: error: the first argument names the core: {', '.join(COMMANDS)} ({got})", file=sys.stderr)
        return 2
    return COMMANDS[argv[0]](argv[1:])


if __name__ == "__main__":
    raise SystemExit(main())
