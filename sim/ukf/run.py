"""Generate, build and run a UKF core under cocotb (:mod:`kfgen.sim.ukf.tb`) on Verilator."""

from __future__ import annotations

from pathlib import Path

from ..verilator import Build, build, run_test

__all__ = ["build_ukf_core", "run_ukf"]

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
    rtl_dir = Path(rtl_dir)
    run_dir = rtl_dir / "runs"
    run_dir.mkdir(parents=True, exist_ok=True)
    pattern = "|".join(rf"kfgen\.sim\.ukf\.tb\.{t}\b" for t in tests)
    run_test(model, "kfgen.sim.ukf.tb", run_dir, name,
             {"KFGEN_TB_MANIFEST": str(rtl_dir / f"{top}.json"), "COCOTB_TEST_FILTER": pattern, **(env or {})})
