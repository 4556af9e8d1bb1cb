"""The covariance update's forms in binary32 over a long run with precise sensors: prints, for
the symmetric form and Joseph's, whether P stays positive semidefinite and how far x and P
are from float64 (``python -m kfgen.sim.kf.stability [--iterations T] [--seeds S]``).

The runs: constant-velocity models (white-noise acceleration q, step 1) whose positions are
measured with R = 1e-6 x P0's scale (P0 = I): one axis (n = 2, m = 1) and two axes with a
control input (n = 4, m = 2, nu = 1, an acceleration on the first axis); and the one axis
with a sensor 100 times more precise (R = 1e-8). Every seed has its own trajectory and
measurements. The golden model (:func:`~.reference.run_golden_batch`) runs
the core's program bit for bit; the reference is :func:`~.reference.run_reference`.
"""

from __future__ import annotations

import argparse

import numpy as np

from kfgen.hdl.kf.programs import UPDATES, KfSizes, build_kf

from .reference import buffer_values, run_golden_batch, run_reference

__all__ = ["cv_model", "simulate", "measure", "main"]

#: Measurement noise against P0 = I: the precise sensor.
R_SCALE = 1e-6


def cv_model(axes: int, q: float = 1e-4, inputs: int = 0, r: float = R_SCALE) -> dict:
    """A constant-velocity model of ``axes`` axes (state: position, velocity per axis), the
    positions measured with variance ``r``: F, B (``inputs`` accelerations on the first
    axes), H, Q, R, x0, P0."""
    f = np.array([[1.0, 1.0], [0.0, 1.0]])
    g = np.array([[0.5], [1.0]])
    F = np.kron(np.eye(axes), f)
    G = np.kron(np.eye(axes), g)
    H = np.kron(np.eye(axes), [[1.0, 0.0]])
    return {"F": F, "B": G[:, :inputs] if inputs else None, "H": H, "Q": q * G @ G.T,
            "R": r * np.eye(axes), "x0": np.zeros(2 * axes), "P0": np.eye(2 * axes)}


def simulate(model: dict, steps: int, seed: int):
    """A trajectory of ``model`` from a state drawn from N(x0, P0): the measurements (T, m)
    and inputs (T, nu) (``None`` without inputs)."""
    rng = np.random.default_rng(seed)
    F, B, H, Q, R = (model[k] for k in ("F", "B", "H", "Q", "R"))
    x = rng.multivariate_normal(model["x0"], model["P0"])
    us = None if B is None else 0.01 * rng.standard_normal((steps, B.shape[1]))
    zs = []
    for k in range(steps):
        x = F @ x + rng.multivariate_normal(np.zeros(len(x)), Q) + (0 if us is None else B @ us[k])
        zs.append(H @ x + rng.multivariate_normal(np.zeros(len(R)), R))
    return np.array(zs), us


def measure(model: dict, update: str, steps: int, seeds: int, fmt: str = "binary32") -> dict:
    """The golden model of the ``update`` form over ``seeds`` runs of ``steps`` iterations:
    ``indefinite`` (iterations, over every run, whose P has a negative eigenvalue),
    ``min_eig`` (the smallest eigenvalue of P over every iteration, relative to the largest
    |P_ij| of that P), ``flags`` (iterations with err_pivot or err_nan), and the largest
    relative errors from float64 of x (``x_err``, against the run's scale of x) and of P's
    diagonal (``p_err``) in the last half of the run, and of P's diagonal over the whole run
    (``p_err_all``: the first updates' cancellation)."""
    F, B, H, Q, R = (model[k] for k in ("F", "B", "H", "Q", "R"))
    n, m = F.shape[0], H.shape[0]
    nu = 0 if B is None else B.shape[1]
    progs = build_kf(KfSizes(n, m, nu, update=update), fmt)
    runs = [simulate(model, steps, s) for s in range(seeds)]
    zs = np.array([z for z, _ in runs])
    us = None if B is None else np.array([u for _, u in runs])
    values = buffer_values(progs, F, H, model["x0"], B, Q, R, model["P0"])
    gold = run_golden_batch(progs, values, zs, us)
    eig = np.linalg.eigvalsh(gold["P"])
    scale = np.abs(gold["P"]).max(axis=(-2, -1))
    half = steps // 2
    x_err = p_err = p_all = 0.0
    for s, (z, u) in enumerate(runs):
        ref = run_reference(F, H, Q, R, model["x0"], model["P0"], z, B, u)
        dx = np.abs(gold["x"][s, half:, :, 0] - ref.x_post[half:])
        x_err = max(x_err, float((dx / np.abs(ref.x_post[half:]).max(axis=0)).max()))
        dref = np.diagonal(ref.P_post, axis1=1, axis2=2)
        rel = np.abs(np.diagonal(gold["P"][s], axis1=1, axis2=2) - dref) / dref
        p_err, p_all = max(p_err, float(rel[half:].max())), max(p_all, float(rel.max()))
    return {"indefinite": int((eig[..., 0] < 0).sum()), "min_eig": float((eig[..., 0] / scale).min()),
            "flags": int((gold["flags"] != 0).sum()), "x_err": x_err, "p_err": p_err,
            "p_err_all": p_all}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(prog="python -m kfgen.sim.kf.stability", description=__doc__.split("\n\n")[0])
    ap.add_argument("--iterations", type=int, default=10_000)
    ap.add_argument("--seeds", type=int, default=4)
    args = ap.parse_args(argv)
    print(f"binary32, {args.iterations:,} iterations x {args.seeds} seeds, P0 = I, R = {R_SCALE:g} I unless said")
    print("P indefinite: iterations; errors: relative, from float64, in the last half (diag P: and the whole run)")
    print("| model | update | P indefinite | min eig / max abs P | err flags | x error | diag P error | whole run |")
    print("|---|---|---|---|---|---|---|---|")
    for label, model in (("CV 1 axis, n=2 m=1", cv_model(1)), ("CV 2 axes, n=4 m=2 nu=1", cv_model(2, inputs=1)),
                         ("CV 1 axis, R = 1e-8 I", cv_model(1, r=1e-8))):
        for update in UPDATES:
            r = measure(model, update, args.iterations, args.seeds)
            print(f"| {label} | {update} | {r['indefinite']} | {r['min_eig']:.2e} | {r['flags']} "
                  f"| {r['x_err']:.1e} | {r['p_err']:.1e} | {r['p_err_all']:.1e} |")


if __name__ == "__main__":
    main()
