"""The chapter's Figure 12: the nanosatellite's absolute attitude error against time.

(a) the first tenth of a second and the first second, (b) the whole run; one curve per
trace, a trace being the attitude error (degrees) of one implementation after each
iteration. ``make plots`` draws the float64 reference and the bit-exact binary32 golden
model of the core (:mod:`kfgen.sim.ukf.accuracy`) over the nanosatellite scenario
(:mod:`kfgen.sim.ukf.apps.nanosat`), and with ``--rtl`` the generated Verilog's, from a
co-simulation on Verilator (:func:`rtl_run`); more traces come in an ``.npz`` file, one
array per trace name.

Usage::

    python -m kfgen.sim.ukf.plots -o sim/ukf/figures [--steps 1000] [--seed 1] [--traces FILE.npz] [--rtl DIR]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from kfgen.sim.engine.run import build_core, generated_top

from .accuracy import run_golden, run_reference
from .apps.nanosat import STEPS, Nanosat, NanosatPrinted, attitude_error_deg
from .run import run_cosim

__all__ = ["SEED", "REFERENCE", "GOLDEN", "RTL", "figure12", "nanosat_runs", "generate_command", "rtl_top", "rtl_run", "main"]

SEED = 1
REFERENCE = "float64 reference"
GOLDEN = "binary32 golden model"
RTL = "generated Verilog (co-simulation)"
GOLDEN_ON_CHIP = "binary32 golden model, f and h on chip"
RTL_ON_CHIP = "generated Verilog, f and h on chip"
#: The shipped application's spec, for the on-chip core.
NANOSAT_SPEC = "nanosat:Nanosat"
NANOSAT_PRINTED_SPEC = "nanosat:NanosatPrinted"
_STYLES = {REFERENCE: dict(color="tab:blue", lw=2.6, alpha=0.6),
           GOLDEN: dict(color="black", lw=1.0, ls="--"),
           RTL: dict(color="tab:orange", lw=0, marker=".", ms=3),
           GOLDEN_ON_CHIP: dict(color="black", lw=1.0, ls=":"),
           RTL_ON_CHIP: dict(color="tab:green", lw=0, marker=".", ms=3)}
#: The chapter's claim after convergence (section 4.6), drawn as a line.
CLAIM_DEG = 0.1


def figure12(t, traces: dict, path, title: str = "") -> None:
    """Write Figure 12 to ``path`` (PNG): three panels, the first 0.1 s, the first 1 s and the
    whole run, of the attitude error of every trace.

    Parameters
    ----------
    t : (K,) the time of each iteration's estimate, s.
    traces : {name: (K,) attitude error in degrees}; drawn in order.
    """
    import matplotlib  # deferred: matplotlib (the [dev] extras), only to draw
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = np.asarray(t)
    fig, axes = plt.subplots(3, 1, figsize=(8, 9))
    spans = ((0.1, "(a) the first 0.1 s"), (1.0, "(a) the first second"), (t[-1], "(b) the whole run"))
    for ax, (end, label) in zip(axes, spans):
        keep = t <= end + 1e-9
        for i, (name, err) in enumerate(traces.items()):
            style = _STYLES.get(name, dict(color=f"C{i + 2}", lw=0, marker=".", ms=3))
            marker = dict(marker="o", ms=3) if keep.sum() <= 20 and "marker" not in style else {}
            ax.plot(t[keep], np.asarray(err)[keep], label=name, **style, **marker)
        ax.axhline(CLAIM_DEG, color="tab:red", lw=0.8, ls=":", label=f"{CLAIM_DEG:g} degree")
        ax.set_yscale("log")
        ax.set_xlim(0, end)
        ax.set_ylabel("attitude error (deg)")
        ax.set_title(label, fontsize=10, loc="left")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("time (s)")
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _nanosat(form: str):
    """The application and its spec: the square-root form's figure uses the printed P0 = I."""
    return (NanosatPrinted(), NANOSAT_PRINTED_SPEC) if form == "sqrt" else (Nanosat(), NANOSAT_SPEC)


def nanosat_runs(steps: int = STEPS, seed: int = SEED, on_chip: bool = False, form: str = "ldl") -> dict:
    """The nanosatellite scenario through the reference and the binary32 golden model (of
    the core with f and h on chip too, with ``on_chip``); with ``form="sqrt"`` the
    square-root form's, from the printed P0 = I.

    Returns ``t`` (K,), ``truth`` (K, 7) and ``estimates``: {trace name: (K, 7)}."""
    app, spec = _nanosat(form)
    sc = app.scenario(steps, seed)
    estimates = {REFERENCE: run_reference(app, sc, form), GOLDEN: run_golden(app, sc, "binary32", form=form)}
    if on_chip:
        estimates[GOLDEN_ON_CHIP] = run_golden(app, sc, "binary32", on_chip=spec, form=form)
    return {"t": sc.t, "truth": sc.truth, "estimates": estimates}


def generate_command(on_chip: bool = False, form: str = "ldl") -> str:
    """The ``kfgen`` command that generates the core :func:`rtl_run` co-simulates (the
    nanosatellite's sizes, binary32, P = 1; with ``on_chip`` f and h compiled into it)."""
    return (f"kfgen ukf --app {_nanosat(form)[1]}" + (" --on-chip" if on_chip else "")
            + (" --form sqrt" if form == "sqrt" else "") + " -o DIR")


def rtl_top(rtl: Path, on_chip: bool = False, form: str = "ldl") -> str:
    """The top of the core generated into ``rtl`` by :func:`generate_command`.

    Raises
    ------
    ValueError
        When ``rtl`` holds no such core."""
    app, _ = _nanosat(form)
    top, manifest = generated_top(rtl)
    got = manifest["parameters"]
    if (got.get("on_chip"), got.get("form"), got.get("states"), got.get("observations")) != (on_chip, form, app.n, app.m):
        raise ValueError(f"{rtl} holds {top}, not the core of `{generate_command(on_chip, form)}`")
    return top


def rtl_run(rtl: Path, steps: int = STEPS, seed: int = SEED, on_chip: bool = False, form: str = "ldl") -> np.ndarray:
    """The nanosatellite on the core generated into ``rtl`` (:func:`generate_command`,
    :func:`rtl_top`) in a Verilator co-simulation (:mod:`kfgen.sim.ukf.cosim`, every word
    checked against the golden model); the estimates, (K, 7). About 0.3 s an iteration
    (0.05 s on chip: one transaction)."""
    app, _ = _nanosat(form)
    top = rtl_top(rtl, on_chip, form)
    # an iteration is about 5,000 cycles: a long run gets the optimised C++
    model = build_core(rtl, top, Path(rtl) / "verilator", cycles=steps * 5000)
    npz = Path(rtl) / "cosim.npz"
    run_cosim(model, rtl, top, "python_processor", "figure12", f"{Nanosat.__module__}:{type(app).__name__}", steps,
              seed=seed, out=npz)
    with np.load(npz) as d:
        return d["estimates"]


def _summary(t, truth, estimates: dict) -> None:
    start = min(1.0, t[-1] / 2)  # after convergence: from the first second on (in a long run)
    after = t > start + 1e-9
    print(f"{'trace':24} {'at 0.1 s':>9} {'at 1 s':>9} {f'max > {start:g} s':>10} {f'mean > {start:g} s':>11}"
          f" {f'bias err, mean > {start:g} s (rad/s)':>29}")
    for name, x in estimates.items():
        err = attitude_error_deg(x[:, :4], truth[:, :4])
        bias = np.linalg.norm(x[:, 4:] - truth[:, 4:], axis=1)
        at = [float(np.interp(s, t, err)) for s in (0.1, 1.0)]
        print(f"{name:24} {at[0]:9.4f} {at[1]:9.4f} {err[after].max():10.4f} {err[after].mean():11.4f}"
              f" {bias[after].mean():29.5f}")


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m kfgen.sim.ukf.plots", description=__doc__.split("\n\n")[0])
    ap.add_argument("-o", "--outdir", default="sim/ukf/figures", help="directory for figure12.png")
    ap.add_argument("--steps", type=int, default=STEPS, help="iterations (100 a second)")
    ap.add_argument("--seed", type=int, default=SEED)
    ap.add_argument("--traces", metavar="FILE.npz", help="more traces: one array of attitude errors (degrees) "
                                                          "per trace name, one entry per iteration")
    ap.add_argument("--rtl", metavar="DIR", help="also co-simulate the core generated into DIR (Verilator, the "
                                                 "Python processor over AXI; generated by `kfgen ukf --app "
                                                 "nanosat:Nanosat [--on-chip] -o DIR`, with --form sqrt by "
                                                 "`kfgen ukf --app nanosat:NanosatPrinted --on-chip --form sqrt "
                                                 "-o DIR`) and draw its trace")
    ap.add_argument("--on-chip", action="store_true",
                    help="the core with f and h on chip (kfgen ukf --on-chip) instead: its golden model's trace, "
                         "and with --rtl its co-simulation's; writes figure12_on_chip.png")
    ap.add_argument("--form", choices=("ldl", "sqrt"), default="ldl",
                    help="the core's covariance form; sqrt draws the chapter's printed P0 = I (on which the ldl "
                         "form faults) and writes figure12_sqrt*.png")
    args = ap.parse_args(argv)
    if args.rtl:  # before the runs: a directory without the core is refused at once
        try:
            rtl_top(Path(args.rtl), args.on_chip, args.form)
        except ValueError as exc:
            ap.exit(2, f"{ap.prog}: error: {exc}\n")  # one line, without the usage
    runs = nanosat_runs(args.steps, args.seed, args.on_chip, args.form)
    if args.rtl:
        t0 = time.monotonic()
        runs["estimates"][RTL_ON_CHIP if args.on_chip else RTL] = rtl_run(Path(args.rtl), args.steps, args.seed,
                                                                           args.on_chip, args.form)
        print(f"co-simulation of {args.steps} iterations: {time.monotonic() - t0:.0f} s (build included)")
    t, truth = runs["t"], runs["truth"]
    traces = {name: attitude_error_deg(x[:, :4], truth[:, :4]) for name, x in runs["estimates"].items()}
    if args.traces:
        with np.load(args.traces) as npz:
            traces.update({name: npz[name] for name in npz.files})
    _summary(t, truth, runs["estimates"])
    outdir = Path(args.outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    name = "figure12" + ("_sqrt" if args.form == "sqrt" else "") + ("_on_chip" if args.on_chip else "") + ".png"
    figure12(t, traces, outdir / name,
             f"Nanosatellite attitude error, {len(t)} iterations at {1 / (t[1] - t[0]):.0f} Hz, seed {args.seed}"
             + (", f and h on chip" if args.on_chip else "")
             + (", square-root form, P0 = I" if args.form == "sqrt" else ""))
    print(outdir / name)


if __name__ == "__main__":
    main()
