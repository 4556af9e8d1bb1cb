"""Generate, build and run a UKF core under cocotb (:mod:`kfgen.sim.ukf.tb`) on Verilator."""

from __future__ import annotations

from pathlib import Path

from ..verilator import build, run_test

__all__ = ["build_ukf_core", "run_ukf"]


def build_ukf_core(rtl_dir, top: str, waves: bool = False):
    """Verilate ``rtl_dir/TOP.v`` (a ``kfgen ukf`` output) into ``rtl_dir/sim_build``; the runner."""
    rtl_dir = Path(rtl_dir)
    return build([rtl_dir / f"{top}.v"], top, rtl_dir / "sim_build", waves=waves)


def run_ukf(runner, rtl_dir, top: str, tests: list[str], name: str, env: dict | None = None,
            waves: bool = False) -> None:
    """Run the testbench's ``tests`` (function names) on a build; fails with the log's tail."""
    rtl_dir = Path(rtl_dir)
    pattern = "|".join(rf"kfgen\.sim\.ukf\.tb\.{t}\b" for t in tests)
    run_test(runner, "kfgen.sim.ukf.tb", top, rtl_dir / "sim_build", name,
             {"KFGEN_TB_MANIFEST": str(rtl_dir / f"{top}.json"), "COCOTB_TEST_FILTER": pattern, **(env or {})},
             waves=waves)
