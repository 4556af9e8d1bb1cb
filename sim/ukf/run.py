"""Generate, build and run a UKF core under cocotb (:mod:`kfgen.sim.ukf.tb`) on Verilator."""

from __future__ import annotations

from pathlib import Path

from ..verilator import Build, build, run_test

__all__ = ["build_ukf_core", "run_ukf", "build_driver", "run_cosim"]

#: A generous bound on the cycles one testbench run simulates (for the build's C++ optimisation).
RUN_CYCLES = 100_000


def build_ukf_core(rtl_dir, top: str, cache_dir=None, waves: bool = False) -> Build:
    """Verilate ``rtl_dir/TOP.v`` (a ``kfgen ukf`` output) into the build cache ``cache_dir``
    (default ``rtl_dir/sim_build``).

    A run of the testbench simulates some thousands of cycles (five iterations of steps of a
    few hundred cycles, the bus transfers between them, with backpressure), far below
    :data:`kfgen.sim.verilator.LONG_RUN_CYCLES`, so the build takes the cheap C++ optimisation."""
    rtl_dir = Path(rtl_dir)
    return build([rtl_dir / f"{top}.v"], top, cache_dir or rtl_dir / "sim_build", waves=waves, cycles=RUN_CYCLES)


def run_ukf(model: Build, rtl_dir, top: str, tests: list[str], name: str, env: dict | None = None) -> None:
    """Run the testbench's ``tests`` (function names) on a build, in ``rtl_dir/runs``; fails with
    the log's tail."""
    rtl_dir = Path(rtl_dir).resolve()  # the simulation runs in rtl_dir/runs
    run_dir = rtl_dir / "runs"
    run_dir.mkdir(parents=True, exist_ok=True)
    pattern = "|".join(rf"kfgen\.sim\.ukf\.tb\.{t}\b" for t in tests)
    run_test(model, "kfgen.sim.ukf.tb", run_dir, name,
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
    ``.npz`` for the estimates and cycles; ``driver``: the C driver's library (:func:`build_driver`)."""
    rtl_dir = Path(rtl_dir).resolve()  # the simulation runs in rtl_dir/runs
    run_dir = rtl_dir / "runs"
    run_dir.mkdir(parents=True, exist_ok=True)
    env = {"KFGEN_TB_MANIFEST": str(rtl_dir / f"{top}.json"), "COCOTB_TEST_FILTER": rf"kfgen\.sim\.ukf\.cosim\.{test}\b",
           "KFGEN_APP": app, "KFGEN_STEPS": str(steps), "KFGEN_SEED": str(seed), "KFGEN_BEATS": beats,
           "KFGEN_WAIT": wait}
    if out:
        env["KFGEN_COSIM_OUT"] = str(Path(out).resolve())
    if driver:
        env["KFGEN_DRIVER_LIB"] = str(Path(driver).resolve())
    run_test(model, "kfgen.sim.ukf.cosim", run_dir, name, env)
