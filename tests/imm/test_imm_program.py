"""The IMM program, executed by the golden model, against a float64 evaluation of its
equations."""

import math

import numpy as np
import pytest

from kfgen.hdl.imm.programs import ImmSizes, build_imm
from kfgen.sim.linalg.exec import from_words, run, to_words


def spd(rng, k, scale=1.0):
    A = rng.normal(size=(k, k))
    return scale * (A @ A.T / k + np.eye(k))


@pytest.mark.parametrize("R,n,d,fmt", [(2, 2, 1, "binary32"), (3, 4, 2, "binary32"), (5, 6, 2, "binary64"),
                                       (2, 3, 3, "binary64"), (3, 5, 4, "binary64")])
def test_program_matches_float64(R, n, d, fmt):
    """The IMM program, executed by the golden model, against a literal float64 evaluation of
    the mixing, the R Kalman filters and the combination (numpy's inverse and determinant):
    to the format's precision, and exactly symmetric covariances."""
    rng = np.random.default_rng(R * 100 + n * 10 + d)
    progs = build_imm(ImmSizes(R, n, d), fmt)
    lay, f = progs.layout, progs.fmt
    pi = rng.uniform(0.05, 1, (R, R)) + np.eye(R) * R
    pi /= pi.sum(1, keepdims=True)
    val = {"pi": pi, "mu": rng.dirichlet(np.ones(R)),
           "F": np.vstack([np.eye(n) + 0.1 * rng.normal(size=(n, n)) for _ in range(R)]),
           "Q": np.vstack([spd(rng, n, 0.1) for _ in range(R)]),
           "H": rng.normal(size=(R * d, n)),
           "R": np.vstack([spd(rng, d) for _ in range(R)]),
           "x_model": rng.normal(size=(R, n)),
           "P_model": np.vstack([spd(rng, n) for _ in range(R)]),
           "z": rng.normal(size=d)}
    mem = lay.initial_memory()
    for name, a in val.items():
        r = lay[name]
        words = to_words(f, np.ravel(a))
        mem[r.base:r.base + r.size] = words
        val[name] = np.array(from_words(f, words)).reshape(np.shape(a))  # what the core reads
    st = run(progs.iterate, mem)
    assert not (st.pivot or st.nan)

    def get(name):
        r = lay[name]
        return np.array(from_words(f, mem[r.base:r.base + r.size])).reshape(r.rows, r.cols)

    blk = lambda a, j, k: a[j * k:(j + 1) * k]  # noqa: E731
    pi, mu, xs = val["pi"], val["mu"], val["x_model"]
    Ps = [blk(val["P_model"], i, n) for i in range(R)]
    c = pi.T @ mu
    W = pi * mu[:, None] / c
    x_out, P_out, lik = [], [], []
    for j in range(R):
        x0 = W[:, j] @ xs
        P0 = sum(W[i, j] * (Ps[i] + np.outer(xs[i] - x0, xs[i] - x0)) for i in range(R))
        F, Q, H, Rm = blk(val["F"], j, n), blk(val["Q"], j, n), blk(val["H"], j, d), blk(val["R"], j, d)
        xp, Pp = F @ x0, F @ P0 @ F.T + Q
        y = val["z"] - H @ xp
        S = H @ Pp @ H.T + Rm
        K = Pp @ H.T @ np.linalg.inv(S)
        x_out.append(xp + K @ y)
        P_out.append(Pp - K @ H @ Pp)
        lik.append(math.exp(-0.5 * y @ np.linalg.solve(S, y)) / math.sqrt((2 * math.pi) ** d * np.linalg.det(S)))
    mu_new = c * np.array(lik) / (c @ np.array(lik))
    x = mu_new @ np.array(x_out)
    P = sum(mu_new[j] * (P_out[j] + np.outer(x_out[j] - x, x_out[j] - x)) for j in range(R))
    eps = 1e-4 if fmt == "binary32" else 1e-11
    assert np.allclose(get("mu").ravel(), mu_new, rtol=eps, atol=eps)
    assert np.allclose(get("x_model"), np.array(x_out), rtol=eps, atol=eps * 10)
    assert np.allclose(get("P_model"), np.vstack(P_out), rtol=eps, atol=eps * 10)
    assert np.allclose(get("x").ravel(), x, rtol=eps, atol=eps * 10)
    assert np.allclose(get("P"), P, rtol=eps, atol=eps * 10)
    for name in ("P", "P_model"):
        a = get(name)
        for j in range(a.shape[0] // n):
            assert np.array_equal(blk(a, j, n), blk(a, j, n).T), name
