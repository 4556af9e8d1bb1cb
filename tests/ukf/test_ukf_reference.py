"""The float64 UKF reference (kfgen.sim.ukf.reference) against the chapter and filterpy.

Expected values come from the chapter's defining properties, from numpy's own linear
algebra, or from filterpy; never from the reference itself.

How filterpy 2.0.0 differs from the chapter, and how each difference is handled:

* ``KalmanFilter``: a linear system with additive noise has one answer; the augmented UKF
  must equal it to rounding (the simplex set matches the first two moments exactly, and
  eq. (19) equals filterpy's Joseph form when K is the optimal gain).
* ``UnscentedKalmanFilter`` is not augmented: it adds Q and R to the sample covariances.
  Run on the *augmented* state (f carries the noise parts along, Q = R = 0 in filterpy, the
  augmentation of eqs. (3)-(4) redone before each predict) with the chapter's points as a
  custom points object, it is the chapter's filter, except that filterpy 2.0 redraws the
  sigma points from (x^-, P^-) at the end of ``predict`` while the chapter maps the moved
  points through h (eq. 12). Restoring the moved points makes both agree to rounding.
* filterpy's ``SimplexSigmaPoints`` is another spherical simplex: M + 1 points without the
  centre point (the chapter's set with W0 = 0, whose centre carries no weight), the same
  radii, and rows 2..M of sigma negated (a reflection, so the same first two moments but
  different points: a nonlinear f sees them differently). Checked exactly below.
* With additive noise, the augmented filter and filterpy's non-augmented one differ in
  their covariances by second-order terms. The state parts of the M-dimensional simplex are
  the n-dimensional simplex with W0' = W0 + (M - n) W1 (the extra columns are zero there),
  so the predicted means are equal; P^- differs by exactly C + C^T, C the sample
  cross-covariance of f(chi^x) and chi^w, which is zero for a linear f. In the update the
  non-augmented filter also redraws its points from P^- (spread by Q) where the augmented
  one maps moved points; the difference is again a curvature term. Over a run the two
  filters stay well within each other's uncertainty.
"""

from __future__ import annotations

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter, SimplexSigmaPoints, UnscentedKalmanFilter

from kfgen.sim.ukf.reference import (AugmentedUKF, PivotError, ldl, predict, right_divide,
                                     sigma_points, simplex_coefficients, simplex_weights,
                                     sqrt_ldl, update)

SEED = 2018  # the chapter's year


def spd(rng, n, scale=1.0):
    """A random symmetric positive-definite matrix, reasonably conditioned."""
    A = rng.standard_normal((n, n))
    return scale * (A @ A.T / n + 0.5 * np.eye(n))


def assert_close(actual, expected, rtol=1e-9):
    """Elementwise, relative to the largest entry of expected (covariances span decades)."""
    expected = np.asarray(expected)
    np.testing.assert_allclose(actual, expected, rtol=rtol,
                               atol=rtol * max(np.abs(expected).max(), 1e-300))


class ChapterPoints:
    """filterpy's points interface around the chapter's set; the square root is numpy's
    Cholesky factor, so nothing of the reference's LDL^T enters filterpy."""

    def __init__(self, M, W0):
        self.sigma = simplex_coefficients(M, W0)
        self.Wm = self.Wc = simplex_weights(M, W0)

    def num_sigmas(self):
        return self.Wm.size

    def sigma_points(self, x, P):
        return (x[:, np.newaxis] + np.linalg.cholesky(P) @ self.sigma).T


# ---------------------------------------------------------------------------- sigma set
@pytest.mark.parametrize("M", [1, 2, 5, 20])
@pytest.mark.parametrize("W0", [0.0, 0.3, 0.9])
def test_simplex_moments(M, W0):
    W = simplex_weights(M, W0)
    sigma = simplex_coefficients(M, W0)
    assert sigma.shape == (M, M + 2) and W.shape == (M + 2,)
    assert W[0] == W0 and np.all(W[1:] == (1 - W0) / (M + 1))  # eq. (5)
    assert W.sum() == pytest.approx(1.0, abs=1e-15)
    assert np.all(sigma[:, 0] == 0)  # the centre point
    np.testing.assert_allclose(sigma @ W, 0, atol=1e-14)
    np.testing.assert_allclose((sigma * W) @ sigma.T, np.eye(M), atol=1e-13)
    # spherical: every other point lies on one sphere, radius^2 = M / ((M + 1) W1)
    np.testing.assert_allclose(np.sum(sigma[:, 1:] ** 2, axis=0), M / ((M + 1) * W[1]))


def test_simplex_by_hand():
    """M = 2, W0 = 1/4: W1 = 1/4, eq. (6) gives +-sqrt(2), eq. (7) with j = 2 gives
    -1/sqrt(6 W1) = -sqrt(2/3) for points 1, 2 and 2 sqrt(2/3) for the new point 3."""
    a = np.sqrt(2 / 3)
    expected = [[0, -np.sqrt(2), np.sqrt(2), 0], [0, -a, -a, 2 * a]]
    np.testing.assert_allclose(simplex_coefficients(2, 0.25), expected, rtol=1e-15)


@pytest.mark.parametrize("W0", [-0.1, 1.0, float("nan")])
def test_bad_w0(W0):
    with pytest.raises(ValueError, match="W0"):
        simplex_weights(3, W0)


@pytest.mark.parametrize("M", [1, 3, 8])
def test_filterpy_simplex_is_the_chapter_set_reflected(M):
    rng = np.random.default_rng(SEED + M)
    x, P = rng.standard_normal(M), spd(rng, M)
    theirs = SimplexSigmaPoints(M).sigma_points(x, P).T
    flip = np.diag([1.0] + [-1.0] * (M - 1))
    ours = x[:, np.newaxis] + np.linalg.cholesky(P) @ flip @ simplex_coefficients(M, 0.0)
    np.testing.assert_allclose(theirs, ours[:, 1:], atol=1e-13)
    np.testing.assert_allclose(SimplexSigmaPoints(M).Wm, simplex_weights(M, 0.0)[1:])


def test_sigma_points_carry_the_augmented_moments():
    rng = np.random.default_rng(SEED)
    n, nw, nv, W0 = 4, 3, 2, 0.2
    x, P, Q, R = rng.standard_normal(n), spd(rng, n), spd(rng, nw, 1e-2), spd(rng, nv, 1e-3)
    chi = sigma_points(x, P, Q, R, W0)
    W = simplex_weights(n + nw + nv, W0)
    Pa = np.zeros((9, 9))
    Pa[:4, :4], Pa[4:7, 4:7], Pa[7:, 7:] = P, Q, R
    mean = chi @ W
    np.testing.assert_allclose(mean, np.r_[x, np.zeros(nw + nv)], atol=1e-14)
    d = chi - mean[:, np.newaxis]
    assert_close((d * W) @ d.T, Pa, rtol=1e-13)


# ---------------------------------------------------------------------------- LDL^T
@pytest.mark.parametrize("n", [1, 2, 7, 20])
def test_ldl_against_cholesky(n):
    rng = np.random.default_rng(SEED + n)
    A = spd(rng, n)
    L, d = ldl(A)
    assert np.all(np.diag(L) == 1) and np.all(np.triu(L, 1) == 0)
    assert_close(L @ np.diag(d) @ L.T, A, rtol=1e-14)
    assert_close(sqrt_ldl(A), np.linalg.cholesky(A), rtol=1e-13)


def test_right_divide_against_solve():
    rng = np.random.default_rng(SEED)
    A, B = spd(rng, 6), rng.standard_normal((4, 6))
    assert_close(right_divide(B, A), np.linalg.solve(A, B.T).T, rtol=1e-12)


NOT_PD = {
    "negative pivot": (np.diag([2.0, -1.0, 3.0]), 1),
    "negative first": (np.array([[-1.0, 0.0], [0.0, 1.0]]), 0),
    "zero pivot (singular)": (np.array([[1.0, 1.0], [1.0, 1.0]]), 1),
    "indefinite": (np.array([[1.0, 2.0], [2.0, 1.0]]), 1),
    "NaN": (np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, np.nan]]), 2),
}


@pytest.mark.parametrize("case", sorted(NOT_PD))
def test_not_positive_definite_raises_the_pivot(case):
    """The core sets err_pivot when D_j <= 0 or NaN; the reference raises the same rule."""
    A, j = NOT_PD[case]
    with pytest.raises(PivotError, match=f"pivot D_{j} ") as info:
        ldl(A)
    assert info.value.pivot == j
    assert not info.value.value > 0
    with pytest.raises(np.linalg.LinAlgError):  # callers may catch numpy's own error
        right_divide(np.ones((1, A.shape[0])), A)


def test_filter_raises_on_a_bad_covariance():
    ukf = AugmentedUKF(1, 1, 1, 1, lambda x, w, u, dt: x + w, lambda x, v: x + v, 0.5,
                       [0.0], [[1.0]], [[-1.0]], [[1.0]])
    with pytest.raises(PivotError) as info:
        ukf.predict()
    assert info.value.pivot == 1  # the Q block of P^a
    # S = H P^- H^T + R must be positive definite too: an h that ignores everything
    ukf = AugmentedUKF(1, 1, 1, 1, lambda x, w, u, dt: x + w, lambda x, v: 0 * x, 0.5,
                       [0.0], [[1.0]], [[1.0]], [[1.0]])
    ukf.predict()
    with pytest.raises(PivotError):
        ukf.update([0.0])


def test_update_needs_a_predict():
    ukf = AugmentedUKF(1, 1, 1, 1, lambda x, w, u, dt: x + w, lambda x, v: x + v, 0.5,
                       [0.0], [[1.0]], [[1.0]], [[1.0]])
    with pytest.raises(RuntimeError, match="predict"):
        ukf.update([0.0])


@pytest.mark.parametrize("kw, match", [
    (dict(n=0), "n must"), (dict(W0=1.0), "W0"), (dict(x0=[0.0, 0.0]), "x0"),
    (dict(Q=[[1.0, 0.0]]), "Q must"),
])
def test_constructor_checks(kw, match):
    args = dict(n=1, nw=1, nv=1, m=1, f=None, h=None, W0=0.5, x0=[0.0], P0=[[1.0]],
                Q=[[1.0]], R=[[1.0]])
    args.update(kw)
    with pytest.raises(ValueError, match=match):
        AugmentedUKF(**args)


def test_shape_errors():
    chi = sigma_points([0.0], [[1.0]], [[1.0]], [[1.0]], 0.5)
    W = simplex_weights(3, 0.5)
    with pytest.raises(ValueError, match="A must be a square"):
        ldl(np.ones(3))
    with pytest.raises(ValueError, match="B must"):
        right_divide(np.ones((2, 3)), np.eye(2))
    with pytest.raises(ValueError, match="x must"):
        sigma_points([0.0, 0.0], [[1.0]], [[1.0]], [[1.0]], 0.5)
    with pytest.raises(ValueError, match="f must return"):
        predict(chi, lambda x, w, u, dt: np.r_[x, x], W, 1, 1)
    pred = predict(chi, lambda x, w, u, dt: x + w, W, 1, 1)
    with pytest.raises(ValueError, match="h must return"):
        update(pred, chi[2:], [0.0], lambda x, v: np.r_[x, v], W)
    with pytest.raises(ValueError, match="z must"):
        update(pred, chi[2:], [[0.0]], lambda x, v: x + v, W)
    ukf = AugmentedUKF(1, 1, 1, 1, lambda x, w, u, dt: x + w, lambda x, v: x + v, 0.5,
                       [0.0], [[1.0]], [[1.0]], [[1.0]])
    ukf.predict()
    with pytest.raises(ValueError, match="z must"):
        ukf.update([0.0, 0.0])


# ---------------------------------------------------------------------------- linear: KF
@pytest.mark.parametrize("n, nw, m, W0", [(1, 1, 1, 0.0), (2, 2, 1, 0.5), (4, 2, 2, 0.2),
                                          (6, 6, 3, 0.9)])
def test_linear_equals_kalman_filter(n, nw, m, W0):
    """x' = F x + B u + G w, z = H x + v: the UKF is filterpy's KalmanFilter to rounding."""
    rng = np.random.default_rng(SEED + 10 * n + m)
    dt = 0.1
    F = np.eye(n) + dt * rng.standard_normal((n, n)) / np.sqrt(n)
    B = rng.standard_normal((n, 1))
    G = rng.standard_normal((n, nw))
    H = rng.standard_normal((m, n))
    Qw, R = spd(rng, nw, 1e-2), spd(rng, m, 1e-1)
    x0, P0 = rng.standard_normal(n), spd(rng, n)

    ukf = AugmentedUKF(n, nw, m, m, lambda x, w, u, dt: F @ x + B @ u + G @ w,
                       lambda x, v: H @ x + v, W0, x0, P0, Qw, R)
    kf = KalmanFilter(dim_x=n, dim_z=m, dim_u=1)
    kf.x, kf.P, kf.F, kf.B, kf.H, kf.Q, kf.R = x0.copy(), P0.copy(), F, B, H, G @ Qw @ G.T, R

    x_true = x0.copy()
    for k in range(100):
        u = np.array([np.sin(0.1 * k)])
        x_true = F @ x_true + B @ u + G @ rng.multivariate_normal(np.zeros(nw), Qw)
        z = H @ x_true + rng.multivariate_normal(np.zeros(m), R)
        ukf.predict(u, dt)
        kf.predict(u=u)
        assert_close(ukf.x_prior, kf.x_prior)
        assert_close(ukf.P_prior, kf.P_prior)
        ukf.update(z)
        kf.update(z)
        assert_close(ukf.S, kf.S)
        assert_close(ukf.K, kf.K)
        assert_close(ukf.x_post, kf.x_post)
        assert_close(ukf.P_post, kf.P_post)


# ---------------------------------------------------------------------------- nonlinear
N_, NW, NV, M_ = 3, 2, 2, 2  # state, process noise, measurement noise, observation
DT = 0.1


def f_nl(x, w, u, dt):
    """A damped pendulum driving a decaying third state; w enters nonlinearly."""
    return np.array([x[0] + dt * x[1],
                     x[1] + dt * (-np.sin(x[0]) + x[2] * np.cos(x[0]) - 0.1 * x[1]) + w[0],
                     x[2] * np.exp(-dt) + w[1] * (1 + 0.1 * x[0] ** 2)])


def h_nl(x, v):
    """Range and bearing from a point off the pivot; v scales the bearing."""
    return np.array([np.hypot(x[0] + 2, x[1]) + v[0], np.arctan2(x[1], x[0] + 2) * (1 + v[1])])


def simulate(rng, f, h, x0, Q, R, steps):
    x, zs = np.array(x0, dtype=float), []
    for _ in range(steps):
        x = f(x, rng.multivariate_normal(np.zeros(len(Q)), Q), None, DT)
        zs.append(h(x, rng.multivariate_normal(np.zeros(len(R)), R)))
    return zs


@pytest.mark.parametrize("W0", [0.0, 0.3, 0.8])
def test_nonlinear_equals_filterpy_ukf_on_the_augmented_state(W0):
    rng = np.random.default_rng(SEED)
    Q, R = np.diag([1e-2, 4e-3]), np.diag([1e-2, 1e-2])
    x0, P0 = np.array([0.8, 0.0, 0.3]), np.diag([0.1, 0.1, 0.1])
    zs = simulate(rng, f_nl, h_nl, x0 + [0.2, -0.1, 0.1], Q, R, 50)
    ukf = AugmentedUKF(N_, NW, NV, M_, f_nl, h_nl, W0, x0, P0, Q, R)

    Ma, n, nw = N_ + NW + NV, N_, NW
    fp = UnscentedKalmanFilter(dim_x=Ma, dim_z=M_, dt=DT,
                               fx=lambda xa, dt: np.r_[f_nl(xa[:n], xa[n:n + nw], None, dt),
                                                       xa[n:]],
                               hx=lambda xa: h_nl(xa[:n], xa[n + nw:]),
                               points=ChapterPoints(Ma, W0))
    fp.Q, fp.R = np.zeros((Ma, Ma)), np.zeros((M_, M_))
    x, P = x0, P0
    for z in zs:
        # eqs. (3)-(4): the augmentation filterpy does not do
        fp.x = np.r_[x, np.zeros(NW + NV)]
        fp.P = np.zeros((Ma, Ma))
        fp.P[:n, :n], fp.P[n:n + nw, n:n + nw], fp.P[n + nw:, n + nw:] = P, Q, R
        fp.compute_process_sigmas(DT)
        moved = fp.sigmas_f.copy()
        fp.predict()
        fp.sigmas_f = moved  # undo filterpy 2.0's redraw: eq. (12) maps the moved points
        fp.update(z)
        x, P = fp.x[:n], fp.P[:n, :n]

        ukf.predict(None, DT)
        ukf.update(z)
        assert_close(ukf.x_prior, fp.x_prior[:n])
        assert_close(ukf.P_prior, fp.P_prior[:n, :n])
        assert_close(ukf.S, fp.S)
        assert_close(ukf.K, fp.K[:n])
        assert_close(ukf.x_post, x)
        assert_close(ukf.P_post, P)


def g_add(x):
    """The additive-noise process model's deterministic part (f = g(x) + w)."""
    return np.array([x[0] + DT * x[1], x[1] - DT * np.sin(x[0]), x[2] * np.exp(-DT)])


def k_add(x):
    return np.array([np.hypot(x[0] + 2, x[1]), np.arctan2(x[1], x[0] + 2)])


@pytest.mark.parametrize("scale", [0.0, 1.0])
def test_additive_predict_differs_from_filterpy_by_the_cross_term(scale):
    """Same (x, P): equal means; P^-_aug - P^-_filterpy = C + C^T, C = sum W (g(chi^x) - x^-)
    (chi^w)^T, which vanishes for a linear g (scale 0) and not otherwise."""
    rng = np.random.default_rng(SEED)
    n, W0 = 3, 0.2
    Q, R = spd(rng, n, 1e-2), spd(rng, 2, 1e-2)
    x, P = np.array([0.8, 0.3, 0.3]), spd(rng, n, 0.2)
    lin = np.array([[1, DT, 0], [-DT, 1, 0], [0, 0, np.exp(-DT)]])

    def g(x):
        return scale * g_add(x) + (1 - scale) * lin @ x

    chi = sigma_points(x, P, Q, R, W0)
    M = chi.shape[0]
    W = simplex_weights(M, W0)
    ours = predict(chi, lambda x, w, u, dt: g(x) + w, W, n, n)

    W0_state = W0 + (M - n) * W[1]  # the state marginal of the M-simplex is an n-simplex
    fp = UnscentedKalmanFilter(dim_x=n, dim_z=2, dt=DT, fx=lambda x, dt: g(x), hx=k_add,
                               points=ChapterPoints(n, W0_state))
    fp.x, fp.P, fp.Q = x.copy(), P.copy(), Q
    fp.predict()

    assert_close(ours.x, fp.x_prior, rtol=1e-12)
    moved = np.column_stack([g(c) for c in chi[:n].T]) - ours.x[:, np.newaxis]
    C = (moved * W) @ chi[n:2 * n].T
    np.testing.assert_allclose(ours.P - fp.P_prior, C + C.T, rtol=0,
                               atol=1e-12 * np.abs(ours.P).max())
    assert (np.abs(C).max() > 1e-4 * np.abs(ours.P).max()) == (scale != 0)


def test_additive_run_stays_within_filterpy_uncertainty():
    """Over a run, the augmented reference and filterpy's non-augmented UKF (same simplex,
    W0' for the state marginal) differ by far less than their own standard deviations."""
    rng = np.random.default_rng(SEED)
    n, m, W0 = 3, 2, 0.2
    Q, R = np.diag([1e-4, 1e-3, 1e-4]), np.diag([1e-2, 1e-3])
    x0, P0 = np.array([0.8, 0.0, 0.3]), np.diag([0.05, 0.05, 0.05])
    zs = simulate(rng, lambda x, w, u, dt: g_add(x) + w, lambda x, v: k_add(x) + v,
                  x0 + [0.1, -0.1, 0.1], Q, R, 100)
    ukf = AugmentedUKF(n, n, m, m, lambda x, w, u, dt: g_add(x) + w,
                       lambda x, v: k_add(x) + v, W0, x0, P0, Q, R)
    fp = UnscentedKalmanFilter(dim_x=n, dim_z=m, dt=DT, fx=lambda x, dt: g_add(x), hx=k_add,
                               points=ChapterPoints(n, W0 + (ukf.M - n) * ukf.W[1]))
    fp.x, fp.P, fp.Q, fp.R = x0.copy(), P0.copy(), Q, R
    worst = 0.0
    for z in zs:
        ukf.predict(None, DT)
        ukf.update(z)
        fp.predict()
        fp.update(z)
        worst = max(worst, np.max(np.abs(ukf.x - fp.x) / np.sqrt(np.diag(fp.P))))
        assert_close(ukf.P, fp.P, rtol=0.1)
    assert worst < 0.1


# ---------------------------------------------------------------------------- nanosatellite
G_LOCAL = 8.94  # m/s^2 at 300 km (section 4.4)
B_A, B_M = np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])


def skew(v):
    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])  # eq. (31)


def rotation(q):
    """A_q of eq. (40); q = [q1, q2, q3, q0]."""
    q1, q2, q3, q0 = q
    return np.array([
        [q0**2 + q1**2 - q2**2 - q3**2, 2 * (q1 * q2 - q0 * q3), 2 * (q0 * q2 + q1 * q3)],
        [2 * (q1 * q2 + q0 * q3), q0**2 - q1**2 + q2**2 - q3**2, 2 * (q2 * q3 - q0 * q1)],
        [2 * (q1 * q3 - q0 * q2), 2 * (q0 * q1 + q2 * q3), q0**2 - q1**2 - q2**2 + q3**2]])


def f_sat(x, w, u, dt):
    """Eqs. (37)-(38) with the bias taken off the gyro reading (omega = z_g - beta)."""
    q, q0, omega = x[:3], x[3], u - x[4:]
    rate = np.r_[0.5 * (q0 * np.eye(3) + skew(q)) @ omega, -0.5 * q @ omega, np.zeros(3)]
    return x + (rate + w) * dt


def h_sat(x, v):
    A = rotation(x[:4])
    return np.r_[A @ (G_LOCAL * B_A), A @ B_M] + v  # eq. (39)


def test_nanosatellite_sized_filter_keeps_p_positive_definite():
    """n = 7 (q, q0, beta), nw = 7 (eta_q 4, bias drift 3), nv = m = 6, so M = 20 as in
    section 4.5; slow tumbling, 100 steps at 10 Hz."""
    rng = np.random.default_rng(SEED)
    dt, steps = 0.1, 100
    Q = np.diag([1e-6] * 4 + [1e-6] * 3)
    R = np.diag([1e-2 * G_LOCAL] * 3 + [1e-2] * 3) ** 2
    beta = np.array([0.01, -0.02, 0.015])
    x_true = np.r_[0.1, -0.2, 0.05, 0.0, beta]
    x_true[3] = np.sqrt(1 - np.sum(x_true[:3] ** 2))
    x0 = np.r_[x_true[:4] + 0.05 * rng.standard_normal(4), np.zeros(3)]
    ukf = AugmentedUKF(7, 7, 6, 6, f_sat, h_sat, 0.1, x0, np.diag([1e-2] * 4 + [1e-3] * 3),
                       Q, R)
    assert ukf.M == 20 and ukf.W0 == 0.1
    for k in range(steps):
        omega = np.array([0.05, -0.03, 0.02]) * np.cos(0.02 * k)
        z_gyro = omega + beta + 1e-3 * rng.standard_normal(3)
        x_true = f_sat(x_true, np.zeros(7), omega + beta, dt)
        x_true[:4] /= np.linalg.norm(x_true[:4])
        ukf.predict(z_gyro, dt)
        ukf.update(h_sat(x_true, rng.multivariate_normal(np.zeros(6), R)))
        for P in (ukf.P_prior, ukf.P_post):
            assert np.all(np.isfinite(P))
            assert np.abs(P - P.T).max() <= 1e-12 * np.abs(P).max()
            assert np.linalg.eigvalsh(P).min() > 0
            ldl(P)  # the core's own test: every pivot positive
    q = ukf.x[:4] / np.linalg.norm(ukf.x[:4])
    assert min(np.linalg.norm(q - x_true[:4]), np.linalg.norm(q + x_true[:4])) < 0.02
