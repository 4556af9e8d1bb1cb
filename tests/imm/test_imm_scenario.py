"""The satellite-link scenario (kfgen.sim.imm.scenario): what its docstring promises, and that
the float64 IMM identifies the channel's condition and beats every single model."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pytest

from kfgen.sim.imm import scenario
from kfgen.sim.imm.reference import imm_step, run_reference, run_single
from kfgen.sim.imm.scenario import CONDITIONS, satlink


def segments(condition):
    """(condition, start, stop) of each stay."""
    starts = np.flatnonzero(np.diff(np.r_[-1, condition]) != 0)
    return [(int(condition[s]), int(s), int(e)) for s, e in zip(starts, np.r_[starts[1:], condition.size])]


def test_deterministic_per_seed():
    a, b, c = satlink(600, 11), satlink(600, 11), satlink(600, 12)
    for name in ("truth", "condition", "zs", "mu0", "xs0", "Ps0"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert not np.array_equal(a.zs, c.zs)
    assert not np.array_equal(a.condition, c.condition)
    # a longer run of the same seed starts with the same schedule
    assert np.array_equal(satlink(1200, 11).condition[:600][:segments(a.condition)[-1][1]],
                          a.condition[:segments(a.condition)[-1][1]])


def test_shapes_and_start():
    sc = satlink(300)
    assert sc.truth.shape == (300, 6) and sc.zs.shape == (300, 2) and sc.condition.shape == (300,)
    assert sc.mu0.shape == (5,) and sc.xs0.shape == (5, 6) and sc.Ps0.shape == (5, 6, 6)
    assert sc.mu0.sum() == pytest.approx(1.0)
    assert sc.names == ("clear sky", "rain fade", "ionospheric scintillation",
                        "tropospheric scintillation", "multipath fading")
    assert sc.dt == scenario.DT == 1.0 and sc.t[-1] == 299.0
    assert sc.condition[0] == scenario.CLEAR
    assert satlink(1).truth.shape == (1, 6)
    for bad in (0, -3, 2.5):
        with pytest.raises(ValueError, match="steps must be a positive integer"):
            satlink(bad)


def test_models_and_transition_matrix():
    s = scenario.system()
    F = np.kron(np.eye(2), scenario.ca_transition())
    for m, c in zip(s.models, CONDITIONS):
        assert m.name == c.name
        np.testing.assert_array_equal(m.F, F)
        np.testing.assert_array_equal(m.H, [[1, 0, 0, 0, 0, 0], [0, 0, 0, 1, 0, 0]])
        np.testing.assert_allclose(m.R, np.diag([0.2 ** 2, 0.3 ** 2]))
        assert np.linalg.eigvalsh(m.Q).min() > 0
        assert m.Q[0, 0] == pytest.approx(c.q_level[0] + c.q_jerk[0] / 20)
        assert m.Q[3, 3] == pytest.approx(c.q_level[1] + c.q_jerk[1] / 20)
        assert m.Q[2, 2] == c.q_jerk[0] and m.Q[5, 5] == c.q_jerk[1]
        assert np.all(m.Q[:3, 3:] == 0)
    assert np.all(np.diag(s.pi) == 0.99)
    np.testing.assert_allclose(s.pi[~np.eye(5, dtype=bool)], 0.0025)


def test_level_noise_follows_the_fluctuation():
    """The documented q_level of each fluctuating condition is within 2 % of the AR(1)'s
    increment variance 2 sigma^2 (1 - rho) plus the wander's 2 sigma_w^2 dt / tau_w."""
    sigma_w, tau_w = scenario.WANDER
    wander = 2 * sigma_w ** 2 * scenario.DT / tau_w
    for c in CONDITIONS:
        for ch in range(2):
            sigma, tau = c.fluctuation[ch]
            want = 2 * sigma ** 2 * (1 - np.exp(-scenario.DT / tau)) + wander
            assert c.q_level[ch] == pytest.approx(want, rel=0.02), (c.name, ch)


def test_schedule_follows_its_rules():
    sc = satlink(20000, 3)
    segs = segments(sc.condition)
    seen = set()
    for (c, s, e), nxt in zip(segs, segs[1:] + [None]):
        lo, hi = CONDITIONS[c].dwell
        if nxt is not None:  # the last stay is cut by the end of the run
            assert lo <= e - s <= hi, (c, s, e)
            assert nxt[0] != c
            if c != scenario.CLEAR:
                seen.add((c, nxt[0]))
    assert len({c for c, _, _ in segs}) == 5
    assert len(seen) == 4 * 4  # every impairment went to clear sky and to each other


def test_truth_follows_the_conditions():
    sc = satlink(20000, 3)
    snr, sir = sc.truth[:, 0], sc.truth[:, 3]
    cond = sc.condition
    # where no condition's effect is left (inside clear-sky stays, after a decay), only the
    # wander: 0.1 dB about the link budget
    quiet = np.zeros(cond.size, dtype=bool)
    for c, s, e in segments(cond):
        if c == scenario.CLEAR:
            quiet[s + 20:e] = True
    assert abs(snr[quiet].mean() - 14.0) < 0.1 and snr[quiet].std() == pytest.approx(0.1, rel=0.3)
    assert abs(sir[quiet].mean() - 20.0) < 0.1 and sir[quiet].std() == pytest.approx(0.1, rel=0.3)
    # rain: fades of 5-12 dB (times the intensity), the SIR sagging by half of it
    rain = cond == scenario.RAIN
    A = 14.0 - snr
    assert 3.0 < np.median(A[rain]) < 12.0 and A[rain].max() > 8.0
    drop = np.polyfit(14.0 - snr[rain], 20.0 - sir[rain], 1)[0]
    assert drop == pytest.approx(0.5, abs=0.05)
    # the rate and acceleration columns are the smooth part's, zero outside rain
    assert np.all(sc.truth[~rain & np.r_[~rain[1:], True] & np.r_[True, ~rain[:-1]], 1] == 0)
    assert np.abs(sc.truth[rain, 1]).max() > 0.1
    # scintillation and multipath: the documented spread about the link budget
    for c, ch, sigma in [(scenario.IONO, 0, 2.5), (scenario.TROPO, 0, 0.8),
                         (scenario.MULTIPATH, 0, 1.5), (scenario.MULTIPATH, 1, 2.0)]:
        x = sc.truth[cond == c, 3 * ch] - (14.0, 20.0)[ch]
        assert x.std() == pytest.approx(sigma, rel=0.15), (c, ch)
    for c in (scenario.IONO, scenario.TROPO):
        assert sir[cond == c].std() < 0.2
    # the measurements: the truth plus the estimator's 0.2 / 0.3 dB
    np.testing.assert_allclose((sc.zs - sc.truth[:, [0, 3]]).std(axis=0), [0.2, 0.3], rtol=0.05)


class Run(NamedTuple):
    mu: np.ndarray  # (T, R)
    x: np.ndarray  # (T, n)
    xs_max: float  # largest |entry| of any state the iterations formed
    diag: tuple  # (smallest, largest) covariance diagonal the iterations formed
    span: float  # largest ratio of largest to smallest diagonal entry within one covariance


@pytest.fixture(scope="module")
def run2000():
    """The default scenario through the reference, step by step so that every covariance an
    iteration forms (mixed, predicted, updated) is seen."""
    sc = satlink()
    mu, xs, Ps = sc.mu0, sc.xs0, sc.Ps0
    mus, x, lo, hi, span, xs_max = [], [], np.inf, 0.0, 0.0, 0.0
    for z in sc.zs:
        s = imm_step(sc.system, mu, xs, Ps, z)
        mu, xs, Ps = s.mu, s.xs, s.Ps
        mus.append(s.mu)
        x.append(s.x)
        for P in (s.P0, s.P_prior, s.Ps):
            d = np.diagonal(P, axis1=-2, axis2=-1)
            lo, hi = min(lo, d.min()), max(hi, d.max())
            span = max(span, float(np.max(d.max(axis=-1) / d.min(axis=-1))))
        xs_max = max(xs_max, *(float(np.abs(v).max()) for v in (s.x0, s.x_prior, s.xs)))
    return sc, Run(np.array(mus), np.array(x), xs_max, (lo, hi), span)


def test_run_is_the_reference_run(run2000):
    sc, run = run2000
    ref = run_reference(sc.system, sc.mu0, sc.xs0, sc.Ps0, sc.zs[:200])
    np.testing.assert_array_equal(run.mu[:200], ref.mu)


def test_imm_identifies_the_condition(run2000):
    """The default scenario (2000 steps, seed 4): the most probable model is the true
    condition at 95.2 % of the steps, and at 92 % or more in every condition."""
    sc, ref = run2000
    rate = scenario.identification(ref.mu, sc.condition)
    assert rate > 0.9, rate
    for c in range(5):
        here = sc.condition == c
        assert scenario.identification(ref.mu[here], sc.condition[here]) > 0.9, CONDITIONS[c].name
    # without the right model in the bank, its condition is not recognised
    assert scenario.identification(np.roll(ref.mu, 1, axis=1), sc.condition) < 0.2


def test_imm_beats_every_single_model(run2000):
    """SNR error over the run: the IMM below every single-model filter, and below the
    measurements' own 0.2 dB."""
    sc, ref = run2000
    def rmse(x):
        return float(np.sqrt(np.mean((x[:, 0] - sc.truth[:, 0]) ** 2)))
    imm = rmse(ref.x)
    singles = [rmse(run_single(sc.system, r, sc.xs0[r], sc.Ps0[r], sc.zs).x) for r in range(5)]
    assert imm < 0.9 * min(singles), (imm, singles)
    assert imm < 0.9 * float(np.sqrt(np.mean((sc.zs[:, 0] - sc.truth[:, 0]) ** 2)))


def test_fits_binary32(run2000):
    """States O(1)-O(10) and covariances that the core's binary32 holds: every diagonal an
    iteration forms within [1e-6, 12] (1.8e-6 and 11.9), spanning less than 4e6 in one matrix
    (3.9e6)."""
    sc, run = run2000
    assert np.abs(sc.truth).max() < 30 and run.xs_max < 30
    assert 1e-6 < run.diag[0] and run.diag[1] < 12
    assert run.span < 4e6
