"""Float64 reference of one IMM iteration, written from Hackett et al.'s step table (seed 004:
MIX01-07, KF01-09, COM01-10) with numpy's own linear algebra.

It checks the core's program, not its rounding: the bit-exact golden model is separate. One
iteration takes the model probabilities mu, every model's state x_r and covariance P_r and a
measurement z, and returns the next ones and the combined estimate:

* **MIX** (interaction): c_j = sum_i pi_ij mu_i (MIX01), the mixing weights
  omega_ij = pi_ij mu_i / c_j (MIX02-03), the mixed states x0_j = sum_i omega_ij x_i (MIX04)
  and covariances P0_j = sum_i omega_ij (P_i + (x_i - x0_j)(x_i - x0_j)^T) (MIX05-07, with the
  slides' G taken as zero).
* **KF** per model j from (x0_j, P0_j): the Kalman filter's predict and update (KF01-09).
* **COM** (combination): the likelihood of each model's innovation (COM01-06), the updated
  probabilities (COM07-09), the combined state (COM10) and covariance.

Conventions (where the slides and filterpy differ):

* ``pi[i, j]`` is P(model j at k | model i at k-1); rows sum to one. filterpy's ``M`` is the
  same matrix (its code computes ``cbar = mu @ M``; its docstring says the transpose). The
  slides print MIX01 as mu^T pi^T, which agrees with their MIX03 (diag(mu) pi diag(c)^-1 in
  our indices) only for this pi read as mu^T pi; MIX03 and the brief decide.
* COM06 prints (2 pi)^(d/2); the density has (2 pi)^(-d/2), and it cancels in COM09.
* COM03's exp underflows to zero for every model when the measurement is far from all of them
  (and COM09 then divides 0 by 0). The probabilities are therefore computed in a scaled domain:
  with t_j = -q_j / 2 and m = max_j t_j, w_j = c_j |S_j|^(-1/2) exp(t_j - m) is the slides'
  c_j Lambda_j times (2 pi)^(d/2) e^(-m), a factor common to every j, so mu_j = w_j / sum_k w_k
  is COM09 unchanged, and the largest w_j is c_j |S_j|^(-1/2) > 0.
* Covariances are kept symmetric ((A + A^T) / 2 after each product that is not symmetric by
  construction), as the core keeps one triangle.

``mu`` need not sum to one exactly: every use of it is normalised (omega by c_j, the new mu by
sum w), so an iteration's result does not depend on its scale.

Shapes are 1-D vectors and 2-D matrices; a bank of R models stacks them on a first axis:
xs (R, n), Ps (R, n, n).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

__all__ = ["ImmModel", "ImmSystem", "KfStep", "kf_step", "ImmStep", "imm_step", "ImmRun",
           "run_reference", "run_filterpy", "KfRun", "run_single"]

#: How far a row of pi may be from summing to one.
ROW_SUM_TOLERANCE = 1e-12


def _matrix(owner: str, name: str, A, shape: tuple[int, int] | None = None,
            symmetric: bool = False) -> np.ndarray:
    A = np.array(A, dtype=np.float64)
    if A.ndim != 2 or (shape is not None and A.shape != shape):
        want = f"a {shape[0]} x {shape[1]} matrix" if shape else "a 2-D matrix"
        raise ValueError(f"{owner}: {name} must be {want}, not of shape {A.shape}")
    if not np.all(np.isfinite(A)):
        raise ValueError(f"{owner}: {name} must be finite")
    if symmetric and not np.allclose(A, A.T, rtol=0, atol=1e-12 * max(np.abs(A).max(), 1e-300)):
        raise ValueError(f"{owner}: {name} must be symmetric")
    A.setflags(write=False)
    return A


def _state_size(owner: str, F: np.ndarray, Q: np.ndarray, H: np.ndarray) -> int:
    """The state size n that F (n x n), Q (n x n) and H (d x n) agree on, two of them at
    least, so that the error names the one matrix that does not fit."""
    sizes = [F.shape[0], Q.shape[0], H.shape[1]]
    agreed = [k for k in sizes if sizes.count(k) >= 2]
    if not agreed:
        raise ValueError(f"{owner}: F, Q and H must agree on the state size n (F and Q are n x n, H is d x n), "
                         f"not F {F.shape}, Q {Q.shape}, H {H.shape}")
    return agreed[0]


def _sym(A: np.ndarray) -> np.ndarray:
    return (A + np.swapaxes(A, -1, -2)) / 2


@dataclass(frozen=True)
class ImmModel:
    """One model of the bank: x' = F x + w, w ~ N(0, Q); z = H x + v, v ~ N(0, R).

    Parameters
    ----------
    name : what the model stands for (a channel condition in the scenario).
    F : (n, n) state transition.
    Q : (n, n) process-noise covariance, symmetric.
    H : (d, n) measurement matrix.
    R : (d, d) measurement-noise covariance, symmetric.

    The matrices are stored as read-only float64 arrays.

    Raises
    ------
    ValueError
        On a shape that does not fit, a non-finite entry or an asymmetric Q or R.
    """
    name: str
    F: np.ndarray
    Q: np.ndarray
    H: np.ndarray
    R: np.ndarray

    def __post_init__(self):
        owner = f"model {self.name!r}"
        F, Q, H = (_matrix(owner, name, getattr(self, name)) for name in "FQH")
        for name, A in (("F", F), ("Q", Q)):
            if A.shape[0] != A.shape[1]:
                raise ValueError(f"{owner}: {name} must be square, not of shape {A.shape}")
        n = _state_size(owner, F, Q, H)
        if F.shape != (n, n):
            raise ValueError(f"{owner}: F must be a {n} x {n} matrix, not of shape {F.shape}")
        if H.shape[1] != n:
            raise ValueError(f"{owner}: H must have n = {n} columns, not of shape {H.shape}")
        d = H.shape[0]
        object.__setattr__(self, "F", F)
        object.__setattr__(self, "Q", _matrix(owner, "Q", Q, (n, n), symmetric=True))
        object.__setattr__(self, "H", H)
        object.__setattr__(self, "R", _matrix(owner, "R", self.R, (d, d), symmetric=True))

    @property
    def n(self) -> int:
        """State size."""
        return self.F.shape[0]

    @property
    def d(self) -> int:
        """Measurement size."""
        return self.H.shape[0]


@dataclass(frozen=True)
class ImmSystem:
    """A bank of R >= 2 models of one state and measurement, and their transition matrix.

    Parameters
    ----------
    models : the R models (:class:`ImmModel`), all with the same n and d.
    pi : (R, R) Markov transition matrix, ``pi[i, j]`` = P(model j at k | model i at k-1):
        non-negative, every row sums to one (within 1e-12).

    Raises
    ------
    ValueError
        On fewer than two models, models of different sizes, or a pi that is not a
        row-stochastic R x R matrix.
    """
    models: tuple
    pi: np.ndarray

    def __post_init__(self):
        models = tuple(self.models)
        if len(models) < 2 or not all(isinstance(m, ImmModel) for m in models):
            raise ValueError(f"models must be at least two ImmModel, not {self.models!r}")
        n, d = models[0].n, models[0].d
        for m in models[1:]:
            if (m.n, m.d) != (n, d):
                raise ValueError(f"model {m.name!r} has n = {m.n}, d = {m.d}; model "
                                 f"{models[0].name!r} has n = {n}, d = {d}")
        R = len(models)
        pi = _matrix("the system", "pi", self.pi, (R, R))
        if np.any(pi < 0):
            raise ValueError("pi must be non-negative")
        rows = pi.sum(axis=1)
        if np.any(np.abs(rows - 1) > ROW_SUM_TOLERANCE):
            raise ValueError(f"every row of pi must sum to 1 (pi[i, j] = P(j | i)), not {rows}")
        object.__setattr__(self, "models", models)
        object.__setattr__(self, "pi", pi)

    @property
    def n(self) -> int:
        """State size."""
        return self.models[0].n

    @property
    def d(self) -> int:
        """Measurement size."""
        return self.models[0].d

    @property
    def R(self) -> int:
        """Number of models."""
        return len(self.models)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(m.name for m in self.models)


def _vector(name: str, v, length: int) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    if v.shape != (length,):
        raise ValueError(f"{name} must be a 1-D vector of length {length}, not of shape {v.shape}")
    return v


def _stack(name: str, A, shape: tuple[int, ...]) -> np.ndarray:
    A = np.asarray(A, dtype=np.float64)
    if A.shape != shape:
        raise ValueError(f"{name} must be of shape {shape}, not {A.shape}")
    return A


class KfStep(NamedTuple):
    """One model's Kalman filter step (KF01-09)."""
    x_prior: np.ndarray  #: F x0 (KF01)
    P_prior: np.ndarray  #: F P0 F^T + Q (KF02-03)
    y: np.ndarray  #: innovation z - H x_prior (KF08)
    S: np.ndarray  #: innovation covariance H P_prior H^T + R (KF04-05)
    K: np.ndarray  #: gain P_prior H^T S^-1 (KF06)
    x: np.ndarray  #: x_prior + K y (KF09)
    P: np.ndarray  #: P_prior - K (P_prior H^T)^T (KF07)


def kf_step(model: ImmModel, x0: np.ndarray, P0: np.ndarray, z: np.ndarray) -> KfStep:
    """Predict from (x0, P0) with the model's F and Q, then update with z (KF01-09).

    Arguments are taken as checked: :func:`imm_step` and :func:`run_single` check them.
    """
    F, H = model.F, model.H
    x_prior = F @ x0  # KF01
    P_prior = _sym(F @ P0 @ F.T + model.Q)  # KF02-03
    PHt = P_prior @ H.T  # KF04
    S = _sym(H @ PHt + model.R)  # KF05
    K = np.linalg.solve(S, PHt.T).T  # KF06: S is symmetric, so (S^-1 (P H^T)^T)^T
    y = z - H @ x_prior  # KF08
    x = x_prior + K @ y  # KF09
    P = _sym(P_prior - K @ PHt.T)  # KF07
    return KfStep(x_prior, P_prior, y, S, K, x, P)


class ImmStep(NamedTuple):
    """One IMM iteration: the outputs (the next iteration's inputs and the combined
    estimate) and every intermediate the step table names, per model on the first axis."""
    mu: np.ndarray  #: (R,) updated model probabilities (COM09)
    xs: np.ndarray  #: (R, n) updated model states (KF09)
    Ps: np.ndarray  #: (R, n, n) updated model covariances (KF07)
    x: np.ndarray  #: (n,) combined state (COM10)
    P: np.ndarray  #: (n, n) combined covariance
    c: np.ndarray  #: (R,) predicted model probabilities c_j (MIX01)
    omega: np.ndarray  #: (R, R) mixing weights omega[i, j] = pi_ij mu_i / c_j (MIX02-03)
    x0: np.ndarray  #: (R, n) mixed states (MIX04)
    P0: np.ndarray  #: (R, n, n) mixed covariances (MIX05-07)
    x_prior: np.ndarray  #: (R, n) (KF01)
    P_prior: np.ndarray  #: (R, n, n) (KF03)
    y: np.ndarray  #: (R, d) innovations (KF08)
    S: np.ndarray  #: (R, d, d) innovation covariances (KF05)
    K: np.ndarray  #: (R, n, d) gains (KF06)
    q: np.ndarray  #: (R,) y^T S^-1 y (COM01)
    t: np.ndarray  #: (R,) -q / 2 (COM02)
    det_S: np.ndarray  #: (R,) |S| (COM04)
    m: float  #: max_j t_j, the scale of the likelihood domain
    w: np.ndarray  #: (R,) scaled c_j Lambda_j: c_j |S_j|^(-1/2) exp(t_j - m) (COM03-07)


def imm_step(system: ImmSystem, mu, xs, Ps, z) -> ImmStep:
    """One IMM iteration (MIX01-07, KF01-09 per model, COM01-10).

    Parameters
    ----------
    system : the models and the transition matrix.
    mu : (R,) model probabilities at k-1 (non-negative; normalised where used).
    xs, Ps : (R, n) states and (R, n, n) covariances of the models at k-1.
    z : (d,) measurement at k.

    Raises
    ------
    ValueError
        On a shape that does not fit, a negative or non-finite mu, or a model whose predicted
        probability c_j is zero (its mixing weights are undefined).
    numpy.linalg.LinAlgError
        When some S_j is singular.
    """
    Rm, n, d = system.R, system.n, system.d
    mu = _vector("mu", mu, Rm)
    if not np.all(np.isfinite(mu)) or np.any(mu < 0):
        raise ValueError(f"mu must be finite and non-negative, not {mu}")
    xs = _stack("xs", xs, (Rm, n))
    Ps = _stack("Ps", Ps, (Rm, n, n))
    z = _vector("z", z, d)
    pi = system.pi

    # MIX
    c = mu @ pi  # MIX01: c_j = sum_i pi_ij mu_i
    if not np.all(c > 0):
        j = int(np.argmin(c))
        raise ValueError(f"model {system.names[j]!r} has predicted probability c_j = {float(c[j])!r}: "
                         f"its mixing weights are undefined")
    omega = pi * mu[:, np.newaxis] / c  # MIX02-03: omega_ij = pi_ij mu_i / c_j
    x0 = omega.T @ xs  # MIX04: x0_j = sum_i omega_ij x_i
    P0 = np.empty((Rm, n, n))
    for j in range(Rm):
        e = xs - x0[j]  # MIX05
        spread = Ps + e[:, :, np.newaxis] * e[:, np.newaxis, :]  # MIX06
        P0[j] = np.tensordot(omega[:, j], spread, axes=1)  # MIX07, G = 0

    # KF per model
    steps = [kf_step(model, x0[j], P0[j], z) for j, model in enumerate(system.models)]
    x_prior, P_prior, y, S, K, xs_new, Ps_new = (np.stack(a) for a in zip(*steps))

    # COM
    q = np.array([y[j] @ np.linalg.solve(S[j], y[j]) for j in range(Rm)])  # COM01
    t = -q / 2  # COM02
    det_S = np.linalg.det(S)  # COM04
    m = float(t.max())
    w = c * det_S ** -0.5 * np.exp(t - m)  # COM03, COM05-07 scaled by (2 pi)^(d/2) e^-m
    mu_new = w / w.sum()  # COM08-09
    x = mu_new @ xs_new  # COM10
    e = xs_new - x
    P = np.tensordot(mu_new, Ps_new + e[:, :, np.newaxis] * e[:, np.newaxis, :], axes=1)
    return ImmStep(mu_new, xs_new, Ps_new, x, P, c, omega, x0, P0, x_prior, P_prior, y, S, K,
                   q, t, det_S, m, w)


class ImmRun(NamedTuple):
    """An IMM over a measurement sequence: entry k is the estimate after measurement k."""
    mu: np.ndarray  #: (T, R)
    x: np.ndarray  #: (T, n) combined state
    P: np.ndarray  #: (T, n, n) combined covariance
    xs: np.ndarray  #: (T, R, n) model states
    Ps: np.ndarray  #: (T, R, n, n) model covariances


def _measurements(system: ImmSystem, zs) -> np.ndarray:
    zs = np.asarray(zs, dtype=np.float64)
    if zs.ndim != 2 or zs.shape[1] != system.d:
        raise ValueError(f"zs must be of shape (T, {system.d}), not {zs.shape}")
    return zs


def _initial(system: ImmSystem, mu0, xs0, Ps0, zs):
    Rm, n = system.R, system.n
    return (_vector("mu0", mu0, Rm), _stack("xs0", xs0, (Rm, n)),
            _stack("Ps0", Ps0, (Rm, n, n)), _measurements(system, zs))


def run_reference(system: ImmSystem, mu0, xs0, Ps0, zs) -> ImmRun:
    """:func:`imm_step` over the measurements zs (T, d), from mu0 (R,), xs0 (R, n) and
    Ps0 (R, n, n)."""
    mu, xs, Ps, zs = _initial(system, mu0, xs0, Ps0, zs)
    out = []
    for z in zs:
        s = imm_step(system, mu, xs, Ps, z)
        mu, xs, Ps = s.mu, s.xs, s.Ps
        out.append((s.mu, s.x, s.P, s.xs, s.Ps))
    return ImmRun(*(np.array(a) for a in zip(*out)))


def _filterpy_kf(model: ImmModel, x0, P0):
    from filterpy.kalman import KalmanFilter  # deferred: filterpy (the [dev] extras), the third party

    kf = KalmanFilter(dim_x=model.n, dim_z=model.d)
    kf.F, kf.Q, kf.H, kf.R = (np.array(a) for a in (model.F, model.Q, model.H, model.R))
    kf.x, kf.P = np.array(x0, dtype=np.float64), np.array(P0, dtype=np.float64)
    return kf


def run_filterpy(system: ImmSystem, mu0, xs0, Ps0, zs) -> ImmRun:
    """The same run through filterpy's ``IMMEstimator`` with one ``KalmanFilter`` per model
    (1-D states), ``M = pi``: its ``predict`` mixes (MIX) and predicts (KF01-03), its
    ``update`` updates every filter (Joseph form), weighs ``cbar`` by each filter's
    likelihood (unscaled, raised to the smallest normal float where exp underflows) and
    combines."""
    from filterpy.kalman import IMMEstimator  # deferred: filterpy (the [dev] extras), the third party

    mu0, xs0, Ps0, zs = _initial(system, mu0, xs0, Ps0, zs)
    filters = [_filterpy_kf(m, x, P) for m, x, P in zip(system.models, xs0, Ps0)]
    imm = IMMEstimator(filters, mu0, np.array(system.pi))
    out = []
    for z in zs:
        imm.predict()
        imm.update(z)
        out.append((imm.mu.copy(), imm.x.copy(), imm.P.copy(), np.array([f.x for f in filters]),
                    np.array([f.P for f in filters])))
    return ImmRun(*(np.array(a) for a in zip(*out)))


class KfRun(NamedTuple):
    """A single-model Kalman filter over a measurement sequence."""
    x: np.ndarray  #: (T, n) posterior states
    P: np.ndarray  #: (T, n, n) posterior covariances


def run_single(system: ImmSystem, r: int, x0, P0, zs) -> KfRun:
    """Model r of the system alone, as a plain Kalman filter (:func:`kf_step`, no mixing)
    over zs (T, d) from x0 (n,), P0 (n, n)."""
    if not isinstance(r, (int, np.integer)) or not 0 <= r < system.R:
        raise ValueError(f"r must be a model index 0..{system.R - 1}, not {r!r}")
    model = system.models[r]
    x = _vector("x0", x0, system.n)
    P = _stack("P0", P0, (system.n, system.n))
    xs, Ps = [], []
    for z in _measurements(system, zs):
        s = kf_step(model, x, P, z)
        x, P = s.x, s.P
        xs.append(x)
        Ps.append(P)
    return KfRun(np.array(xs), np.array(Ps))

