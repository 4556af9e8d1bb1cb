"""Build a generated engine core (``kfgen ukf``, ``kfgen imm``: ``DIR/TOP.v`` and ``DIR/TOP.json``)
on Verilator and run a cocotb testbench of it."""

from __future__ import annotations

import json
import os
import re
import subprocess
from pathlib import Path

from ..verilator import Build, build, run_test

__all__ = ["RUN_CYCLES", "build_core", "run_tb", "generated_top", "CosimFault", "run_cosim", "build_driver"]

#: A generous bound on the cycles one testbench run simulates (for the build's C++ optimisation).
RUN_CYCLES = 100_000


def build_core(rtl_dir, top: str, cache_dir=None, waves: bool | None = None, cycles: int = RUN_CYCLES) -> Build:
    """Verilate ``rtl_dir/TOP.v`` (a generated engine core) into the build cache ``cache_dir``
    (default ``rtl_dir/sim_build``).

    A run of a testbench simulates some thousands of cycles (a few iterations of steps of a
    few hundred cycles, the bus transfers between them, with backpressure), far below
    :data:`kfgen.sim.verilator.LONG_RUN_CYCLES`, so the build takes the cheap C++ optimisation.
    ``waves`` (default: the environment's ``KFGEN_WAVES``, so that ``KFGEN_WAVES=1 make test``
    traces every run) builds with FST tracing: each run then leaves ``runs/<name>.fst``. A
    longer run passes its ``cycles`` (the C++ is then optimised, :func:`kfgen.sim.verilator.cxx_opt`)."""
    if waves is None:
        waves = bool(os.environ.get("KFGEN_WAVES"))
    rtl_dir = Path(rtl_dir)
    return build([rtl_dir / f"{top}.v"], top, cache_dir or rtl_dir / "sim_build", waves=waves, cycles=cycles)


def run_tb(model: Build, rtl_dir, top: str, module: str, tests: list[str], name: str,
           env: dict | None = None) -> None:
    """Run the tests ``tests`` (function names of the cocotb module ``module``, e.g.
    ``kfgen.sim.ukf.tb``) on a build of the core in ``rtl_dir``, in ``rtl_dir/runs``; the
    testbench finds the manifest in ``KFGEN_TB_MANIFEST``. Fails with the log's tail."""
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
    rtl_dir = Path(rtl_dir)
    out = Path(out_dir or rtl_dir) / f"lib{top}_driver.so"
    cmd = ["gcc", "-std=c99", "-Wall", "-Wextra", "-Werror", "-O2", "-shared", "-fPIC", "-DKFGEN_MMIO_HOOKS",
           "-I", str(rtl_dir), str(rtl_dir / f"{top}_driver.c"), "-o", str(out)]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{proc.stderr}")
    return out


class CosimFault(RuntimeError):
    """A co-simulated step raised ``err_pivot`` or ``err_nan`` (:func:`run_cosim`): its
    ``iteration`` (from 0), ``step`` and STATUS ``bit``."""

    def __init__(self, step: str, bit: str, iteration: int):
        self.step, self.bit, self.iteration = step, bit, iteration
        super().__init__(f"iteration {iteration}: {step} raised {bit}")


def run_cosim(model: Build, rtl_dir, top: str, module: str, test: str, name: str, app: str, *, app_dir=None,
              out=None, driver=None, env: dict | None = None) -> None:
    """Run co-simulation ``test`` of the cocotb module ``module`` (``python_processor`` or
    ``c_processor`` of a core's ``cosim``) of application ``app`` (``module:Class`` or
    ``file.py:Class``, found from ``app_dir``: by default the current directory) on a build of
    the core generated into ``rtl_dir``, in ``rtl_dir/runs``; ``out``: an ``.npz`` the run
    writes (``KFGEN_COSIM_OUT``); ``driver``: the C driver's library (``KFGEN_DRIVER_LIB``);
    ``env``: the module's other variables.

    Raises
    ------
    CosimFault
        When a step raised ``err_pivot`` or ``err_nan`` (the module left ``KFGEN_COSIM_FAULT``).
    AssertionError
        When the run failed otherwise (a word unlike the golden model's), with the log's tail.
    """
    rtl_dir = Path(rtl_dir).resolve()  # the simulation runs in rtl_dir/runs
    run_dir = rtl_dir / "runs"
    run_dir.mkdir(parents=True, exist_ok=True)
    fault = run_dir / f"{name}_fault.json"
    fault.unlink(missing_ok=True)
    app_dir = Path(app_dir or Path.cwd()).resolve()
    spec, _, cls = app.rpartition(":")
    if spec.endswith(".py"):  # a file's spec, from the simulation's directory
        app = f"{app_dir / spec}:{cls}"
    env = {"KFGEN_TB_MANIFEST": str(rtl_dir / f"{top}.json"), "COCOTB_TEST_FILTER": rf"{re.escape(module)}\.{test}\b",
           "KFGEN_APP": app, "KFGEN_APP_DIR": str(app_dir), "KFGEN_COSIM_FAULT": str(fault), **(env or {})}
    if out:
        env["KFGEN_COSIM_OUT"] = str(Path(out).resolve())
    if driver:
        env["KFGEN_DRIVER_LIB"] = str(Path(driver).resolve())
    try:
        run_test(model, module, run_dir, name, env)
    except AssertionError:
        if not fault.exists():
            raise
        f = json.loads(fault.read_text())
        raise CosimFault(f["step"], f["bit"], f["iteration"]) from None


def generated_top(rtl_dir) -> tuple[str, dict]:
    """The top of the one core generated into ``rtl_dir`` (``kfgen CORE -o DIR``: ``TOP.json``
    beside ``TOP.v``) and its manifest.

    Raises
    ------
    ValueError
        When ``rtl_dir`` holds no generated core, or more than one.
    """
    rtl_dir = Path(rtl_dir)
    tops = sorted(p.stem for p in rtl_dir.glob("*.json") if (rtl_dir / f"{p.stem}.v").is_file())
    if len(tops) != 1:
        raise ValueError(f"{rtl_dir} holds {len(tops) or 'no'} generated cores (TOP.json beside TOP.v)"
                         f"{': ' + ', '.join(tops) if tops else ''}; one is needed")
    return tops[0], json.loads((rtl_dir / f"{tops[0]}.json").read_text())
