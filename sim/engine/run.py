"""Build a generated engine core (``kfgen ukf``, ``kfgen imm``: ``DIR/TOP.v`` and ``DIR/TOP.json``)
on Verilator and run a cocotb testbench of it."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

from ..verilator import Build, build, run_test

__all__ = ["RUN_CYCLES", "build_core", "run_tb", "generated_top"]

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
