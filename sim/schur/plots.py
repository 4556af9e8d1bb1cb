"""The Schur-complement unit's trade study as a figure: Fmax and area against latency.

Our points (:mod:`kfgen.gen.bench_schur`: ECP5-85 Fmax, Xilinx 7-series LUTs and FFs) beside
the slides' Virtex-II rows. The slides give unit latencies, not the unit's; their points are
drawn at the latency our d = 2 schedule has with those unit latencies,
``2 (Ld + Lm + La) + 3``.

Usage (the bench draws it; this redraws from its records)::

    python -m kfgen.sim.schur.plots build/bench_schur/bench_schur.json -o sim/schur/figures
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

__all__ = ["tradeoff", "slides_latency", "main"]


def slides_latency(point: dict) -> int:
    """Our d = 2 latency with the slides' unit latencies (input register and FIFO included)."""
    return 2 * (point["div_latency"] + point["mul"] + point["add"]) + 3


def tradeoff(records: list[dict], path) -> None:
    """Write the figure to ``path`` (PNG) from the bench's records."""
    import matplotlib  # deferred: matplotlib (the [dev] extras), only to draw
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 8), sharex=True)
    # A point without Fmax (place and route not run, or failed) is still drawn in the area panel.
    ours = [r for r in records if r.get("lut")]
    slides = [r["point"] for r in records if r["point"].get("fmax")]
    placed = []  # (latency, Fmax) of the points already labelled, to keep labels apart
    for k, r in enumerate(ours):
        row = r["point"].get("fmax") is not None
        style = dict(color="tab:blue", marker="o" if row else "^", ms=7 if row else 6, ls="none")
        label = f"{r['point']['label']}: {r['params']['mul_latency']}/{r['params']['add_latency']}/" \
                f"{r['params']['div_cycles_per_op']}/{r['params']['div_latency']}"
        x = r["latency"]
        if r.get("fmax_mhz"):
            near = any(0 <= x - px <= 12 and abs(r["fmax_mhz"] - py) <= 4 for px, py in placed)  # a label's width
            top.plot(x, r["fmax_mhz"], **style)
            top.annotate(label, (x, r["fmax_mhz"]), fontsize=7, xytext=(4, -10 if near else 3),
                         textcoords="offset points")
            placed.append((x, r["fmax_mhz"]))
        bottom.plot(x, r["lut"], color="tab:blue", marker=style["marker"], ls="none")
        bottom.plot(x, r["ff"], color="tab:green", marker=style["marker"], ls="none")
        # upright labels above the LUT points, side by side where two share a latency
        beside = sum(q["latency"] == x for q in ours[:k])
        bottom.annotate(r["point"]["label"], (x, r["lut"]), fontsize=7, xytext=(8 * beside, 6),
                        textcoords="offset points", rotation=90, ha="center", va="bottom")
    for p in slides:
        x = slides_latency(p)
        top.plot(x, p["fmax"], color="tab:red", marker="s", ls="none")
        top.annotate(p["label"], (x, p["fmax"]), fontsize=7, xytext=(4, -9), textcoords="offset points",
                     color="tab:red")
        bottom.plot(x, p["lut4"], color="tab:red", marker="s", ls="none")
        bottom.plot(x, p["ff"], color="tab:orange", marker="s", ls="none")
    handles = [
        plt.Line2D([], [], color="tab:blue", marker="o", ls="none", label="ours, the slides' rows (ECP5-85 Fmax)"),
        plt.Line2D([], [], color="tab:blue", marker="^", ls="none", label="ours, the sweep"),
        plt.Line2D([], [], color="tab:red", marker="s", ls="none", label="slides, Virtex-II"),
    ]
    top.legend(handles=handles, fontsize=8, loc="center left")
    top.set_ylabel("Fmax (MHz)")
    top.set_title("d = 2, binary32: mul / add / divider cycles per op / divider latency", fontsize=9, loc="left")
    top.grid(True, alpha=0.3)
    bottom.legend(handles=[
        plt.Line2D([], [], color="tab:blue", marker="o", ls="none", label="ours, Xilinx 7 LUT"),
        plt.Line2D([], [], color="tab:green", marker="o", ls="none", label="ours, Xilinx 7 FF"),
        plt.Line2D([], [], color="tab:red", marker="s", ls="none", label="slides, Virtex-II 4-input LUT"),
        plt.Line2D([], [], color="tab:orange", marker="s", ls="none", label="slides, Virtex-II FF"),
    ], fontsize=8, loc="lower right", ncol=2)
    bottom.set_yscale("log")
    bottom.set_ylim(top=3 * max(r["lut"] for r in ours))
    top.set_xlim(right=max(r["latency"] for r in ours) + 12)  # room for the labels (shared x)
    bottom.set_ylabel("area (cells)")
    bottom.set_xlabel("latency (cycles, input handshake to result); slides at 2 (Ld + Lm + La) + 3")
    bottom.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m kfgen.sim.schur.plots", description=__doc__.split("\n\n")[0])
    ap.add_argument("records", help="bench_schur.json from python -m kfgen.gen.bench_schur")
    ap.add_argument("-o", "--outdir", default="sim/schur/figures", help="directory for schur_tradeoff.png")
    args = ap.parse_args(argv)
    outdir = Path(args.outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    tradeoff(json.loads(Path(args.records).read_text()), outdir / "schur_tradeoff.png")
    print(outdir / "schur_tradeoff.png")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
