"""Figures of the satellite-link scenario (:mod:`kfgen.sim.imm.scenario`).

* ``imm_probabilities.png``: the true channel condition against the float64 IMM's most
  probable model, and the five model probabilities over time;
* ``imm_snr.png``: the SNR estimate against the truth and the measurements, for the float64
  IMM and each model alone as a Kalman filter: the whole run, a zoom on the first rain fade,
  and each filter's running RMS error.

More traces (the core's, from a co-simulation) come as ``extra={name: (mu (T, R), x (T, n))}``
to :func:`figures` or in an ``.npz`` file (``--traces``: arrays ``NAME:mu`` and ``NAME:x`` per
trace); each is drawn in both figures.

Usage::

    python -m kfgen.sim.imm.plots [--steps 2000] [--seed 4] [-o sim/imm/figures] [--traces FILE.npz]
                                  [--rtl DIR]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from kfgen.sim.cluster import add_arguments, open_runner
from kfgen.sim.engine.run import generated_top

from .reference import run_reference, run_single
from .run import run_scenario
from .scenario import CONDITIONS, RAIN, SEED, STEPS, Scenario, identification, satlink

__all__ = ["REFERENCE", "COLORS", "figure_probabilities", "figure_snr", "figures", "main"]

REFERENCE = "float64 IMM"
#: one colour per model (and condition), in the order of CONDITIONS
COLORS = ("tab:green", "tab:blue", "tab:purple", "tab:olive", "tab:brown")
_EXTRA = ("tab:orange", "tab:cyan", "tab:pink", "tab:gray")
#: running RMS window, steps
WINDOW = 50


#: The RTL core's trace (``--rtl``).
RTL = "RTL core (binary32, Verilator)"


def _pyplot():
    import matplotlib  # deferred: matplotlib (the [dev] extras), only to draw
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _segments(condition: np.ndarray):
    starts = np.flatnonzero(np.diff(np.r_[-1, condition]) != 0)
    return zip(condition[starts], starts, np.r_[starts[1:], condition.size])


def _shade(ax, t, condition, dt) -> None:
    for c, s, e in _segments(condition):
        ax.axvspan(t[s] - dt / 2, t[e - 1] + dt / 2, color=COLORS[c], alpha=0.10, lw=0)


def figure_probabilities(sc: Scenario, mu: np.ndarray, path, extra: dict | None = None,
                         title: str = "") -> None:
    """Write the condition and model-probability figure to ``path`` (PNG).

    Parameters
    ----------
    sc : the scenario (truth and condition schedule).
    mu : (T, R) the float64 IMM's model probabilities.
    extra : {name: (mu (T, R), x (T, n))} more traces; their most probable model is drawn
        beside the reference's and their probabilities dashed over its.
    """
    plt = _pyplot()
    extra = extra or {}
    t, names = sc.t, sc.names
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(11, 7), sharex=True,
                                      gridspec_kw=dict(height_ratios=(2, 3)))
    top.step(t, sc.condition, where="mid", color="black", lw=2.0, label="true condition")
    top.plot(t, np.argmax(mu, axis=1), ".", color="tab:red", ms=2.5,
             label=f"{REFERENCE}: most probable model")
    for i, (name, (mu_e, _)) in enumerate(extra.items()):
        top.plot(t, np.argmax(mu_e, axis=1) + 0.15 * (i + 1), ".", color=_EXTRA[i % len(_EXTRA)], ms=2,
                 label=f"{name}: most probable model")
    top.set_yticks(range(len(names)), names)
    top.set_ylim(-0.5, len(names) - 0.5)
    rate = identification(mu, sc.condition)
    top.set_title(f"(a) condition; the {REFERENCE}'s most probable model is the true condition "
                  f"at {100 * rate:.1f} % of the steps", fontsize=10, loc="left")
    top.legend(loc="upper right", fontsize=8, markerscale=3)

    _shade(bottom, t, sc.condition, sc.dt)
    for r, name in enumerate(names):
        bottom.plot(t, mu[:, r], color=COLORS[r], lw=1.2, label=name)
        for name_e, (mu_e, _) in extra.items():
            bottom.plot(t, mu_e[:, r], color=COLORS[r], lw=0.8, ls="--")
    if extra:
        bottom.plot([], [], color="black", lw=0.8, ls="--", label=" / ".join(extra))
    bottom.set_ylim(-0.02, 1.02)
    bottom.set_ylabel("model probability")
    bottom.set_xlabel("time (s)")
    bottom.set_xlim(t[0], t[-1])
    bottom.set_title(f"(b) model probabilities of the {REFERENCE} (background: true condition)",
                     fontsize=10, loc="left")
    bottom.legend(loc="upper center", bbox_to_anchor=(0.5, -0.13), fontsize=8,
                  ncols=len(names) + bool(extra))
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _zoom(condition: np.ndarray, width: int) -> slice:
    """A window of ``width`` steps from shortly before the first rain fade (or the start)."""
    rain = np.flatnonzero(condition == RAIN)
    start = max(0, int(rain[0]) - width // 6) if rain.size else 0
    start = max(0, min(start, condition.size - width))
    return slice(start, start + width)


def _running_rms(err: np.ndarray, window: int) -> np.ndarray:
    kernel = np.ones(min(window, err.size))
    # centred; the ends average over the steps that exist
    return np.sqrt(np.convolve(err * err, kernel, mode="same")
                   / np.convolve(np.ones(err.size), kernel, mode="same"))


def figure_snr(sc: Scenario, estimates: dict, path, extra: dict | None = None,
               title: str = "") -> None:
    """Write the SNR figure to ``path`` (PNG).

    Parameters
    ----------
    sc : the scenario (truth, measurements).
    estimates : {name: (T, n) states}: the float64 IMM first, then the single-model filters.
    extra : {name: (mu (T, R), x (T, n))} more traces, drawn like the estimates.
    """
    plt = _pyplot()
    traces = dict(estimates)
    traces.update({name: x for name, (_, x) in (extra or {}).items()})
    t, truth, z = sc.t, sc.truth[:, 0], sc.zs[:, 0]
    styles = {REFERENCE: dict(color="tab:red", lw=1.6)}
    styles.update({name: dict(color=COLORS[r], lw=0.9, alpha=0.85) for r, name in enumerate(sc.names)})
    styles.update({name: dict(color=_EXTRA[i % len(_EXTRA)], lw=0, marker=".", ms=2.5)
                   for i, name in enumerate(extra or {})})
    fig, axes = plt.subplots(3, 1, figsize=(11, 10), gridspec_kw=dict(height_ratios=(3, 3, 2)))
    zoom = _zoom(sc.condition, min(300, t.size))
    panels = ((axes[0], slice(None), "(a) the whole run: truth, measurements and the "
               f"{REFERENCE}"), (axes[1], zoom, "(b) a zoom (background: true condition): "
               "every filter"))
    for ax, span, label in panels:
        _shade(ax, t[span], sc.condition[span], sc.dt)
        ax.plot(t[span], z[span], ".", color="0.55", ms=2, label="measured SNR")
        ax.plot(t[span], truth[span], color="black", lw=1.0, label="true SNR")
        for name, x in traces.items():
            if span == slice(None) and name in sc.names:
                continue
            ax.plot(t[span], x[span, 0], label=name, **styles[name])
        ax.set_xlim(t[span][0], t[span][-1])
        ax.set_ylabel("SNR (dB)")
        ax.set_title(label, fontsize=10, loc="left")
        ax.legend(loc="lower left", fontsize=7, ncols=2, markerscale=2)
    ax = axes[2]
    for name, x in traces.items():
        style = dict(styles[name], lw=max(styles[name].get("lw", 1.0), 1.0), marker=None)
        ax.plot(t, _running_rms(x[:, 0] - truth, WINDOW), label=name, **style)
    ax.plot(t, _running_rms(z - truth, WINDOW), color="0.55", lw=1.0, ls=":", label="measurements")
    ax.set_yscale("log")
    ax.set_xlim(t[0], t[-1])
    ax.set_ylabel("SNR error (dB, RMS)")
    ax.set_xlabel("time (s)")
    ax.set_title(f"(c) running RMS error over {WINDOW} steps", fontsize=10, loc="left")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="upper left", fontsize=7, ncols=4)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _summary(sc: Scenario, mu: np.ndarray, snr: dict) -> None:
    """Print the identification rate and each SNR series' RMS error, overall and per condition."""
    present = [c for c in range(len(CONDITIONS)) if np.any(sc.condition == c)]
    per = ", ".join(f"{sc.names[c]} {100 * identification(mu[sc.condition == c], sc.condition[sc.condition == c]):.1f} %"
                    for c in present)
    print(f"identification: {100 * identification(mu, sc.condition):.1f} % of {sc.condition.size} "
          f"steps; {per}")
    print(f"{'SNR RMS error (dB)':26} {'all':>6} " + " ".join(f"{sc.names[c][:12]:>12}" for c in present))
    for name, x in snr.items():
        err = x - sc.truth[:, 0]
        rms = [np.sqrt(np.mean(err[sc.condition == c] ** 2)) for c in present]
        print(f"{name[:26]:26} {np.sqrt(np.mean(err ** 2)):6.3f} " + " ".join(f"{v:12.3f}" for v in rms))


def figures(outdir, steps: int = STEPS, seed: int = SEED, extra: dict | None = None) -> list[Path]:
    """Run the scenario through the float64 IMM and every single-model filter, print a summary
    and write both figures into ``outdir``; returns their paths.

    ``extra``: {name: (mu (T, R), x (T, n))} more traces over the same scenario (the same
    ``steps`` and ``seed``)."""
    sc = satlink(steps, seed)
    ref = run_reference(sc.system, sc.mu0, sc.xs0, sc.Ps0, sc.zs)
    estimates = {REFERENCE: ref.x}
    for r, name in enumerate(sc.names):
        estimates[name] = run_single(sc.system, r, sc.xs0[r], sc.Ps0[r], sc.zs).x
    extra = {name: (np.asarray(m), np.asarray(x)) for name, (m, x) in (extra or {}).items()}
    for name, (m, x) in extra.items():
        if m.shape != ref.mu.shape or x.shape != ref.x.shape:
            raise ValueError(f"trace {name!r}: mu must be of shape {ref.mu.shape} and x of "
                             f"shape {ref.x.shape}, not {m.shape} and {x.shape}")
    snr = {name: x[:, 0] for name, x in estimates.items()}
    snr.update({name: x[:, 0] for name, (_, x) in extra.items()})
    _summary(sc, ref.mu, dict(snr, measurements=sc.zs[:, 0]))
    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    title = f"Satellite link, {steps} steps of {sc.dt:g} s, seed {seed}"
    paths = [outdir / "imm_probabilities.png", outdir / "imm_snr.png"]
    figure_probabilities(sc, ref.mu, paths[0], extra, title)
    figure_snr(sc, estimates, paths[1], extra, title)
    return paths


def _load_traces(path) -> dict:
    with np.load(path) as npz:
        names = sorted({key.rsplit(":", 1)[0] for key in npz.files})
        missing = [f"{n}:{k}" for n in names for k in ("mu", "x") if f"{n}:{k}" not in npz.files]
        if missing:
            raise ValueError(f"{path}: every trace needs NAME:mu and NAME:x; missing {missing}")
        return {n: (npz[f"{n}:mu"], npz[f"{n}:x"]) for n in names}


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m kfgen.sim.imm.plots",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("-o", "--outdir", default="sim/imm/figures",
                    help="directory for imm_probabilities.png and imm_snr.png")
    ap.add_argument("--steps", type=int, default=STEPS, help="measurements, one a second")
    ap.add_argument("--seed", type=int, default=SEED)
    ap.add_argument("--traces", metavar="FILE.npz",
                    help="more traces: arrays NAME:mu (steps, 5) and NAME:x (steps, 6) per trace")
    ap.add_argument("--rtl", metavar="DIR",
                    help="also run the scenario through the IMM core generated into DIR in Verilator (the "
                         "default sizes: `kfgen imm --pes 4 -o DIR`; every word checked against the golden "
                         "model) and draw its trace")
    add_arguments(ap)
    args = ap.parse_args(argv)
    extra = _load_traces(args.traces) if args.traces else {}
    if args.rtl:  # the RTL run as a task (kfgen.sim.cluster), as the benches' simulations
        try:
            top, _ = generated_top(args.rtl)
        except ValueError as exc:
            ap.exit(2, f"{ap.prog}: error: {exc}\n")  # one line, without the usage
        with open_runner(args) as runner:
            trace = runner.submit(run_scenario, Path(args.rtl).resolve(), top, args.steps, seed=args.seed,
                                  name="imm-scenario").result()
        extra[RTL] = (trace["mu"], trace["x"])
    for path in figures(args.outdir, args.steps, args.seed, extra or None):
        print(path)


if __name__ == "__main__":
    main()
