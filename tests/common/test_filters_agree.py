"""Two cores' filters agree where they must: an IMM of two identical models is the linear
Kalman filter of that model. Here, not in ``tests/kf`` or ``tests/imm``, because it imports
both cores (no core's tests import another core's)."""

import numpy as np

from kfgen.hdl.kf.params import KfParams
from kfgen.hdl.kf.steps import programs
from kfgen.sim.imm.golden import run_golden as imm_golden
from kfgen.sim.imm.reference import ImmModel, ImmSystem
from kfgen.sim.kf.reference import buffer_values, run_golden, run_reference


def test_imm_of_identical_models_is_the_kf():
    """n = 4, d = m = 2, 20 iterations, both golden models in binary64 (the IMM inverts S by
    Schur complements, the KF factors it by LDL^T): the IMM's combined x and P, and each
    model's, equal the KF's within 1e-12 of their scale; the model probabilities stay at
    the prior's; both within 1e-12 of the float64 reference."""
    rng = np.random.default_rng(5)
    n, m, T = 4, 2, 20
    F = np.eye(n) + 0.1 * np.eye(n, k=1)
    H = rng.standard_normal((m, n))
    g = rng.standard_normal((n, n))
    Q = 0.01 * (g @ g.T + n * np.eye(n))
    R = np.array([[0.2, 0.05], [0.05, 0.3]])
    x0, P0 = rng.standard_normal(n), np.eye(n) * 0.5
    zs = rng.standard_normal((T, m))
    model = ImmModel("same", F, Q, H, R)
    system = ImmSystem((model, ImmModel("same too", F, Q, H, R)), np.array([[0.9, 0.1], [0.2, 0.8]]))
    imm = imm_golden(system, np.array([0.5, 0.5]), np.array([x0, x0]), np.array([P0, P0]), zs, "binary64")
    progs = programs(KfParams(states=n, measurements=m, format="binary64"))
    kf = run_golden(progs, buffer_values(progs, F, H, x0, Q=Q, R=R, P0=P0), zs)
    ref = run_reference(F, H, Q, R, x0, P0, zs)
    assert not imm["flags"].any() and not kf["flags"].any()
    for k in range(T):
        x, P = kf["x"][k, :, 0], kf["P"][k]
        sx, sP = np.abs(x).max(), np.abs(P).max()
        assert np.abs(imm["x"][k] - x).max() <= 1e-12 * sx, k
        assert np.abs(imm["P"][k] - P).max() <= 1e-12 * sP, k
        for r in range(2):
            assert np.abs(imm["xs"][k, r] - x).max() <= 1e-12 * sx, (k, r)
        assert np.abs(x - ref.x_post[k]).max() <= 1e-12 * sx and np.abs(P - ref.P_post[k]).max() <= 1e-12 * sP
    # identical likelihoods: mu is the prior's stationary distribution's march, pi^T mu
    mu = np.array([0.5, 0.5])
    for k in range(T):
        mu = system.pi.T @ mu
        np.testing.assert_allclose(imm["mu"][k], mu, rtol=1e-12)
