"""The UKF step programs, run by the bit-exact golden model, against float64 numpy evaluations
of the chapter's equations; the simplex constants; the fault status."""

from fractions import Fraction

import numpy as np
import pytest

from kfgen.hdl.linalg.program import Copy, Dot
from kfgen.hdl.ukf.params import UkfParams
from kfgen.hdl.ukf.programs import build_ukf, simplex_rows
from kfgen.sim.linalg.exec import from_words, run, to_words


def ukf_programs(sizes, w0=0.0, fmt="binary32"):
    """The UKF's programs for ``sizes`` (n, nw, nv, m)."""
    n, nw, nv, m = sizes
    return build_ukf(UkfParams(states=n, observations=m, process_noise=nw, measurement_noise=nv, w0=w0,
                               format=fmt))

TOL = {"binary32": 2e-5, "binary64": 1e-12}


def sigma_matrix(M, w0):
    """sigma (M x (M + 2)) and the weights in float64, from (5)-(7)."""
    W1 = (1 - w0) / (M + 1)
    s = np.zeros((M, M + 2))
    for j in range(1, M + 1):
        q = 1 / np.sqrt(j * (j + 1) * W1)
        s[j - 1, 1:j + 1] = -q
        s[j - 1, j + 1] = j * q
    W = np.full(M + 2, W1)
    W[0] = w0
    return s, W


class Buffer:
    def __init__(self, ukf):
        self.ukf, self.lay, self.fmt = ukf, ukf.layout, ukf.fmt
        self.mem = self.lay.initial_memory()

    def put(self, name, arr):
        r = self.lay[name]
        w = to_words(self.fmt, np.ravel(arr))
        assert len(w) == r.size, (name, len(w), r.size)
        self.mem[r.base:r.base + r.size] = w
        return np.array(from_words(self.fmt, w)).reshape(r.rows, r.cols)

    def get(self, name):
        r = self.lay[name]
        return np.array(from_words(self.fmt, self.mem[r.base:r.base + r.size])).reshape(r.rows, r.cols)


def spd(rng, k, scale):
    A = rng.normal(size=(k, k))
    return scale * (A @ A.T / k + 0.5 * np.eye(k))


def relerr(a, b):
    return np.max(np.abs(a - b)) / np.max(np.abs(b))


@pytest.mark.parametrize("sizes,w0,fmt", [
    ((2, 1, 1, 1), 0.0, "binary32"),
    ((2, 2, 1, 1), 0.3, "binary64"),
    ((3, 3, 2, 2), 0.2, "binary32"),
    ((7, 6, 7, 6), 0.0, "binary32"),
    ((7, 6, 7, 6), 0.5, "binary64"),
])
def test_iteration_matches_float64(sizes, w0, fmt):
    rng = np.random.default_rng(sum(sizes) + int(10 * w0))
    n, nw, nv, m = sizes
    ukf = ukf_programs(sizes, w0, fmt)
    M, N = ukf.params.M, ukf.params.N
    buf = Buffer(ukf)
    x = buf.put("x", rng.normal(size=n))[:, 0]
    P = buf.put("P", spd(rng, n, 1.0))
    Q = buf.put("Q", spd(rng, nw, 0.1))
    R = buf.put("R", spd(rng, nv, 0.2))
    st = run(ukf.sig_gen, buf.mem)
    assert not st.pivot and not st.nan
    # sig_gen reads the lower triangles: the float64 P^a is built from them (4)
    sym = lambda A: np.tril(A) + np.tril(A, -1).T  # noqa: E731
    Pa = np.zeros((M, M))
    for A, b in zip((P, Q, R), ((0, n), (n, n + nw), (n + nw, M))):
        Pa[b[0]:b[1], b[0]:b[1]] = sym(A)
    sig, W = sigma_matrix(M, w0)
    chi64 = np.concatenate([x, np.zeros(nw + nv)])[:, None] + np.linalg.cholesky(Pa) @ sig  # (8)
    chi = buf.get("sigma_points").T
    assert relerr(chi, chi64) < TOL[fmt]
    # a mildly nonlinear f and a linear h with additive noise, in float64 on the core's words
    F = np.eye(n) + 0.1 * rng.normal(size=(n, n))
    fx = F @ chi[:n] + 0.05 * np.sin(chi[:n])
    fx[:min(n, nw)] += chi[n:n + min(n, nw)]
    chif = buf.put("sigma_points_f", fx.T).T
    assert not run(ukf.predict, buf.mem).nan
    xm = chif @ W  # (10)
    res = chif - xm[:, None]
    Pm = (res * W) @ res.T  # (11)
    assert relerr(buf.get("x")[:, 0], xm) < TOL[fmt]
    assert relerr(buf.get("P"), Pm) < TOL[fmt]
    assert np.array_equal(buf.get("P"), buf.get("P").T)  # one triangle, mirrored
    H = rng.normal(size=(m, n))
    hz = H @ chif
    hz[:min(m, nv)] += chi[n + nw:n + nw + min(m, nv)]
    Zh = buf.put("sigma_points_h", hz.T).T
    zt = buf.put("z", rng.normal(size=m))[:, 0]
    assert not run(ukf.update, buf.mem).pivot
    zm = Zh @ W  # (13)
    rz = Zh - zm[:, None]
    S = (rz * W) @ rz.T  # (14)
    Pxz = (res * W) @ rz.T  # (15)
    K = Pxz @ np.linalg.inv(S)  # (16)
    assert relerr(buf.get("x")[:, 0], xm + K @ (zt - zm)) < TOL[fmt]  # (17)
    assert relerr(buf.get("P"), Pm - Pxz @ K.T) < TOL[fmt]  # (19)
    assert np.array_equal(buf.get("P"), buf.get("P").T)


@pytest.mark.parametrize("M,w0", [(3, 0.0), (20, 0.0), (20, 0.5)])
def test_simplex_set(M, w0):
    """The rows c_j, d_j rebuild a sigma with sum W sigma = 0 and sum W sigma sigma^T = I."""
    W1, c, d = simplex_rows(M, w0)
    assert W1 == (1 - Fraction(w0)) / (M + 1)
    sig = np.zeros((M, M + 2))
    for j in range(M):
        sig[j, 1:j + 2] = float(c[j])
        sig[j, j + 2] = float(d[j])
    ref, W = sigma_matrix(M, w0)
    np.testing.assert_allclose(sig, ref, rtol=1e-15)
    np.testing.assert_allclose(sig @ W, 0, atol=1e-12)
    np.testing.assert_allclose((sig * W) @ sig.T, np.eye(M), atol=1e-12)


def test_pivot_and_nan_status():
    ukf = ukf_programs((2, 1, 1, 1), 0.0, "binary32")
    buf = Buffer(ukf)
    buf.put("P", [[1.0, 2.0], [2.0, 1.0]])  # indefinite: D_1 = -3
    buf.put("Q", [[1.0]])
    buf.put("R", [[1.0]])
    assert run(ukf.sig_gen, buf.mem).pivot
    buf.put("P", [[1.0, 0.0], [0.0, 1.0]])
    buf.put("R", [[0.0]])  # a zero pivot
    assert run(ukf.sig_gen, buf.mem).pivot
    buf.put("R", [[float("nan")]])
    assert run(ukf.sig_gen, buf.mem).pivot
    buf.put("R", [[1.0]])
    assert not run(ukf.sig_gen, buf.mem).pivot
    buf.put("sigma_points_f", np.ones((6, 2)))
    assert not run(ukf.predict, buf.mem).nan
    f = np.ones((6, 2))
    f[3, 1] = float("inf")
    buf.put("sigma_points_f", f)
    assert run(ukf.predict, buf.mem).nan


def test_program_rules():
    ukf = ukf_programs((2, 1, 1, 1))
    one = ukf.layout["one"](0, 0)
    with pytest.raises(ValueError, match="constant"):
        ukf.sig_gen.emit(Copy(one, 0))
    with pytest.raises(ValueError, match="at least one term"):
        Dot(0, 1)
    with pytest.raises(ValueError, match="outside"):
        ukf.sig_gen.emit(Copy(ukf.layout.size, 0))
