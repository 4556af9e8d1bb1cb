"""Monte Carlo RMS-error figures of the Castella tracker, like the paper's Figures 5 and 6.

For each scenario, one PNG with two panels (RMS range error and RMS velocity error against
time, over 50 seeded runs) comparing the conventional Kalman filter (CKF, float64), the
adaptive CTS in float64, the bit-accurate fixed-point model of the core and, when given,
the outputs the generated Verilog produced in Verilator for the same measurement codes.

Every filter sees the same quantised measurements (the core's range codes), so the curves
differ only by the algorithm and its arithmetic.

Usage::

    python -m kfgen.sim.castella.plots -o sim/castella/figures [--verilator FILE.npz]

where ``FILE.npz`` holds, per scenario, ``<scenario>_range`` and ``<scenario>_velocity``
integer code arrays of shape (runs, steps), as the core output them for the measurement
codes ``monte_carlo(p, scenario)["codes"]``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from kfgen.hdl.castella.params import CastellaParams
from .model import run_fixed, run_float
from .scenarios import SCENARIOS, Scenario, measure, to_codes, truth

__all__ = ["SEED", "RUNS", "monte_carlo", "rms_curves", "summary", "make_figures", "main"]

#: Seed of the measurement noise: the figures and a Verilator run of the same codes share it.
SEED = 2002
RUNS = 50
#: Samples left out of time averages: step 0 echoes the first measurement (zero velocity),
#: step 1 is the two-point initialisation of eq. (17); neither is a filter estimate.
SKIP = 2
#: The manoeuvre window of the time averages: turn_start .. turn_end + this, in seconds.
AFTER_TURN = 10.0

_LABELS = {"ckf": "CKF (float)", "cts": "CTS (float)", "fixed": "CTS (fixed point)",
           "verilator": "CTS (Verilator)"}
_STYLES = {"ckf": dict(color="tab:red", lw=1.4), "cts": dict(color="tab:blue", lw=2.6, alpha=0.6),
           "fixed": dict(color="black", lw=1.0, ls="--"),
           "verilator": dict(color="tab:green", lw=0, marker=".", ms=3)}


def _scenario(scenario) -> Scenario:
    return SCENARIOS[scenario] if isinstance(scenario, str) else scenario


def _decode(p: CastellaParams, rng_codes, vel_codes):
    """Range and velocity codes to metres and m/s; velocity accepted signed or as raw bits."""
    rf, vf = p.range_fmt, p.vel_fmt
    half = 1 << (vf.width - 1)
    vel = (np.asarray(vel_codes, dtype=np.int64) + half) % (1 << vf.width) - half
    return np.asarray(rng_codes, dtype=np.int64) * 2.0 ** -rf.frac, vel * 2.0 ** -vf.frac


def monte_carlo(p: CastellaParams, scenario, runs: int = RUNS, seed: int = SEED) -> dict:
    """Fly ``scenario`` (a name or :class:`Scenario`) ``runs`` times through every filter.

    Returns a dict of arrays: ``t``, ``range_true``, ``rate_true`` (steps,); ``codes`` the
    measurement codes (runs, steps) fed to the core; ``fixed`` the raw outputs of the
    fixed-point model (a dict of code arrays); and ``<filter>_range``, ``<filter>_velocity``
    (runs, steps) in metres and m/s for ``ckf``, ``cts`` and ``fixed``.
    """
    sc = _scenario(scenario)
    t, rng_true, rate_true = truth(sc, p.period)
    codes = to_codes(p, measure(rng_true, p.sigma_r, runs, seed))
    y = codes * 2.0 ** -p.range_fmt.frac
    fixed = run_fixed(p, codes)
    mc = {"t": t, "range_true": rng_true, "rate_true": rate_true, "codes": codes, "fixed": fixed}
    mc["ckf_range"], mc["ckf_velocity"] = run_float(p, y, adaptive=False)
    mc["cts_range"], mc["cts_velocity"] = run_float(p, y, adaptive=True)
    mc["fixed_range"], mc["fixed_velocity"] = _decode(p, fixed["range"], fixed["velocity"])
    return mc


def rms_curves(mc: dict, filt: str):
    """RMS over runs of the range and velocity errors of one filter, against time."""
    er = mc[f"{filt}_range"] - mc["range_true"]
    ev = mc[f"{filt}_velocity"] - mc["rate_true"]
    return np.sqrt(np.mean(er ** 2, axis=0)), np.sqrt(np.mean(ev ** 2, axis=0))


def _window(sc: Scenario, t):
    return (t >= sc.turn_start) & (t <= sc.turn_end + AFTER_TURN)


def summary(mc: dict, sc: Scenario, filt: str) -> dict:
    """Time-averaged RMS errors (``range``, ``velocity``) from step 2 on, and the RMS range
    error over runs and samples of the manoeuvre window (``range_manoeuvre``)."""
    rr, rv = rms_curves(mc, filt)
    er = (mc[f"{filt}_range"] - mc["range_true"])[:, _window(sc, mc["t"])]
    return {"range": float(rr[SKIP:].mean()), "velocity": float(rv[SKIP:].mean()),
            "range_manoeuvre": float(np.sqrt(np.mean(er ** 2)))}


def _figure(p: CastellaParams, sc: Scenario, mc: dict, filters, path: Path):
    import matplotlib  # deferred: matplotlib (the [dev] extras), only to draw
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = mc["t"]
    fig, axes = plt.subplots(2, 1, figsize=(8, 7), sharex=True)
    for filt in filters:
        for ax, curve in zip(axes, rms_curves(mc, filt)):
            ax.plot(t[1:], curve[1:], label=_LABELS[filt], **_STYLES[filt])
    for ax, what in zip(axes, ("range error (m)", "velocity error (m/s)")):
        ax.axvspan(sc.turn_start, sc.turn_end, color="0.85", zorder=0, label="manoeuvre")
        ax.set_yscale("log")
        ax.set_ylabel(f"RMS {what}")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(loc="upper left", fontsize=8)
    axes[1].set_xlabel("time (s)")
    axes[0].set_title(f"{sc.name}: {sc.accel:.1f} m/s$^2$ turn, {mc['codes'].shape[0]} Monte Carlo runs, "
                      f"T = {p.period:g} s, $\\sigma_r$ = {p.sigma_r:g} m", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def make_figures(outdir, verilator: dict | None = None, p: CastellaParams | None = None,
                 runs: int = RUNS, seed: int = SEED) -> dict:
    """Write ``<scenario>.png`` for every scenario into ``outdir`` and print a table.

    ``verilator`` maps a scenario name to ``{"range": codes, "velocity": codes}`` (runs,
    steps) as the core output them; a scenario without an entry is plotted without that
    curve. Returns ``{scenario: {filter: summary}}``; for Verilator runs the summary also
    counts the output words (range and velocity) that differ from the fixed-point model.
    """
    p = p or CastellaParams()
    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    verilator = verilator or {}
    table = {}
    for name, sc in SCENARIOS.items():
        mc = monte_carlo(p, sc, runs, seed)
        filters = ["ckf", "cts", "fixed"]
        mismatches = None
        if name in verilator:
            hw = verilator[name]
            mc["verilator_range"], mc["verilator_velocity"] = _decode(p, hw["range"], hw["velocity"])
            mismatches = int(np.sum(mc["verilator_range"] != mc["fixed_range"])
                             + np.sum(mc["verilator_velocity"] != mc["fixed_velocity"]))
            filters.append("verilator")
        _figure(p, sc, mc, filters, outdir / f"{name}.png")
        table[name] = {f: summary(mc, sc, f) for f in filters}
        if mismatches is not None:
            table[name]["verilator"]["mismatches"] = mismatches
    _print_table(table)
    return table


def _print_table(table: dict):
    print(f"{'scenario':10} {'filter':18} {'RMS range (m)':>14} {'RMS vel (m/s)':>14} "
          f"{'turn to +10 s range (m)':>24}")
    for name, rows in table.items():
        for filt, s in rows.items():
            extra = f"  words differing from the model: {s['mismatches']}" if "mismatches" in s else ""
            print(f"{name:10} {_LABELS[filt]:18} {s['range']:14.2f} {s['velocity']:14.2f} "
                  f"{s['range_manoeuvre']:24.2f}{extra}")


def _load_verilator(path) -> dict:
    with np.load(path) as npz:
        return {name: {"range": npz[f"{name}_range"], "velocity": npz[f"{name}_velocity"]}
                for name in SCENARIOS if f"{name}_range" in npz}


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m kfgen.sim.castella.plots", description=__doc__.split("\n\n")[0])
    ap.add_argument("-o", "--outdir", default="sim/castella/figures", help="directory for the PNGs")
    ap.add_argument("--verilator", metavar="FILE.npz",
                    help="core outputs: <scenario>_range and <scenario>_velocity code arrays (runs, steps)")
    args = ap.parse_args(argv)
    make_figures(args.outdir, _load_verilator(args.verilator) if args.verilator else None)


if __name__ == "__main__":
    main()
