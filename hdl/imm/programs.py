"""The IMM filter's iteration (Hackett et al.'s step table MIX01-07, KF01-09, COM01-10) as one
engine program.

R models of n states and d measurements; model r has F_r, Q_r, H_r, R_r (written by software
like the UKF's Q and R), a state x_r and covariance P_r; pi[i][j] is the probability of a
switch from model i to model j, mu the model probabilities. One iteration:

MIX (mixing)
  c_j = sum_i pi_ij mu_i; w_ij = pi_ij mu_i / c_j (one reciprocal of c_j, then multiplies);
  x0_j = sum_i w_ij x_i; P0_j = sum_i w_ij (P_i + e_ij e_ij^T), e_ij = x_i - x0_j (the
  slides' G in MIX07 taken as zero).
KF (one Kalman filter per model, on x0_j, P0_j)
  x^- = F x0; P^- = F P0 F^T + Q; y = z - H x^-; S = H P^- H^T + R;
  S^-1 and |S| by the Schur-complement graph of :mod:`kfgen.hdl.schur.program` (the
  ``kfgen schur`` unit's own operations, each one rounding, so the IMM's S^-1 is that
  unit's result bit for bit); K = (H P^-)^T S^-1; x = x^- + K y; P = P^- - K (H P^-).
COM (combination)
  q_j = y_j^T S_j^-1 y_j and t_j = -q_j / 2, so the likelihood is
  Lambda_j = (2 pi)^(-d/2) |S_j|^(-1/2) exp(t_j). The normalisation is taken in a scaled
  domain: with m = max_j t_j, w_j = c_j |S_j|^(-1/2) exp(t_j - m), whose largest exp is
  exp(0) = 1, so the sum cannot underflow to 0 while any c_j |S_j|^(-1/2) is normal; the
  factors (2 pi)^(-d/2) e^m cancel in mu_j = w_j / sum_k w_k. Then x = sum_j mu_j x_j and
  P = sum_j mu_j (P_j + (x_j - x)(x_j - x)^T).

Every covariance (P0_j, P^-, P_j, P) is computed as one triangle and mirrored on write-back,
so the matrices stay exactly symmetric over any number of iterations.

For a short dependency chain: x0_j and x are summed unnormalised while their reciprocal is
divided (x0_j = (sum_i pi_ij mu_i x_i) / c_j, x = (sum_j w_j x_j) / sum_j w_j); the
covariance sums list their terms that are ready early (w_ij P_i, mu_j P_j) first; t_j is
(-y_j / 2)^T S_j^-1 y_j, the halving done while S_j^-1 is formed.

Checks: a predicted model probability c_j, a Schur pivot of S_j, |S_j| and the sum of the
w_j are pivots (err_pivot when <= 0 or NaN); the new mu, x_j, P_j, x and P are checked finite
(err_nan).
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

from kfgen.hdl.arith.float.format import FloatFormat
from kfgen.hdl.schur.program import schur_program

from ..linalg.matrix import block, const, fill, hadamard, mirrored, product, row, transpose
from ..linalg.program import Div, Dot, Exp, Layout, Max, Program, Sqrt

__all__ = ["ImmSizes", "ImmPrograms", "build_imm"]


@dataclass(frozen=True)
class ImmSizes:
    """``models`` (R) models of ``n`` states and ``d`` measurements."""

    models: int
    n: int
    d: int

    def __post_init__(self):
        for k, lo in (("models", 2), ("n", 1), ("d", 1)):
            v = getattr(self, k)
            if isinstance(v, bool) or not isinstance(v, int) or v < lo:
                raise ValueError(f"{k} must be an integer >= {lo}, not {v!r}")


@dataclass
class ImmPrograms:
    sizes: ImmSizes
    fmt: FloatFormat
    layout: Layout
    iterate: Program

    @property
    def steps(self):
        return {"iterate": self.iterate}


def build_imm(sizes: ImmSizes, fmt="binary32") -> ImmPrograms:
    """The memory layout and the iteration's program for one configuration."""
    fmt = FloatFormat.parse(fmt)
    R, n, d = sizes.models, sizes.n, sizes.d
    lay = Layout()
    # The processor's buffer: model matrices stacked model by model, then the state.
    pi = lay.add("pi", R, R, "bus")
    mu = lay.add("mu", R, 1, "bus")
    F = lay.add("F", R * n, n, "bus")
    Q = lay.add("Q", R * n, n, "bus")
    H = lay.add("H", R * d, n, "bus")
    Rm = lay.add("R", R * d, d, "bus")
    xm = lay.add("x_model", R, n, "bus")
    Pm = lay.add("P_model", R * n, n, "bus")
    z = lay.add("z", d, 1, "bus")
    x = lay.add("x", n, 1, "bus")
    P = lay.add("P", n, n, "bus")
    # Work, one region per model where the models' filters may overlap in time.
    pm = lay.add("pi_mu", R, R)  # pi_ij mu_i
    c = lay.add("c", R)
    rc = lay.add("rc", R)
    W = lay.add("w_mix", R, R)
    x0u = lay.add("x0_sum", R, n)
    x0 = lay.add("x0", R, n)
    e = lay.add("e_mix", R * R, n)  # e_ij, row i * R + j
    we = lay.add("we_mix", R * R, n)  # w_ij e_ij
    P0 = lay.add("P0", R * n, n)
    xp = lay.add("x_pred", R, n)
    FP = lay.add("FP0", R * n, n)
    Pp = lay.add("P_pred", R * n, n)
    HP = lay.add("HP", R * d, n)
    S = lay.add("S", R * d, d)
    y = lay.add("innov", R, d)
    graph = schur_program(d)
    inner = [k for k, node in enumerate(graph.nodes) if node.op not in ("in", "one")]
    sch = lay.add("schur", R, len(inner))
    K = lay.add("K", R * n, d)
    v = lay.add("Sinv_y", R, d)
    yh = lay.add("innov_half", R, d)
    t = lay.add("t", R)
    sd = lay.add("sqrt_det", R)
    rsd = lay.add("rsqrt_det", R)
    mx = lay.add("t_max", max(1, R - 1))
    u = lay.add("t_scaled", R)
    ex = lay.add("exp_t", R)
    a = lay.add("c_rsd", R)
    w = lay.add("w", R)
    sw = lay.add("w_sum", 1)
    rsw = lay.add("w_rsum", 1)
    xu = lay.add("x_sum", n)
    dx = lay.add("dx_com", R, n)
    mdx = lay.add("mu_dx_com", R, n)
    one = const(lay, fmt, "one", [1])(0, 0)
    nhalf = const(lay, fmt, "minus_half", [Fraction(-1, 2)])(0, 0)

    pr = Program("iterate", lay, fmt)

    def dot(dst, init, terms, check=None):
        return pr.emit(Dot(dst, init, terms, check))

    # ---- MIX (column by column: model j's sums) --------------------------------------------
    hadamard(pr, transpose(pm), transpose(pi), lambda j, i: mu(i), R, R)
    for j in range(R):  # c_j, from the exact products (its own accumulation)
        dot(c(j), None, [(pi(i, j), mu(i), False) for i in range(R)], "pivot")
        pr.emit(Div(rc(j), one, c(j)))
    hadamard(pr, transpose(W), transpose(pm), lambda j, i: rc(j), R, R)
    for j in range(R):
        for k in range(n):  # x0 = (sum_i pi_ij mu_i x_i) / c_j: the sum while the division runs
            dot(x0u(j, k), None, [(pm(i, j), xm(i, k), False) for i in range(R)])
            dot(x0(j, k), None, [(x0u(j, k), rc(j), False)])
        for i in range(R):
            for k in range(n):
                dot(e(i * R + j, k), xm(i, k), [(one, x0(j, k), True)])
                dot(we(i * R + j, k), None, [(W(i, j), e(i * R + j, k), False)])
        for r in range(n):
            for s in range(r + 1):
                terms = [(W(i, j), Pm(i * n + r, s), False) for i in range(R)]  # the early terms first
                terms += [(we(i * R + j, r), e(i * R + j, s), False) for i in range(R)]
                dot(mirrored(block(P0, j * n))(r, s), None, terms)

    # ---- KF, model by model ---------------------------------------------------------------
    for j in range(R):
        fr, hr = j * n, j * d
        Fj, Hj, Ppj, HPj = block(F, fr), block(H, hr), block(Pp, fr), block(HP, hr)
        product(pr, row(xp, j), Fj, row(x0, j), n, n, 1)  # x^- = F x0
        product(pr, block(FP, fr), Fj, block(P0, fr), n, n, n)  # P^- = F P0 F^T + Q
        product(pr, mirrored(Ppj), block(FP, fr), transpose(Fj), n, n, n, init=block(Q, fr), lower=True)
        product(pr, HPj, Hj, Ppj, d, n, n)
        product(pr, row(y, j), Hj, row(xp, j), d, n, 1, init=z, neg=True)  # y = z - H x^-
        pivots = set(graph.pivots)  # S = H P^- H^T + R, its Schur pivots checked
        product(pr, mirrored(block(S, hr)), HPj, transpose(Hj), d, n, d, init=block(Rm, hr), lower=True,
                check=lambda i, k: "pivot" if graph.inputs[k, i] in pivots else None)
        # S^-1 and |S|: the Schur unit's graph, one engine operation a node
        addr = {}
        for (i, k), node in graph.inputs.items():
            addr[node] = S(hr + i, k)
        for idx, node in enumerate(graph.nodes):
            if node.op == "one":
                addr[idx] = one
            elif node.op != "in":
                addr[idx] = sch(j, inner.index(idx))
        for idx, node in enumerate(graph.nodes):
            if node.op in ("in", "one"):
                continue
            dst, args = addr[idx], [addr[k] for k in node.args]
            chk = "pivot" if idx in pivots else None
            if node.op == "mul":
                dot(dst, None, [(args[0], args[1], False)], chk)
            elif node.op == "add":
                dot(dst, args[0], [(one, args[1], False)], chk)
            elif node.op == "sub":
                dot(dst, args[0], [(one, args[1], True)], chk)
            elif node.op == "neg":  # -x + -0: the sign flipped, exactly
                dot(dst, None, [(one, args[0], True)], chk)
            elif node.op == "div":
                pr.emit(Div(dst, args[0], args[1], chk))
            else:
                raise AssertionError(node.op)

        def sinv(i, k):
            return addr[graph.inverse[min(i, k), max(i, k)]]

        det = addr[graph.det]
        Kj = block(K, fr)
        product(pr, Kj, transpose(HPj), sinv, n, d, d)  # K = (H P^-)^T S^-1
        product(pr, row(xm, j), Kj, row(y, j), n, d, 1, init=row(xp, j), check="finite")  # x = x^- + K y
        product(pr, mirrored(block(Pm, fr)), Kj, HPj, n, d, n, init=Ppj, neg=True, lower=True,
                check="finite")  # P = P^- - K (H P^-)
        for i in range(d):  # t = -q / 2 = (-y / 2)^T S^-1 y, the halving while S^-1 is formed
            dot(yh(j, i), None, [(y(j, i), nhalf, False)])
            dot(v(j, i), None, [(sinv(i, k), y(j, k), False) for k in range(d)])
        product(pr, fill(t(j)), transpose(row(yh, j)), row(v, j), 1, d, 1)  # t = yh^T v
        pr.emit(Sqrt(sd(j), det, "pivot"))
        pr.emit(Div(rsd(j), one, sd(j)))

    # ---- COM -----------------------------------------------------------------------------
    m = t(0)
    for j in range(1, R):  # m = max_j t_j
        pr.emit(Max(mx(j - 1), m, t(j)))
        m = mx(j - 1)
    for j in range(R):
        dot(u(j), t(j), [(one, m, True)])
        pr.emit(Exp(ex(j), u(j)))
        dot(a(j), None, [(c(j), rsd(j), False)])
        dot(w(j), None, [(a(j), ex(j), False)])
    dot(sw(0), None, [(one, w(j), False) for j in range(R)], "pivot")
    pr.emit(Div(rsw(0), one, sw(0)))
    hadamard(pr, mu, w, fill(rsw(0)), R, check="finite")
    for r in range(n):  # x = (sum_j w_j x_j) / sum_j w_j: the sum while the division runs
        dot(xu(r), None, [(w(j), xm(j, r), False) for j in range(R)])
        dot(x(r), None, [(xu(r), rsw(0), False)], "finite")
    for j in range(R):
        for r in range(n):
            dot(dx(j, r), xm(j, r), [(one, x(r), True)])
            dot(mdx(j, r), None, [(mu(j), dx(j, r), False)])
    for r in range(n):
        for s in range(r + 1):
            terms = [(mu(j), Pm(j * n + r, s), False) for j in range(R)]  # the early terms first
            terms += [(mdx(j, r), dx(j, s), False) for j in range(R)]
            dot(mirrored(P)(r, s), None, terms, "finite")
    return ImmPrograms(sizes, fmt, lay, pr)
