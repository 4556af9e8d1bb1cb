"""The linear Kalman filter's float64 reference (:mod:`kfgen.sim.kf.reference`) against
filterpy's ``KalmanFilter``, and its steady-state gain against the filter's converged gain."""

import numpy as np
from filterpy.kalman import KalmanFilter

from kfgen.sim.kf.reference import run_reference, steady_gain


def random_model(rng, n=4, m=2, nu=1):
    """A stable random model of n states, m measurements and nu inputs, and a run of it."""
    a = rng.standard_normal((n, n))
    F = np.eye(n) + 0.1 * a / np.abs(np.linalg.eigvals(a)).max()
    spd = lambda k, s: (lambda g: s * (g @ g.T + k * np.eye(k)))(rng.standard_normal((k, k)))  # noqa: E731
    return {"F": F, "B": rng.standard_normal((n, nu)), "H": rng.standard_normal((m, n)), "Q": spd(n, 0.01),
            "R": spd(m, 0.1), "x0": rng.standard_normal(n), "P0": spd(n, 1.0),
            "zs": rng.standard_normal((6, m)), "us": rng.standard_normal((6, nu))}


def test_reference_matches_filterpy():
    """n = 4, m = 2, nu = 1, six iterations: every prior and posterior to 1e-12."""
    md = random_model(np.random.default_rng(1))
    ref = run_reference(md["F"], md["H"], md["Q"], md["R"], md["x0"], md["P0"], md["zs"], md["B"], md["us"])
    kf = KalmanFilter(dim_x=4, dim_z=2, dim_u=1)
    kf.x, kf.P = md["x0"].reshape(-1, 1), md["P0"].copy()
    kf.F, kf.B, kf.H, kf.Q, kf.R = md["F"], md["B"], md["H"], md["Q"], md["R"]
    for k, (z, u) in enumerate(zip(md["zs"], md["us"])):
        kf.predict(u=u.reshape(-1, 1))
        np.testing.assert_allclose(ref.x_prior[k], kf.x.ravel(), rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(ref.P_prior[k], kf.P, rtol=1e-12, atol=1e-12)
        kf.update(z.reshape(-1, 1))
        np.testing.assert_allclose(ref.K[k], kf.K, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(ref.x_post[k], kf.x.ravel(), rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(ref.P_post[k], kf.P, rtol=1e-12, atol=1e-12)


def test_steady_gain_is_the_converged_gain():
    """The DARE's gain is the full filter's after it has converged (same model, 300 steps)."""
    md = random_model(np.random.default_rng(2))
    K = steady_gain(md["F"], md["H"], md["Q"], md["R"])
    zs = np.zeros((300, 2))
    ref = run_reference(md["F"], md["H"], md["Q"], md["R"], md["x0"], md["P0"], zs)
    np.testing.assert_allclose(ref.K[-1], K, rtol=1e-10, atol=1e-12)
