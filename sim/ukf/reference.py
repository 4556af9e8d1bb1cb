"""Float64 reference of the augmented UKF with the spherical-simplex sigma points.

Written from Soh & Wu's chapter (seed 000, section 2.2 eqs. (1)-(19), section 3 eqs.
(21)-(28)) with numpy's own linear algebra for the products, and the chapter's own
recursions where the chapter gives one (the LDL^T factorisation, the "right divide").
It checks the core's program, not its rounding: the bit-exact golden model is separate.

One filter cycle is the core's three steps:

* ``sig_gen``: augment the state with the noises, x^a = [x; 0; 0] and
  P^a = blockdiag(P, Q, R) (eqs. 3-4), factor P^a = L1 L1^T through LDL^T (eqs. 21-24)
  and draw chi = x^a + L1 sigma, column by column (eq. 8);
* ``predict``: the user's f moves the state part of every sigma point with its
  process-noise part (eq. 9); the weighted mean and covariance of the moved points are the
  prior (eqs. 10-11, computed through the residuals of eqs. 25-28);
* ``update``: the user's h maps the *moved* points (no new draw) with their measurement-noise
  part (eq. 12); then z^, S, Pxz, K = Pxz S^-1 by right division, x and P (eqs. 13-17, 19).

The spherical simplex has one weight for the mean and the covariance (W^(m) = W^(c) = W),
which is how eqs. (25)-(28) and the core's mean/covariance unit use it.

Shapes are always 1-D vectors and 2-D matrices; sigma points are the *columns* of an
``(M, N)`` array, as in the chapter (filterpy stores them as rows).
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import numpy as np

__all__ = [
    "PivotError", "simplex_weights", "simplex_coefficients", "ldl", "sqrt_ldl",
    "forward_substitution", "back_substitution", "right_divide", "augment", "sigma_points",
    "Prediction", "predict", "Correction", "update", "AugmentedUKF", "lower_factor", "SquareRootUKF",
]


class PivotError(np.linalg.LinAlgError):
    """An LDL^T pivot D_j is not positive (or is NaN): the matrix is not positive definite.

    The same rule raises the core's ``err_pivot`` status bit.

    Attributes
    ----------
    pivot : int
        Index j (from 0) of the first failing pivot.
    value : float
        D_j as computed.
    """

    def __init__(self, pivot: int, value: float):
        self.pivot = pivot
        self.value = value
        super().__init__(f"matrix is not positive definite: pivot D_{pivot} = {value!r} "
                         f"is not > 0")


def _check_w0(W0) -> float:
    # W0 = 1 would leave W1 = 0 and eq. (6) divides by sqrt(2 W1).
    if not 0.0 <= W0 < 1.0:
        raise ValueError(f"W0 must satisfy 0 <= W0 < 1, not {W0!r}")
    return float(W0)


def _check_size(name: str, value, minimum: int = 1) -> int:
    if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, not {value!r}")
    return int(value)


def simplex_weights(M: int, W0: float) -> np.ndarray:
    """The N = M + 2 weights of the spherical simplex set: [W0, W1, ..., W1] (eq. 5).

    W1 = (1 - W0) / (M + 1), so the weights sum to one.
    """
    M = _check_size("M", M)
    W0 = _check_w0(W0)
    W = np.full(M + 2, (1.0 - W0) / (M + 1))
    W[0] = W0
    return W


def simplex_coefficients(M: int, W0: float) -> np.ndarray:
    """The M x N spherical-simplex coefficient matrix sigma (eqs. 6-7).

    Column i is sigma_i^M. The sequence starts in one dimension with [0], -1/sqrt(2 W1),
    +1/sqrt(2 W1) (eq. 6) and grows one row per dimension j = 2..M (eq. 7): the existing
    columns keep their entries, point 0 gets 0, points 1..j get -1/sqrt(j (j+1) W1), and a new
    point j+1 is zero above and j/sqrt(j (j+1) W1) in the new row.

    With the weights of :func:`simplex_weights`, sum_i W_i sigma_i = 0 and
    sum_i W_i sigma_i sigma_i^T = I_M.
    """
    W1 = simplex_weights(M, W0)[1]
    a1 = 1.0 / np.sqrt(2.0 * W1)
    sigma = np.array([[0.0, -a1, a1]])  # eq. (6)
    for j in range(2, M + 1):  # eq. (7)
        a = 1.0 / np.sqrt(j * (j + 1) * W1)
        grown = np.zeros((j, j + 2))
        grown[:j - 1, :j + 1] = sigma
        grown[j - 1, 1:j + 1] = -a
        grown[j - 1, j + 1] = j * a
        sigma = grown
    return sigma


def _square(name: str, A) -> np.ndarray:
    A = np.asarray(A, dtype=np.float64)
    if A.ndim != 2 or A.shape[0] != A.shape[1]:
        raise ValueError(f"{name} must be a square 2-D matrix, not of shape {A.shape}")
    return A


def ldl(A) -> tuple[np.ndarray, np.ndarray]:
    """LDL^T factorisation A = L D L^T by the chapter's recursion (eqs. 21, 23, 24).

    Column by column, with F_ij = L_ij D_j standing for the divided-out products:
    D_j = A_jj - sum_{k<j} F_jk^2 / D_k, then F_ij = A_ij - sum_{k<j} L_ik F_jk for i > j and
    L_ij = F_ij / D_j. Only the lower triangle of A is read (A is taken as symmetric).

    Returns
    -------
    L : (n, n) unit lower-triangular matrix.
    d : (n,) the diagonal of D.

    Raises
    ------
    PivotError
        When a pivot is not > 0 (D_j <= 0 or NaN), the rule behind the core's ``err_pivot``.
    """
    A = _square("A", A)
    n = A.shape[0]
    L = np.eye(n)
    F = np.zeros((n, n))
    d = np.zeros(n)
    for j in range(n):
        d[j] = A[j, j] - np.sum(F[j, :j] ** 2 / d[:j])  # eq. (24)
        if not d[j] > 0.0:
            raise PivotError(j, float(d[j]))
        for i in range(j + 1, n):
            F[i, j] = A[i, j] - L[i, :j] @ F[j, :j]  # eq. (23)
            L[i, j] = F[i, j] / d[j]
    return L, d


def sqrt_ldl(A) -> np.ndarray:
    """The matrix square root L1 = L2 sqrt(D) of eq. (22), so that A = L1 L1^T (eq. 20)."""
    L, d = ldl(A)
    return L * np.sqrt(d)


def forward_substitution(L, B) -> np.ndarray:
    """Solve L Y = B for Y, with L unit lower triangular (forward elimination)."""
    L = _square("L", L)
    Y = np.array(B, dtype=np.float64)
    for i in range(L.shape[0]):
        Y[i] -= L[i, :i] @ Y[:i]
    return Y


def back_substitution(U, B) -> np.ndarray:
    """Solve U X = B for X, with U unit upper triangular (back substitution)."""
    U = _square("U", U)
    X = np.array(B, dtype=np.float64)
    for i in reversed(range(U.shape[0])):
        X[i] -= U[i, i + 1:] @ X[i + 1:]
    return X


def right_divide(B, A) -> np.ndarray:
    """B A^-1 for a symmetric positive-definite A, without forming the inverse (eq. 16).

    X A = B is A X^T = B^T; with A = L D L^T: forward elimination through L, division by
    the pivots D_j, back substitution through L^T.

    Raises
    ------
    PivotError
        When A is not positive definite.
    """
    L, d = ldl(A)
    B = np.asarray(B, dtype=np.float64)
    if B.ndim != 2 or B.shape[1] != L.shape[0]:
        raise ValueError(f"B must be a 2-D matrix with {L.shape[0]} columns, not of shape "
                         f"{B.shape}")
    Y = forward_substitution(L, B.T) / d[:, np.newaxis]
    return back_substitution(L.T, Y).T


def augment(x, P, Q, R) -> tuple[np.ndarray, np.ndarray]:
    """The augmented state x^a = [x; 0; 0] and covariance blockdiag(P, Q, R) (eqs. 3-4)."""
    x = np.asarray(x, dtype=np.float64)
    blocks = [_square("P", P), _square("Q", Q), _square("R", R)]
    if x.shape != (blocks[0].shape[0],):
        raise ValueError(f"x must be a 1-D vector of length {blocks[0].shape[0]}, not of shape "
                         f"{x.shape}")
    M = sum(b.shape[0] for b in blocks)
    xa = np.zeros(M)
    xa[:x.size] = x
    Pa = np.zeros((M, M))
    at = 0
    for b in blocks:
        Pa[at:at + b.shape[0], at:at + b.shape[0]] = b
        at += b.shape[0]
    return xa, Pa


def sigma_points(x, P, Q, R, W0: float) -> np.ndarray:
    """The N = M + 2 augmented sigma points chi = x^a + L1 sigma, as columns (eq. 8).

    M = len(x) + len(Q) + len(R). Rows 0..n-1 of chi are the state parts chi^x, the next nw
    rows the process-noise parts chi^w, the last nv rows the measurement-noise parts chi^v.

    Raises
    ------
    PivotError
        When blockdiag(P, Q, R) is not positive definite.
    """
    xa, Pa = augment(x, P, Q, R)
    return xa[:, np.newaxis] + sqrt_ldl(Pa) @ simplex_coefficients(xa.size, W0)


def _mean_and_residuals(W, X) -> tuple[np.ndarray, np.ndarray]:
    mean = X @ W  # eq. (25)
    return mean, X - mean[:, np.newaxis]  # the "sigma point residuals" of eq. (27)


def _weighted_outer(W, A, B) -> np.ndarray:
    return (A * W) @ B.T  # sum_k W_k A_ik B_jk, eq. (28)


def _apply(fn: Callable, name: str, length: int, columns) -> np.ndarray:
    out = np.column_stack([np.asarray(fn(*c), dtype=np.float64) for c in zip(*columns)])
    if out.shape[0] != length or out.ndim != 2:
        raise ValueError(f"{name} must return 1-D vectors of length {length}, not {out.shape[:-1]}")
    return out


class Prediction(NamedTuple):
    """The predict step's results."""
    x: np.ndarray  #: x^- (eq. 10)
    P: np.ndarray  #: P^- (eq. 11)
    sigma_x: np.ndarray  #: the moved state sigma points chi^x_{k|k-1}, (n, N) (eq. 9)
    residual: np.ndarray  #: chi^x_{k|k-1} - x^-, (n, N) (eq. 27), reused by the update


def predict(chi, f: Callable, W, n: int, nw: int, u=None, dt=None) -> Prediction:
    """Move the augmented sigma points through f and take their mean and covariance.

    Parameters
    ----------
    chi : (M, N) augmented sigma points (:func:`sigma_points`).
    f : ``f(x, w, u, dt) -> x'``, the process model on one point's state and noise parts.
    W : (N,) weights (:func:`simplex_weights`).
    n, nw : lengths of the state and process-noise parts.
    u, dt : passed to f unchanged.
    """
    chi = np.asarray(chi, dtype=np.float64)
    N = chi.shape[1]
    sigma_x = _apply(f, "f", n, (chi[:n].T, chi[n:n + nw].T, [u] * N, [dt] * N))  # eq. (9)
    x, residual = _mean_and_residuals(W, sigma_x)  # eq. (10)
    return Prediction(x, _weighted_outer(W, residual, residual), sigma_x, residual)  # (11)


class Correction(NamedTuple):
    """The update step's results."""
    x: np.ndarray  #: x (eq. 17)
    P: np.ndarray  #: P (eq. 19)
    z_hat: np.ndarray  #: predicted observation (eq. 13)
    S: np.ndarray  #: observation covariance (eq. 14)
    Pxz: np.ndarray  #: cross-covariance (eq. 15)
    K: np.ndarray  #: gain (eq. 16)


def update(prediction: Prediction, chi_v, z, h: Callable, W) -> Correction:
    """Correct a prediction with the observation z.

    Parameters
    ----------
    prediction : what :func:`predict` returned for these sigma points.
    chi_v : (nv, N) measurement-noise parts of the *same* augmented sigma points.
    z : (m,) observation.
    h : ``h(x, v) -> z``, the observation model on one moved point and its noise part.
    W : (N,) weights.

    Raises
    ------
    PivotError
        When S is not positive definite.
    """
    z = np.asarray(z, dtype=np.float64)
    if z.ndim != 1:
        raise ValueError(f"z must be a 1-D vector, not of shape {z.shape}")
    Z = _apply(h, "h", z.size, (prediction.sigma_x.T, np.asarray(chi_v).T))  # eq. (12)
    z_hat, residual_z = _mean_and_residuals(W, Z)  # eq. (13)
    S = _weighted_outer(W, residual_z, residual_z)  # eq. (14), with Z where the seed prints chi
    Pxz = _weighted_outer(W, prediction.residual, residual_z)  # eq. (15)
    K = right_divide(Pxz, S)  # eq. (16)
    x = prediction.x + K @ (z - z_hat)  # eq. (17)
    P = prediction.P - Pxz @ K.T  # eq. (19), the form the core computes
    return Correction(x, P, z_hat, S, Pxz, K)


class AugmentedUKF:
    """The augmented spherical-simplex UKF, filterpy style.

    Every :meth:`predict` draws M + 2 sigma points from the current (x, P) augmented with
    (Q, R), with M = n + nw + nv, and moves them through f; :meth:`update` maps those same
    moved points through h. After each step the filter keeps ``x_prior/P_prior`` or
    ``x_post/P_post``; ``x``/``P`` are the current estimate.

    Parameters
    ----------
    n, nw, nv, m : lengths of the state, process noise, measurement noise and observation.
    f : ``f(x, w, u, dt) -> (n,)`` process model.
    h : ``h(x, v) -> (m,)`` observation model.
    W0 : weight of the centre point, 0 <= W0 < 1.
    x0, P0 : initial state (n,) and covariance (n, n).
    Q, R : process (nw, nw) and measurement (nv, nv) noise covariances.

    Raises
    ------
    ValueError
        On a size, weight or shape that does not fit.
    """

    def __init__(self, n, nw, nv, m, f, h, W0, x0, P0, Q, R):
        self._n = _check_size("n", n)
        self._nw = _check_size("nw", nw, 0)
        self._nv = _check_size("nv", nv, 0)
        self._m = _check_size("m", m)
        self.f, self.h = f, h
        self.W = simplex_weights(self._n + self._nw + self._nv, W0)
        self._W0 = float(W0)
        self.Q = self._matrix("Q", Q, self._nw)
        self.R = self._matrix("R", R, self._nv)
        x0 = np.array(x0, dtype=np.float64)
        if x0.shape != (self._n,):
            raise ValueError(f"x0 must be a 1-D vector of length {self._n}, not of shape "
                             f"{x0.shape}")
        self.x, self.P = x0, self._matrix("P0", P0, self._n)
        self.x_prior, self.P_prior = self.x.copy(), self.P.copy()
        self.x_post, self.P_post = self.x.copy(), self.P.copy()
        self.chi = None  #: the augmented sigma points of the last predict
        self._prediction = None
        self.z_hat = self.S = self.K = None

    @staticmethod
    def _matrix(name, A, size):
        A = np.array(A, dtype=np.float64)
        if A.shape != (size, size):
            raise ValueError(f"{name} must be a {size} x {size} matrix, not of shape {A.shape}")
        return A

    @property
    def M(self) -> int:
        """Length of the augmented state, n + nw + nv."""
        return self.W.size - 2

    @property
    def W0(self) -> float:
        return self._W0

    def predict(self, u=None, dt=None) -> None:
        """sig_gen and predict: x_prior, P_prior from the current x, P.

        Raises
        ------
        PivotError
            When blockdiag(P, Q, R) is not positive definite.
        """
        self.chi = sigma_points(self.x, self.P, self.Q, self.R, self._W0)
        self._prediction = predict(self.chi, self.f, self.W, self._n, self._nw, u, dt)
        self.x, self.P = self._prediction.x, self._prediction.P
        self.x_prior, self.P_prior = self.x.copy(), self.P.copy()

    def update(self, z) -> None:
        """update: x_post, P_post from the last prediction and the observation z (m,).

        Raises
        ------
        RuntimeError
            When no predict precedes it (the update reuses the predicted sigma points).
        PivotError
            When S is not positive definite.
        """
        if self._prediction is None:
            raise RuntimeError("update needs the sigma points of a preceding predict")
        z = np.asarray(z, dtype=np.float64)
        if z.shape != (self._m,):
            raise ValueError(f"z must be a 1-D vector of length {self._m}, not of shape {z.shape}")
        c = update(self._prediction, self.chi[self._n + self._nw:], z, self.h, self.W)
        self._prediction = None
        self.x, self.P = c.x, c.P
        self.z_hat, self.S, self.K = c.z_hat, c.S, c.K
        self.x_post, self.P_post = self.x.copy(), self.P.copy()


def lower_factor(A) -> np.ndarray:
    """Lower-triangular L with L L^T = A A^T and a diagonal >= 0 (the Cholesky factor), for a
    (R, K) matrix A with R <= K: the transposed R factor of A^T's QR decomposition, by
    orthogonal transformations only, its columns' signs turned to make the diagonal >= 0."""
    A = np.asarray(A, dtype=np.float64)
    if A.ndim != 2 or A.shape[0] > A.shape[1]:
        raise ValueError(f"A must be a 2-D matrix with no more rows than columns, not of shape {A.shape}")
    L = np.linalg.qr(A.T, mode="r").T
    return L * np.where(np.diag(L) < 0, -1.0, 1.0)  # the positive diagonal: the Cholesky factor


class SquareRootUKF(AugmentedUKF):
    """The square-root form of :class:`AugmentedUKF` (the core's ``--form sqrt``), in float64.

    It keeps ``sqrtP`` = S, lower triangular with P = S S^T, and never forms P: the sigma points are
    x^a + blockdiag(S, sqrt Q, sqrt R) sigma; predict's S^- is the triangular factor of the
    moved points' weighted deviations from the mean, A_x (columns sqrt(W_k) (chi_k - x^-));
    update triangularises [A_z; A_x] into [[S_z, 0], [Kb, S^+]], whence S^+ (whose S^+ S^+^T
    is P^- - Pxz S^-1 Pxz^T, the cancellation done by orthogonal transformations) and
    x^+ = x^- + Kb S_z^-1 (z - z^). ``P`` is S S^T, for comparison with the standard form.
    W0 >= 0: every weight enters as a square root.
    """

    def __init__(self, n, nw, nv, m, f, h, W0, x0, P0, Q, R):
        super().__init__(n, nw, nv, m, f, h, W0, x0, P0, Q, R)
        self.sqrtP = np.linalg.cholesky(self._P)
        self._sqrtQ, self._sqrtR = sqrt_ldl(self.Q), sqrt_ldl(self.R)
        self._A_x = None

    @property
    def P(self) -> np.ndarray:
        S = getattr(self, "sqrtP", None)
        return self._P if S is None else S @ S.T

    @P.setter
    def P(self, value) -> None:
        self._P = value

    def _sigma_points(self) -> np.ndarray:
        n, M = self._n, self.M
        La = np.zeros((M, M))
        La[:n, :n] = self.sqrtP
        La[n:n + self._nw, n:n + self._nw] = self._sqrtQ
        La[n + self._nw:, n + self._nw:] = self._sqrtR
        xa = np.zeros(M)
        xa[:n] = self.x
        return xa[:, np.newaxis] + La @ simplex_coefficients(M, self._W0)

    def _deviations(self, X, mean) -> np.ndarray:
        A = (X - mean[:, np.newaxis]) * np.sqrt(self.W)
        return A if self._W0 else A[:, 1:]  # a zero weight adds nothing

    def predict(self, u=None, dt=None) -> None:
        """sig_gen and predict: x_prior and sqrtP (P_prior) from the current x, sqrtP."""
        self.chi = self._sigma_points()
        X = _apply(self.f, "f", self._n, (self.chi[:self._n].T, self.chi[self._n:self._n + self._nw].T,
                                          [u] * self.chi.shape[1], [dt] * self.chi.shape[1]))
        self.x = X @ self.W
        self._X = X
        self._A_x = self._deviations(X, self.x)
        self.sqrtP = lower_factor(self._A_x)
        self.x_prior, self.P_prior = self.x.copy(), self.P.copy()

    def update(self, z) -> None:
        """update: x_post and sqrtP (P_post) from the last prediction and the observation z."""
        if self._A_x is None:
            raise RuntimeError("update needs the sigma points of a preceding predict")
        z = np.asarray(z, dtype=np.float64)
        if z.shape != (self._m,):
            raise ValueError(f"z must be a 1-D vector of length {self._m}, not of shape {z.shape}")
        Z = _apply(self.h, "h", self._m, (self._X.T, self.chi[self._n + self._nw:].T))
        z_hat = Z @ self.W
        m = self._m
        L = lower_factor(np.vstack([self._deviations(Z, z_hat), self._A_x]))
        Sz, Kb = L[:m, :m], L[m:, :m]
        self.x = self.x + Kb @ np.linalg.solve(Sz, z - z_hat)
        self.sqrtP = L[m:, m:]
        self._A_x = None
        self.z_hat, self.S, self.K = z_hat, Sz @ Sz.T, np.linalg.solve(Sz.T, Kb.T).T
        self.x_post, self.P_post = self.x.copy(), self.P.copy()
