"""The linear Kalman filter's iteration (one predict and one update) as engine programs.

The user's model, in the buffer (written by software, changeable between iterations)::

    x_k = F x_(k-1) + B u_k + w,  w ~ N(0, Q);    z_k = H x_k + v,  v ~ N(0, R)

One iteration (a start, or a stream beat), in the vocabulary of :mod:`kfgen.hdl.linalg.matrix`:

predict
  x^- = F x + B u (one sum an entry over [F B] [x; u]), P^- = F P F^T + Q (one triangle,
  mirrored, into P's own words);
update
  y = z - H x^-, S = H P^- H^T + R (its lower triangle), S = L D L^T (each pivot checked:
  err_pivot when S is not positive definite, as the UKF's), K = P^- H^T S^-1 = (H P^-)^T
  S^-1 by the LDL^T right divide, x = x^- + K y, and the covariance update below (one
  triangle, mirrored). x and P are checked finite (err_nan).

Only the lower triangles of P, Q and R are read: P stays exactly symmetric over any number of
iterations, and software writes P0, Q and R once with whatever upper triangle.

**The covariance update: Joseph's form**, P = (I - K H) P^- (I - K H)^T + K R K^T, computed as
A = I - K H, A P^-, K R, and [K R, A P^-] [K, A]^T (one triangle, mirrored). Both forms were
run through the bit-exact golden model in binary32 against float64, 10,000 iterations of a
constant-velocity model (positions measured, P0 = I, R = 1e-6 and 1e-8; 4 seeds);
``python -m kfgen.sim.kf.stability`` printed (``tests/kf/test_kf_golden.py`` keeps 500
iterations of it)::

    binary32, 10,000 iterations x 4 seeds, P0 = I, R = 1e-06 I unless said
    P indefinite: iterations; errors: relative, from float64, in the last half (diag P: and the whole run)
    | model | update | P indefinite | min eig / max abs P | err flags | x error | diag P error | whole run |
    |---|---|---|---|---|---|---|---|
    | CV 1 axis, n=2 m=1 | joseph | 0 | 2.00e-06 | 0 | 2.5e-03 | 8.1e-07 | 1.8e-03 |
    | CV 1 axis, n=2 m=1 | symmetric | 0 | 1.91e-06 | 0 | 2.5e-03 | 1.0e-06 | 4.6e-02 |
    | CV 2 axes, n=4 m=2 nu=1 | joseph | 0 | 2.00e-06 | 0 | 2.4e-03 | 8.1e-07 | 1.8e-03 |
    | CV 2 axes, n=4 m=2 nu=1 | symmetric | 0 | 1.91e-06 | 0 | 2.4e-03 | 1.0e-06 | 4.6e-02 |
    | CV 1 axis, R = 1e-8 I | joseph | 0 | 2.00e-08 | 0 | 9.9e-03 | 2.3e-05 | 1.0e-03 |
    | CV 1 axis, R = 1e-8 I | symmetric | 8 | -2.66e-08 | 0 | 8.4e-03 | 1.3e-04 | 1.0e+00 |

Both stay exactly symmetric (one triangle, mirrored). The symmetric form P^- - K (H P^-) is
first order in every rounding of its cancellation (P^- of 1 against a result of R): at
R = 1e-6 its first covariances are a few per cent off, and with a sensor 100 times more
precise (R = 1e-8, below binary32's 6e-8 relative step of P^-) P loses definiteness in the
first iterations (two a run). Joseph's form is a sum of two products of positive
semidefinite form, and an error in K changes it to second order only: positive definite
throughout, 1e-3 of float64 at worst. (x's error, the same in both forms, is the state's own
rounding: the positions grow to 4e3-4e4 over the runs, where binary32's step, 5e-4 to 4e-3,
is coarser than the sensor's 1e-3 or 1e-4.) Joseph's costs
n^2 m + n^3 + (n + m) n (n + 1) / 2 + n m^2 multiply-adds where the symmetric form's costs
m n (n + 1) / 2, and three products of chain after K instead of one; the symmetric form is
kept in :data:`UPDATES` (``KfSizes.update``) for that measurement.

**Steady-state gain** (``steady_gain``): K is in the buffer (software writes it: the gain of
the discrete algebraic Riccati equation in float64 is
:func:`kfgen.sim.kf.reference.steady_gain`); there is no P, Q, R or S. The filter
x = x^- + K (z - H x^-), x^- = F x + B u, is x = A x + G u + K z with A = (I - K H) F =
F - K (H F) and G = (I - K H) B = B - K (H B), which change only when software writes F, B,
H or K: a step of their own, ``gain``, which the core runs before an iteration that follows
such a write (a prologue, as the UKF's ``noise``; :attr:`KfPrograms.prologue`). An iteration
is then one sum of n + nu + m terms an entry, into ``x_next``, and n copies into x (every
entry's sum reads all of the old x): n (n + nu + m) multiply-adds and a chain of one sum,
where the two-stage form takes n (n + nu + 2m) and a chain of three (x^-, y, x).

**Cycles** of an iteration, binary32, m = 2, nu = 1 (``tests/kf/test_kf_program.py`` prints
them with the bounds): n = 4: 565, 437, 397 at P = 1, 2, 4 (the steady gain's 75); n = 16:
15,597, 8,250, 4,233 (the steady gain's 357, 195, 195). At n = 16, P = 4 that is 42.3 us at
100 MHz against the 0.55 ms of Vitis' KalmanFilter (N = 16 at 300 MHz), 13.0 times faster;
with m = nu = 16 (35,104 multiply-adds, beyond what generates) 10,363 cycles, 104 us, 5.3
times.

**Nothing is cached for the full filter**: each of its products involves x or P, which
change every iteration, and F, B, H, Q and R enter once each.
"""

from __future__ import annotations

from dataclasses import dataclass

from kfgen.hdl.arith.float.format import FloatFormat

from ..linalg.matrix import const, ldl, mirrored, product, solve_ldl, transpose
from ..linalg.program import Copy, Layout, Program

__all__ = ["KfSizes", "KfPrograms", "build_kf", "UPDATES"]

#: The covariance update's forms: the core's (Joseph's, first) and the symmetric one, kept to measure against.
UPDATES = ("joseph", "symmetric")


@dataclass(frozen=True)
class KfSizes:
    """``n`` states, ``m`` measurements, ``nu`` control inputs (0: none); ``steady_gain``:
    K fixed in the buffer; ``update``: the covariance update's form (:data:`UPDATES`)."""

    n: int
    m: int
    nu: int = 0
    steady_gain: bool = False
    update: str = UPDATES[0]

    def __post_init__(self):
        for k, lo in (("n", 1), ("m", 1), ("nu", 0)):
            v = getattr(self, k)
            if isinstance(v, bool) or not isinstance(v, int) or v < lo:
                raise ValueError(f"{k} must be an integer >= {lo}, not {v!r}")
        if self.update not in UPDATES:
            raise ValueError(f"update must be {' or '.join(UPDATES)}, not {self.update!r}")


@dataclass
class KfPrograms:
    """The layout and the steps of one configuration (``gain``: the steady gain's prologue)."""

    sizes: KfSizes
    fmt: FloatFormat
    layout: Layout
    iterate: Program
    gain: Program | None = None

    @property
    def steps(self):
        """Step name -> program, in ``CTRL.step``'s order: ``iterate``, and ``gain`` (its
        prologue) with a steady gain."""
        return {"iterate": self.iterate} if self.gain is None else {"iterate": self.iterate, "gain": self.gain}

    @property
    def prologue(self):
        """``(pre, main, regions)``: with a steady gain, a start of ``iterate`` runs ``gain``
        first when software has written one of ``regions`` since ``gain`` last ran to its end
        (and after reset); ``None`` for the full filter."""
        if self.gain is None:
            return None
        return ("gain", "iterate", tuple(r for r in ("F", "B", "H", "K") if r in self.layout.regions))


def _lower(a):
    """A symmetric matrix's view from its lower triangle: entry ``(i, j)`` is ``a``'s
    ``(max, min)``."""
    return lambda i, j=0: a(max(i, j), min(i, j))


def _beside(a, b, cols):
    """``[a b]``, ``a`` of ``cols`` columns."""
    return lambda i, j=0: a(i, j) if j < cols else b(i, j - cols)


def _above(a, b, rows):
    """``[a; b]``, ``a`` of ``rows`` rows."""
    return lambda i, j=0: a(i, j) if i < rows else b(i - rows, j)


def build_kf(sizes: KfSizes, fmt="binary32") -> KfPrograms:
    """The memory layout and the programs for one configuration."""
    fmt = FloatFormat.parse(fmt)
    n, m, nu, steady = sizes.n, sizes.m, sizes.nu, sizes.steady_gain
    lay = Layout()
    # The processor's buffer, then work, then constants.
    x = lay.add("x", n, 1, "bus")
    P = None if steady else lay.add("P", n, n, "bus")
    F = lay.add("F", n, n, "bus")
    B = lay.add("B", n, nu, "bus") if nu else None
    Q = None if steady else lay.add("Q", n, n, "bus")
    H = lay.add("H", m, n, "bus")
    R = None if steady else lay.add("R", m, m, "bus")
    z = lay.add("z", m, 1, "bus")
    u = lay.add("u", nu, 1, "bus") if nu else None  # after z: one stream beat writes both
    K = lay.add("K", n, m, "bus" if steady else "work")
    if steady:
        return _steady(sizes, fmt, lay, x, F, B, u, H, z, K)
    xp = lay.add("x_pred", n)
    y = lay.add("innov", m)
    FP = lay.add("FP", n, n)
    HP = lay.add("HP", m, n)
    S = lay.add("S", m, m)
    FS = lay.add("FS", m, m)  # F of S's LDL^T below the diagonal
    LS = lay.add("LS", m, m)
    DS = lay.add("DS", m)
    rDS = lay.add("rDS", m)
    Yfw = lay.add("Yfw", n, m)  # the right divide's forward substitution
    Udiv = lay.add("Udiv", n, m)  # and its division by D
    joseph = sizes.update == "joseph"
    if joseph:
        A = lay.add("IKH", n, n)  # I - K H
        AP = lay.add("IKH_P", n, n)
        KR = lay.add("KR", n, m)
    one = const(lay, fmt, "one", [1])(0, 0)
    if joseph:
        zero = const(lay, fmt, "zero", [0])(0, 0)

    pr = Program("iterate", lay, fmt)
    # ---- predict ---------------------------------------------------------------------------
    fb, xu = (_beside(F, B, n), _above(x, u, n)) if nu else (F, x)
    product(pr, xp, fb, xu, n, n + nu, 1)  # x^- = [F B] [x; u]
    product(pr, FP, F, _lower(P), n, n, n)  # P^- = F P F^T + Q, into P
    product(pr, mirrored(P), FP, transpose(F), n, n, n, init=Q, lower=True)
    # ---- update ----------------------------------------------------------------------------
    product(pr, y, H, xp, m, n, 1, init=z, neg=True)  # y = z - H x^-
    product(pr, HP, H, P, m, n, n)
    product(pr, S, HP, transpose(H), m, n, m, init=R, lower=True)  # S = H P^- H^T + R
    ldl(pr, S, m, FS, LS, DS, rDS, one)
    solve_ldl(pr, K, transpose(HP), n, m, LS, DS, rDS, one, Yfw, Udiv)  # K = (H P^-)^T S^-1
    product(pr, x, K, y, n, m, 1, init=xp, check="finite")  # x = x^- + K y
    if joseph:  # P = (I - K H) P^- (I - K H)^T + K R K^T = [K R, A P^-] [K, A]^T, A = I - K H
        product(pr, A, K, H, n, m, n, init=lambda i, j: one if i == j else zero, neg=True)
        product(pr, AP, A, P, n, n, n)
        product(pr, KR, K, _lower(R), n, m, m)
        # K R K^T's terms first: they are ready before A P^-'s
        product(pr, mirrored(P), _beside(KR, AP, m), transpose(_beside(K, A, m)), n, m + n, n, lower=True,
                check="finite")
    else:  # P = P^- - K (H P^-)
        product(pr, mirrored(P), K, HP, n, m, n, init=P, neg=True, lower=True, check="finite")
    return KfPrograms(sizes, fmt, lay, pr)


def _steady(sizes, fmt, lay, x, F, B, u, H, z, K) -> KfPrograms:
    """The steady gain's programs on the buffer placed by :func:`build_kf`: ``gain`` forms
    A = F - K (H F) and G = B - K (H B), ``iterate`` x = K z + G u + A x."""
    n, m, nu = sizes.n, sizes.m, sizes.nu
    HF = lay.add("HF", m, n)
    A = lay.add("A", n, n)
    if nu:
        HB = lay.add("HB", m, nu)
        G = lay.add("G", n, nu)
    xn = lay.add("x_next", n)
    gain = Program("gain", lay, fmt)
    product(gain, HF, H, F, m, n, n)
    product(gain, A, K, HF, n, m, n, init=F, neg=True)
    if nu:
        product(gain, HB, H, B, m, n, nu)
        product(gain, G, K, HB, n, m, nu, init=B, neg=True)
    pr = Program("iterate", lay, fmt)
    # the terms of the words software writes for this iteration (z, u) first, x's last
    mats, vecs = (_beside(_beside(K, G, m), A, m + nu), _above(_above(z, u, m), x, m + nu)) if nu else \
        (_beside(K, A, m), _above(z, x, m))
    product(pr, xn, mats, vecs, n, m + nu + n, 1, check="finite")
    for i in range(n):
        pr.emit(Copy(x(i), xn(i)))
    return KfPrograms(sizes, fmt, lay, pr, gain)
