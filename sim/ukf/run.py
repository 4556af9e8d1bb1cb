"""Run a generated UKF core (``kfgen ukf``) on Verilator: its testbench (:mod:`kfgen.sim.ukf.tb`,
on :mod:`kfgen.sim.engine.run`'s build) and the co-simulation of an application
(:mod:`kfgen.sim.ukf.cosim`) with the Python processor or the generated C driver. Generating
the core and simulating it in one command is gen's (:mod:`kfgen.gen.cosim`)."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

from ..verilator import Build, run_test
from .software import StepError

__all__ = ["TB", "build_driver", "run_cosim"]

#: The UKF's cocotb testbench (:func:`kfgen.sim.engine.run.run_tb`'s ``module``).
TB = "kfgen.sim.ukf.tb"


def build_driver(rtl_dir, top: str, out_dir=None) -> Path:
    """Compile the generated C driver ``rtl_dir/TOP_driver.c`` as a shared library with its MMIO
    hooks (``-DKFGEN_MMIO_HOOKS``), under the flags the driver promises to build with
    (``-std=c99 -Wall -Wextra -Werror``); the library's path."""
    rtl_dir = Path(rtl_dir)
    out = Path(out_dir or rtl_dir) / f"lib{top}_driver.so"
    cmd = ["gcc", "-std=c99", "-Wall", "-Wextra", "-Werror", "-O2", "-shared", "-fPIC", "-DKFGEN_MMIO_HOOKS",
           "-I", str(rtl_dir), str(rtl_dir / f"{top}_driver.c"), "-o", str(out)]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{proc.stderr}")
    return out


def run_cosim(model: Build, rtl_dir, top: str, test: str, name: str, app: str, steps: int, *, seed: int = 1,
              beats: str = "burst", wait: str = "irq", out=None, driver=None, app_dir=None) -> None:
    """Run co-simulation ``test`` (``python_processor`` or ``c_processor``, :mod:`kfgen.sim.ukf.cosim`)
    of application ``app`` (``module:Class`` or ``file.py:Class``, found from ``app_dir``: by
    default the current directory) for ``steps`` iterations on a build of the core generated
    into ``rtl_dir``; ``out``: an ``.npz`` for the estimates and cycles; ``driver``: the C
    driver's library (:func:`build_driver`).

    Raises
    ------
    kfgen.sim.ukf.software.StepError
        When a step of the core raised ``err_pivot`` or ``err_nan`` (its ``iteration``,
        ``step`` and ``bit`` say where).
    AssertionError
        When the run failed otherwise (a word unlike the golden model's), with the log's tail.
    """
    rtl_dir = Path(rtl_dir).resolve()  # the simulation runs in rtl_dir/runs
    run_dir = rtl_dir / "runs"
    run_dir.mkdir(parents=True, exist_ok=True)
    fault = run_dir / f"{name}_fault.json"
    fault.unlink(missing_ok=True)
    # The simulation runs in run_dir: the application is found where the caller finds it (and
    # the manifest's file name, portable_spec's, on sys.path from KFGEN_APP_DIR).
    app_dir = Path(app_dir or Path.cwd()).resolve()
    module, _, cls = app.rpartition(":")
    if module.endswith(".py"):
        app = f"{app_dir / module}:{cls}"
    env = {"KFGEN_TB_MANIFEST": str(rtl_dir / f"{top}.json"), "COCOTB_TEST_FILTER": rf"kfgen\.sim\.ukf\.cosim\.{test}\b",
           "KFGEN_APP": app, "KFGEN_STEPS": str(steps), "KFGEN_SEED": str(seed), "KFGEN_BEATS": beats,
           "KFGEN_WAIT": wait, "KFGEN_COSIM_FAULT": str(fault), "KFGEN_APP_DIR": str(app_dir)}
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
