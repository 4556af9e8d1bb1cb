"""The EKF's iteration program (kfgen.hdl.ekf.programs) run by the golden executor against the
float64 reference (kfgen.sim.ekf.reference), whose Jacobians are computed independently (by
hand on the tracker, by finite differences on the nanosatellite); the reference against
filterpy's ExtendedKalmanFilter; err_pivot; P exactly symmetric."""

import numpy as np
import pytest
from ekf_jacobians import TrackerJacobians

from kfgen.hdl.engine.app import load_app
from kfgen.hdl.ekf.params import EkfParams
from kfgen.hdl.ekf.steps import programs
from kfgen.sim.ekf.golden import run_golden
from kfgen.sim.ekf.reference import run_reference


def _params(app, spec, **kw):
    return EkfParams(spec, app.n, app.m, app.nw, app.nv, app.nu, **kw)


def _run(app, models, spec, steps, seed=3, R=None, **kw):
    sc = app.scenario(steps, seed)
    us = np.zeros((steps, 0)) if sc.u is None else sc.u
    progs = programs(_params(app, spec, **kw), models)
    golden = run_golden(progs, app.x0, app.P0, app.Q, app.R if R is None else R, us, sc.z)
    return sc, us, golden


def test_tracker_golden_is_the_reference_with_analytic_jacobians(tracker):
    app, models = tracker
    sc, us, g = _run(app, models, "tracker:Tracker", 6, format="binary64")
    ref = run_reference(app, us, sc.z, TrackerJacobians(app))
    assert not g["flags"].any()
    for key in ("x_prior", "x", "H"):
        np.testing.assert_allclose(g[key], ref[key], rtol=1e-12, err_msg=key)
    for key in ("P_prior", "P"):
        scale = np.abs(ref[key]).max(axis=(1, 2), keepdims=True)
        np.testing.assert_allclose(g[key] / scale, ref[key] / scale, rtol=0, atol=1e-12, err_msg=key)


def test_nanosat_golden_is_the_reference_with_finite_differences(nanosat):
    app, models = nanosat
    sc, us, g = _run(app, models, "nanosat:Nanosat", 5, format="binary64")
    ref = run_reference(app, us, sc.z)
    assert not g["flags"].any()
    np.testing.assert_allclose(g["x"], ref["x"], rtol=0, atol=1e-7)
    scale = np.abs(ref["P"]).max(axis=(1, 2), keepdims=True)
    np.testing.assert_allclose(g["P"] / scale, ref["P"] / scale, rtol=0, atol=1e-6)


@pytest.mark.parametrize("fmt", ["binary64", "binary32"])
def test_covariance_exactly_symmetric(tracker, fmt):
    app, models = tracker
    _, _, g = _run(app, models, "tracker:Tracker", 8, format=fmt)
    assert not g["flags"].any()
    for key in ("P", "P_prior"):
        assert np.array_equal(g[key], np.swapaxes(g[key], 1, 2)), key


def test_binary32_tracks_the_reference(nanosat):
    app, models = nanosat
    sc, us, g = _run(app, models, "nanosat:Nanosat", 40, format="binary32")
    ref = run_reference(app, us, sc.z)
    assert not g["flags"].any()
    np.testing.assert_allclose(g["x"][:, :4], ref["x"][:, :4], atol=1e-4)


def test_indefinite_innovation_covariance_raises_err_pivot(tracker):
    app, models = tracker
    _, _, g = _run(app, models, "tracker:Tracker", 2, R=-1e9 * np.eye(2), format="binary64")
    assert (g["flags"] & 1).all()


def test_reference_is_filterpy_extended_kalman_filter(tracker):
    from filterpy.kalman import ExtendedKalmanFilter  # deferred: filterpy is the third party only here

    app, _ = tracker
    hand = TrackerJacobians(app)
    sc = app.scenario(20, 11)
    us = np.zeros((20, 0))
    ref = run_reference(app, us, sc.z, hand)
    kf = ExtendedKalmanFilter(dim_x=4, dim_z=2)
    kf.x, kf.P = app.x0.reshape(4, 1).copy(), app.P0.copy()
    kf.F, kf.Q, kf.R = hand.F, hand.L @ app.Q @ hand.L.T, app.R
    xs, Ps = [], []
    for z in sc.z:
        kf.predict()
        kf.update(z.reshape(2, 1), lambda x: hand.hx(x.ravel())[0],
                  lambda x: app.h(x.ravel(), np.zeros(2)).reshape(2, 1))
        xs.append(kf.x.ravel().copy())
        Ps.append(kf.P.copy())
    np.testing.assert_allclose(ref["x"], np.array(xs), rtol=1e-9)
    scale = np.abs(ref["P"]).max(axis=(1, 2), keepdims=True)
    np.testing.assert_allclose(ref["P"] / scale, np.array(Ps) / scale, rtol=0, atol=1e-9)


#: A user's own application: a control input, sin in f and h (their derivatives take the
#: cosine unit), and a second measurement that no state reaches (a zero row of H).
PENDULUM = """
import numpy as np
from kfgen.hdl.engine.app import UkfApplication


class Pendulum(UkfApplication):
    n, nw, nv, m, nu, dt = 2, 1, 2, 2, 1, 0.05
    x0 = np.array([0.3, 0.0])
    P0 = np.eye(2) * 0.1
    Q = np.eye(1) * 1e-3
    R = np.diag([1e-2, 1e-1])

    def f(self, x, w, u, dt):
        return np.array([x[0] + dt * x[1], x[1] + dt * (u[0] - 9.81 * np.sin(x[0])) + w[0]])

    def h(self, x, v):
        return np.array([np.sin(x[0]) + v[0], 1.0 + v[1]])
"""


def test_own_application_with_a_zero_row_of_h(tmp_path):
    (tmp_path / "pend_u.py").write_text(PENDULUM)
    params = EkfParams(f"{tmp_path}/pend_u.py:Pendulum", format="binary64")
    app = load_app(params.app)
    models = params.models
    assert models.H.pattern.tolist() == [[True, False], [False, False]]
    progs = programs(params)
    assert "zero" in progs.layout.regions and "cos" in progs.iteration.units
    rng = np.random.default_rng(4)
    us, zs = rng.normal(0, 1, (6, 1)), np.c_[rng.normal(0.3, 0.1, 6), rng.normal(1, 0.3, 6)]
    g = run_golden(progs, app.x0, app.P0, app.Q, app.R, us, zs)
    ref = run_reference(app, us, zs)
    assert not g["flags"].any()
    np.testing.assert_allclose(g["x"], ref["x"], rtol=0, atol=1e-8)
    np.testing.assert_allclose(g["P"], ref["P"], rtol=0, atol=1e-8)
