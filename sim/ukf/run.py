"""Generate, build and run a UKF core under cocotb (:mod:`kfgen.sim.ukf.tb`) on Verilator."""

from __future__ import annotations

import re
from pathlib import Path

from ..verilator import Build, build, run_test

__all__ = ["build_ukf_core", "run_ukf", "build_driver", "run_cosim"]

#: A generous bound on the cycles one testbench run simulates (for the build's C++ optimisation).
RUN_CYCLES = 100_000


def build_ukf_core(rtl_dir, top: str, cache_dir=None, waves: bool | None = None,
                   cycles: int = RUN_CYCLES) -> Build:
    """Verilate ``rtl_dir/TOP.v`` (a ``kfgen ukf`` output) into the build cache ``cache_dir``
    (default ``rtl_dir/sim_build``).

    A run of the testbench simulates some thousands of cycles (five iterations of steps of a
    few hundred cycles, the bus transfers between them, with backpressure), far below
    :data:`kfgen.sim.verilator.LONG_RUN_CYCLES`, so the build takes the cheap C++ optimisation.
    ``waves`` (default: the environment's ``KFGEN_WAVES``, so that ``KFGEN_WAVES=1 make test``
    traces every run) builds with FST tracing: each run then leaves ``runs/<name>.fst``. A
    longer run passes its ``cycles`` (the C++ is then optimised, :func:`kfgen.sim.verilator.cxx_opt`)."""
    import os

    if waves is None:
        waves = bool(os.environ.get("KFGEN_WAVES"))
    rtl_dir = Path(rtl_dir)
    return build([rtl_dir / f"{top}.v"], top, cache_dir or rtl_dir / "sim_build", waves=waves, cycles=cycles)


def run_ukf(model: Build, rtl_dir, top: str, tests: list[str], name: str, env: dict | None = None,
            module: str = "kfgen.sim.ukf.tb") -> None:
    """Run the testbench's ``tests`` (function names of ``module``, the UKF's by default) on a
    build, in ``rtl_dir/runs``; fails with the log's tail."""
    rtl_dir = Path(rtl_dir).resolve()  # the simulation runs in rtl_dir/runs
    run_dir = rtl_dir / "runs"
    run_dir.mkdir(parents=True, exist_ok=True)
    pattern = "|".join(rf"{re.escape(module)}\.{t}\b" for t in tests)
    run_test(model, module, run_dir, name,
             {"KFGEN_TB_MANIFEST": str(rtl_dir / f"{top}.json"), "COCOTB_TEST_FILTER": pattern, **(env or {})})


def build_driver(rtl_dir, top: str, out_dir=None) -> Path:
    """Compile the generated C driver ``rtl_dir/TOP_driver.c`` as a shared library with its MMIO
    hooks (``-DKFGEN_MMIO_HOOKS``), under the flags the driver promises to build with
    (``-std=c99 -Wall -Wextra -Werror``); the library's path."""
    import subprocess

    rtl_dir = Path(rtl_dir)
    out = Path(out_dir or rtl_dir) / f"lib{top}_driver.so"
    cmd = ["gcc", "-std=c99", "-Wall", "-Wextra", "-Werror", "-O2", "-shared", "-fPIC", "-DKFGEN_MMIO_HOOKS",
           "-I", str(rtl_dir), str(rtl_dir / f"{top}_driver.c"), "-o", str(out)]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{proc.stderr}")
    return out


def run_cosim(model: Build, rtl_dir, top: str, test: str, name: str, app: str, steps: int, *, seed: int = 1,
              beats: str = "burst", wait: str = "irq", out=None, driver=None) -> None:
    """Run co-simulation ``test`` (``python_processor`` or ``c_processor``, :mod:`kfgen.sim.ukf.cosim`)
    of application ``app`` (``module:Class``) for ``steps`` iterations on a build; ``out``: an
    ``.npz`` for the estimates and cycles; ``driver``: the C driver's library (:func:`build_driver`).

    Raises
    ------
    kfgen.sim.ukf.software.StepError
        When a step of the core raised ``err_pivot`` or ``err_nan`` (its ``iteration``,
        ``step`` and ``bit`` say where).
    AssertionError
        When the run failed otherwise (a word unlike the golden model's), with the log's tail.
    """
    import json

    from .software import StepError

    rtl_dir = Path(rtl_dir).resolve()  # the simulation runs in rtl_dir/runs
    run_dir = rtl_dir / "runs"
    run_dir.mkdir(parents=True, exist_ok=True)
    fault = run_dir / f"{name}_fault.json"
    fault.unlink(missing_ok=True)
    # The simulation runs in run_dir: the application is found where the caller finds it.
    module, _, cls = app.rpartition(":")
    if module.endswith(".py"):
        app = f"{Path(module).resolve()}:{cls}"
    env = {"KFGEN_TB_MANIFEST": str(rtl_dir / f"{top}.json"), "COCOTB_TEST_FILTER": rf"kfgen\.sim\.ukf\.cosim\.{test}\b",
           "KFGEN_APP": app, "KFGEN_STEPS": str(steps), "KFGEN_SEED": str(seed), "KFGEN_BEATS": beats,
           "KFGEN_WAIT": wait, "KFGEN_COSIM_FAULT": str(fault), "KFGEN_APP_DIR": str(Path.cwd())}
    if out:
        env["KFGEN_COSIM_OUT"] = str(Path(out).resolve())
    if driver:
        env["KFGEN_DRIVER_LIB"] = str(Path(driver).resolve())
    try:
        run_test(model, "kfgen.sim.ukf.cosim", run_dir, name, env)
    except AssertionError:
        if not fault.exists():
            raise
        f = json.loads(fault.read_text())
        raise StepError(f["step"], f["bit"], f["iteration"]) from None


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


def main(argv=None) -> int:
    """``python -m kfgen.sim.ukf.run --app MODULE:CLASS [...]``: size a core for an application,
    generate and build it, and co-simulate the application on it (every word checked against
    the golden model); prints the cycles of an iteration and the estimate's distance from the
    float64 reference.

    Returns the exit status (:data:`EXIT_CODES`)."""
    import argparse
    import sys
    import textwrap

    import numpy as np

    from kfgen.gen.cdriver import FORMATS as C_FORMATS
    from kfgen.gen.synth import write_core
    from kfgen.hdl.describe import ParamError
    from kfgen.hdl.ukf.descriptor import CORE
    from kfgen.hdl.ukf.params import UkfParams

    from .accuracy import run_reference
    from .app import AppError, checked_scenario, load_app
    from .software import StepError

    class Parser(argparse.ArgumentParser):
        def error(self, message):  # one line, as every other refusal here, not the usage first
            print(f"cosim: error: {message}", file=sys.stderr)
            raise SystemExit(2)

    summary = textwrap.fill(" ".join(main.__doc__.split("\n\n")[0].split()), 88)
    ap = Parser(prog="python -m kfgen.sim.ukf.run", description=summary, epilog=EXIT_CODES,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--app", required=True,
                    help="the application, module:Class or path/file.py:Class (shipped: nanosat:Nanosat, "
                         "tracker:Tracker); it must define scenario(steps, seed)")
    ap.add_argument("--steps", type=int, default=20, help="iterations (default 20)")
    ap.add_argument("--seed", type=int, default=1, help="the scenario's seed (default 1)")
    ap.add_argument("--pes", type=int, default=1, help="processing elements (default 1)")
    ap.add_argument("--format", default="binary32",
                    help="the core's number format (default binary32); the C processor takes binary32 or binary64")
    ap.add_argument("--processor", choices=("python", "c"), default="python",
                    help="the Python software side or the generated C driver (default python)")
    ap.add_argument("--beats", choices=("burst", "single"), default="burst",
                    help="AXI bursts or single beats (default burst)")
    ap.add_argument("--wait", choices=("irq", "poll"), default="irq",
                    help="wait for irq or poll STATUS (default irq)")
    ap.add_argument("--on-chip", action="store_true",
                    help="compile the application's f and h into the core: one start per iteration "
                         "(software writes u and z only)")
    ap.add_argument("--form", choices=("ldl", "sqrt"), default="ldl",
                    help="the core's covariance form (kfgen ukf --form; default ldl)")
    ap.add_argument("--waves", action="store_true", help="write an FST waveform (runs/cosim.fst)")
    ap.add_argument("-o", "--out", default="build/cosim", help="work directory (default build/cosim)")
    args = ap.parse_args(argv)
    try:
        if args.steps < 1:
            raise ValueError(f"--steps must be a positive integer, not {args.steps}")
        app = load_app(args.app)
        on_chip = {"app": args.app, "on_chip": True} if args.on_chip else {}
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
    model = build_ukf_core(rtl, params.name, work / "verilator", waves=args.waves,
                           cycles=args.steps * 5000)  # about 5,000 cycles an iteration at P = 1
    driver = build_driver(rtl, params.name) if args.processor == "c" else None
    npz = rtl / "cosim.npz"
    npz.unlink(missing_ok=True)  # a run that fails leaves none
    try:
        run_cosim(model, rtl, params.name, f"{args.processor}_processor", "cosim", args.app, args.steps,
                  seed=args.seed, beats=args.beats, wait=args.wait, out=npz, driver=driver)
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


if __name__ == "__main__":
    raise SystemExit(main())
