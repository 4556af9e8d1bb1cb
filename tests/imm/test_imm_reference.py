"""The float64 IMM reference (kfgen.sim.imm.reference) against the slides and filterpy.

Expected values come from a literal evaluation of the slides' step table, from filterpy, or
from scipy's log-sum-exp; never from the reference itself.

filterpy 2.0.0's ``IMMEstimator`` is the same algorithm: its ``M`` is our pi (its code takes
``cbar = mu @ M``, so ``M[i, j]`` is P(j | i) whatever its docstring says), its ``omega`` our
mixing weights, and it mixes, predicts, updates and combines as MIX, KF and COM do. Its
arithmetic differs: ``KalmanFilter.update`` takes S^-1 by ``inv`` and P by the Joseph form
(I - K H) P (I - K H)^T + K R K^T, which equals P - K (P H^T)^T for the optimal gain; the
likelihood comes from scipy's ``multivariate_normal.logpdf`` (an eigendecomposition of S)
and is not scaled. Each step thus differs by a few float64 roundings, amplified at most by
the condition numbers of S and P (about 1e2 to 1e5 here) and, in the probabilities, by q_j
(exp's relative error is q_j / 2 times the error in q_j). The filters are stable and the
mixing contracts, so the differences do not accumulate: over 400 steps of the scenario the
largest seen is 2e-12 relative on a probability near 1e-130, 5e-14 on P and 5e-16 on x.
The tolerance, 1e-9 relative, leaves three orders of margin; a formula that differs (a
transposed pi, mu in place of c, a lost spread term) shows at 1e-3 and above.
"""

from __future__ import annotations

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter
from scipy.special import logsumexp

from kfgen.sim.imm import scenario
from kfgen.sim.imm.reference import (ImmModel, ImmSystem, imm_step, run_filterpy,
                                     run_reference, run_single)

SEED = 2016  # the slides' year
RTOL = 1e-9


def spd(rng, n, scale=1.0):
    """A random symmetric positive-definite matrix, reasonably conditioned."""
    A = rng.standard_normal((n, n))
    return scale * (A @ A.T / n + 0.5 * np.eye(n))


def random_system(rng, Rm=3, n=4, d=2) -> ImmSystem:
    models = [ImmModel(f"m{r}", np.eye(n) + 0.1 * rng.standard_normal((n, n)),
                       spd(rng, n, 10.0 ** -r), rng.standard_normal((d, n)), spd(rng, d, 0.1))
              for r in range(Rm)]
    pi = rng.uniform(0.05, 1.0, (Rm, Rm)) + 3 * np.eye(Rm)
    return ImmSystem(models, pi / pi.sum(axis=1, keepdims=True))


def random_bank(rng, system: ImmSystem):
    mu = rng.uniform(0.1, 1.0, system.R)
    xs = rng.standard_normal((system.R, system.n))
    Ps = np.array([spd(rng, system.n) for _ in range(system.R)])
    return mu / mu.sum(), xs, Ps


def rel(actual, expected, axes=None):
    """Largest difference relative to the largest entry of expected (per leading index when
    axes names the others: covariances and states span decades)."""
    actual, expected = np.asarray(actual), np.asarray(expected)
    return float(np.max(np.abs(actual - expected).max(axis=axes)
                        / np.maximum(np.abs(expected).max(axis=axes), 1e-300)))


# ------------------------------------------------------------------ the slides, literally
def slides(system: ImmSystem, mu, xs, Ps, z) -> dict:
    """One iteration evaluated as the step table prints it, in matrices: X holds the models'
    states as columns, S^-1 by inv, the unscaled likelihood with (2 pi)^(-d/2).

    Two readings: MIX01 is taken as mu^T pi (printed mu^T pi^T, which with MIX03's pi is the
    transpose), and COM06's (2 pi)^(d/2) as (2 pi)^(-d/2); the combined covariance, absent
    from the table, is COM10's weighting applied to P_j + spread."""
    pi, d = system.pi, system.d
    X = np.asarray(xs).T  # n x R
    mu_hat = mu @ pi  # MIX01
    mix02 = pi.T @ np.diag(mu)  # MIX02
    mu_ij = mix02.T @ np.linalg.inv(np.diag(mu_hat))  # MIX03
    X0 = X @ mu_ij  # MIX04
    P0 = []
    for j in range(system.R):
        acc = np.zeros((system.n, system.n))
        for i in range(system.R):
            e = X0[:, [j]] - X[:, [i]]  # MIX05
            acc += (e @ e.T + Ps[i]) * mu_ij[i, j]  # MIX06-07, G = 0
        P0.append(acc)
    out = {"c": mu_hat, "omega": mu_ij, "x0": X0.T, "P0": np.array(P0)}
    rows = []
    for j, m in enumerate(system.models):
        F, Q, H, R = m.F, m.Q, m.H, m.R
        xp = F @ X0[:, j]  # KF01
        FP = F @ P0[j]  # KF02
        Pp = FP @ F.T + Q  # KF03
        PHt = Pp @ H.T  # KF04
        S = H @ PHt + R  # KF05
        Si = np.linalg.inv(S)
        K = PHt @ Si  # KF06
        P = Pp - K @ PHt.T  # KF07
        e = z - H @ xp  # KF08
        x = xp + K @ e  # KF09
        q = e @ Si @ e  # COM01
        L = (2 * np.pi) ** (-d / 2) * np.linalg.det(S) ** -0.5 * np.exp(-0.5 * q)  # COM02-06
        rows.append((xp, Pp, e, S, K, x, P, q, np.linalg.det(S), L))
    keys = ("x_prior", "P_prior", "y", "S", "K", "xs", "Ps", "q", "det_S", "L")
    out.update({k: np.array(v) for k, v in zip(keys, zip(*rows))})
    L = out["L"]
    num = np.diag(L) @ mu_hat  # COM07
    den = mu_hat @ L  # COM08
    out["mu"] = num / den  # COM09
    out["x"] = out["xs"].T @ out["mu"]  # COM10
    out["P"] = sum(u * (P + np.outer(x - out["x"], x - out["x"]))
                   for u, x, P in zip(out["mu"], out["xs"], out["Ps"]))
    return out


FIELDS = {"c": None, "omega": None, "x0": 1, "P0": (1, 2), "x_prior": 1, "P_prior": (1, 2),
          "y": 1, "S": (1, 2), "K": (1, 2), "xs": 1, "Ps": (1, 2), "q": None, "det_S": None,
          "mu": None, "x": None, "P": None}


def check_against_slides(system, mu, xs, Ps, z, rtol=1e-12):
    ours = imm_step(system, mu, xs, Ps, z)
    theirs = slides(system, mu, xs, Ps, z)
    assert np.all(theirs["L"] > 0), "the literal form must not underflow here"
    for name, axes in FIELDS.items():
        assert rel(getattr(ours, name), theirs[name], axes) <= rtol, name
    # the scaled weights are the slides' c_j Lambda_j times one common factor
    ratio = ours.w / (theirs["c"] * theirs["L"])
    np.testing.assert_allclose(ratio, ratio[0], rtol=rtol)
    np.testing.assert_allclose(ours.t, -theirs["q"] / 2, rtol=rtol)
    assert ours.m == ours.t.max()
    return ours


@pytest.mark.parametrize("shape", [(2, 2, 1), (3, 4, 2), (5, 6, 2), (4, 5, 3)])
def test_random_systems_against_the_slides(shape):
    rng = np.random.default_rng(SEED + sum(shape))
    system = random_system(rng, *shape)
    mu, xs, Ps = random_bank(rng, system)
    for _ in range(20):
        z = rng.standard_normal(system.d)
        s = check_against_slides(system, mu, xs, Ps, z)
        mu, xs, Ps = s.mu, s.xs, s.Ps


def test_scenario_against_the_slides():
    """Every step of the satellite link's first 300 (clear sky, multipath, ionospheric
    scintillation) against the literal table."""
    sc = scenario.satlink(300)
    mu, xs, Ps = sc.mu0, sc.xs0, sc.Ps0
    for z in sc.zs:
        s = check_against_slides(sc.system, mu, xs, Ps, z, rtol=1e-10)
        mu, xs, Ps = s.mu, s.xs, s.Ps


# ------------------------------------------------------------------ underflow
def test_every_likelihood_underflowing_gives_no_nan():
    """A measurement hundreds of dB from every model: each COM03 exp underflows, the literal
    COM09 is 0/0, and the scaled domain still gives the probabilities a log-domain
    evaluation (scipy's logsumexp) gives."""
    sc = scenario.satlink(50)
    ref = run_reference(sc.system, sc.mu0, sc.xs0, sc.Ps0, sc.zs)
    mu, xs, Ps = ref.mu[-1], ref.xs[-1], ref.Ps[-1]
    z = np.array([400.0, -300.0])
    with np.errstate(invalid="ignore"):
        literal = slides(sc.system, mu, xs, Ps, z)
    assert np.all(literal["L"] == 0) and np.all(np.isnan(literal["mu"]))

    s = imm_step(sc.system, mu, xs, Ps, z)
    assert np.all(np.isfinite(s.mu)) and np.all(s.mu >= 0)
    assert s.mu.sum() == pytest.approx(1.0, abs=1e-15)
    assert np.all(np.isfinite(s.x)) and np.all(np.isfinite(s.P))
    log_w = np.log(s.c) - 0.5 * np.log(s.det_S) - s.q / 2
    np.testing.assert_allclose(s.mu, np.exp(log_w - logsumexp(log_w)), rtol=1e-9, atol=1e-300)
    # multipath fading, the one model with a wide S on both SNR and SIR, explains it best
    assert np.argmax(s.mu) == scenario.MULTIPATH
    assert s.t.max() < -745  # exp(t) is below the smallest subnormal for every model
    # and the next iteration goes on from there
    nxt = imm_step(sc.system, s.mu, s.xs, s.Ps, sc.zs[-1])
    assert np.all(np.isfinite(nxt.mu)) and nxt.mu.sum() == pytest.approx(1.0)


def test_mu_scale_does_not_matter():
    rng = np.random.default_rng(SEED)
    system = random_system(rng)
    mu, xs, Ps = random_bank(rng, system)
    z = rng.standard_normal(system.d)
    a, b = imm_step(system, mu, xs, Ps, z), imm_step(system, 7.5 * mu, xs, Ps, z)
    for name in ("mu", "x", "P", "xs", "Ps", "omega"):
        np.testing.assert_allclose(getattr(b, name), getattr(a, name), rtol=1e-13, atol=1e-15)


def test_covariances_are_symmetric():
    sc = scenario.satlink(100)
    ref = run_reference(sc.system, sc.mu0, sc.xs0, sc.Ps0, sc.zs)
    assert np.array_equal(ref.Ps, np.swapaxes(ref.Ps, -1, -2))
    assert np.array_equal(ref.P, np.swapaxes(ref.P, -1, -2))


# ------------------------------------------------------------------ filterpy
@pytest.fixture(scope="module")
def scenario_400():
    """Clear sky, multipath fading and the start of ionospheric scintillation."""
    sc = scenario.satlink(400)
    assert set(sc.condition) == {scenario.CLEAR, scenario.MULTIPATH, scenario.IONO}
    return sc


def test_against_filterpy_imm_estimator(scenario_400):
    sc = scenario_400
    ours = run_reference(sc.system, sc.mu0, sc.xs0, sc.Ps0, sc.zs)
    theirs = run_filterpy(sc.system, sc.mu0, sc.xs0, sc.Ps0, sc.zs)
    assert theirs.mu.min() > 0  # no likelihood reached filterpy's floor (float_info.min)
    np.testing.assert_allclose(ours.mu, theirs.mu, rtol=RTOL, atol=0)
    assert rel(ours.x, theirs.x, 1) <= RTOL
    assert rel(ours.P, theirs.P, (1, 2)) <= RTOL
    assert rel(ours.xs, theirs.xs, 2) <= RTOL
    assert rel(ours.Ps, theirs.Ps, (2, 3)) <= RTOL


def test_filterpy_comparison_tells_the_transition_matrix_from_its_transpose():
    """The scenario's pi is symmetric; on a random system with an asymmetric one, filterpy
    agrees with M = pi and is far off with M = pi^T."""
    rng = np.random.default_rng(SEED)
    system = random_system(rng, 3, 4, 2)
    mu, xs, Ps = random_bank(rng, system)
    zs = rng.standard_normal((30, system.d))
    ours = run_reference(system, mu, xs, Ps, zs)
    assert rel(run_filterpy(system, mu, xs, Ps, zs).mu, ours.mu) <= RTOL
    transposed = ImmSystem(system.models, system.pi.T / system.pi.T.sum(axis=1, keepdims=True))
    assert np.abs(run_filterpy(transposed, mu, xs, Ps, zs).mu - ours.mu).max() > 1e-3


@pytest.mark.parametrize("r", range(5))
def test_single_model_equals_filterpy_kalman_filter(scenario_400, r):
    sc = scenario_400
    ours = run_single(sc.system, r, sc.xs0[r], sc.Ps0[r], sc.zs)
    m = sc.system.models[r]
    kf = KalmanFilter(dim_x=sc.system.n, dim_z=sc.system.d)
    kf.F, kf.Q, kf.H, kf.R = np.array(m.F), np.array(m.Q), np.array(m.H), np.array(m.R)
    kf.x, kf.P = sc.xs0[r].copy(), sc.Ps0[r].copy()
    xs, Ps = [], []
    for z in sc.zs:
        kf.predict()
        kf.update(z)
        xs.append(kf.x.copy())
        Ps.append(kf.P.copy())
    assert rel(ours.x, xs, 1) <= RTOL
    assert rel(ours.P, Ps, (1, 2)) <= RTOL


def test_single_model_is_the_imm_sure_of_it():
    """With mu0 = e_r and switching 1e-200 likely, the IMM's model r mixes in nothing (its
    weights round to exactly 1 and 0) and is the single-model filter."""
    sc = scenario.satlink(100)  # clear sky throughout: no other model gains 200 decades
    r, Rm, eps = scenario.TROPO, sc.system.R, 1e-200
    pi = np.full((Rm, Rm), eps / (Rm - 1))
    np.fill_diagonal(pi, 1 - eps)
    imm = run_reference(ImmSystem(sc.system.models, pi), np.eye(Rm)[r], sc.xs0, sc.Ps0, sc.zs)
    single = run_single(sc.system, r, sc.xs0[r], sc.Ps0[r], sc.zs)
    assert np.all(imm.mu[:, r] == 1.0)
    np.testing.assert_allclose(imm.xs[:, r], single.x, rtol=1e-15)
    np.testing.assert_allclose(imm.Ps[:, r], single.P, rtol=1e-15)


# ------------------------------------------------------------------ checks
def _model(**kw):
    args = dict(name="m", F=np.eye(2), Q=np.eye(2), H=np.ones((1, 2)), R=np.eye(1))
    args.update(kw)
    return ImmModel(**args)


@pytest.mark.parametrize("kw, match", [
    (dict(F=np.ones((2, 3))), "F must be square"),
    (dict(F=np.ones(2)), "F must be a 2-D"),
    (dict(Q=np.eye(3)), "Q must be a 2 x 2"),
    (dict(Q=[[1.0, 0.5], [0.0, 1.0]]), "Q must be symmetric"),
    (dict(H=np.ones((1, 3))), "H must have n = 2"),
    (dict(R=np.eye(2)), "R must be a 1 x 1"),
    (dict(R=[[np.nan]]), "R must be finite"),
])
def test_model_checks(kw, match):
    with pytest.raises(ValueError, match=match):
        _model(**kw)


def test_model_is_frozen_and_read_only():
    m = _model()
    with pytest.raises(AttributeError):
        m.F = np.eye(2)
    with pytest.raises(ValueError, match="read-only"):
        m.F[0, 0] = 2.0
    assert (m.n, m.d) == (2, 1)


@pytest.mark.parametrize("models, pi, match", [
    ([_model()], [[1.0]], "at least two"),
    ([_model(), "m"], np.eye(2), "at least two"),
    ([_model(), _model(name="b", H=np.ones((2, 2)), R=np.eye(2))], np.eye(2), "'b' has n = 2, d = 2"),
    ([_model(), _model()], np.eye(3), "pi must be a 2 x 2"),
    ([_model(), _model()], [[1.2, -0.2], [0.5, 0.5]], "non-negative"),
    ([_model(), _model()], [[0.9, 0.2], [0.5, 0.5]], "sum to 1"),
])
def test_system_checks(models, pi, match):
    with pytest.raises(ValueError, match=match):
        ImmSystem(models, pi)


def test_system_properties():
    s = scenario.system()
    assert (s.n, s.d, s.R) == (6, 2, 5)
    assert s.names == tuple(c.name for c in scenario.CONDITIONS)


def test_step_checks():
    s = ImmSystem([_model(), _model(name="b")], np.eye(2))
    mu, xs, Ps, z = np.array([0.5, 0.5]), np.zeros((2, 2)), np.array([np.eye(2)] * 2), [0.0]
    imm_step(s, mu, xs, Ps, z)
    with pytest.raises(ValueError, match="mu must be a 1-D vector of length 2"):
        imm_step(s, [1.0], xs, Ps, z)
    with pytest.raises(ValueError, match="mu must be finite and non-negative"):
        imm_step(s, [1.5, -0.5], xs, Ps, z)
    with pytest.raises(ValueError, match=r"xs must be of shape \(2, 2\)"):
        imm_step(s, mu, np.zeros(2), Ps, z)
    with pytest.raises(ValueError, match="Ps must be"):
        imm_step(s, mu, xs, np.eye(2), z)
    with pytest.raises(ValueError, match="z must be"):
        imm_step(s, mu, xs, Ps, [0.0, 0.0])
    with pytest.raises(ValueError, match="model 'b' has predicted probability c_j = 0.0"):
        imm_step(s, [1.0, 0.0], xs, Ps, z)
    with pytest.raises(ValueError, match=r"zs must be of shape \(T, 1\)"):
        run_reference(s, mu, xs, Ps, [0.0, 1.0])
    with pytest.raises(ValueError, match="r must be a model index 0..1"):
        run_single(s, 2, xs[0], Ps[0], [[0.0]])
