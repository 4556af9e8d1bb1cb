"""The UKF's three steps (sig_gen, predict, update) as engine programs.

Equation numbers are the chapter's (Soh & Wu, "A Scalable, FPGA-Based Implementation of the
Unscented Kalman Filter"). Structure known at generation is used instead of computed:

* P^a = blockdiag(P, Q, R) (4), so L and D are block diagonal: each block is factored alone
  by (23)-(24), one triangle, and no multiply-add touches the zero blocks;
* the simplex matrix sigma (5)-(7) has in row j only two values, c_j = -1/sqrt(j'(j'+1)W1)
  (columns 1..j') and d_j = j'/sqrt(j'(j'+1)W1) (column j'+1), j' = j+1, and zeros. The
  recombination L1 = L2 sqrt(D) (22) is folded into sigma's rows (g_j = s_j c_j,
  e_j = s_j d_j, s_j = sqrt(D_j)), and chi = x^a + L1 sigma (8) is built from the suffix sums
  T_rk = x^a_r + sum_{j=k..r} L_rj g_j, each point one multiply-add: M^2 instead of M^3/6;
* the weights take two values, W0 for point 0 and W1 for the rest (5), and sum to 1: the
  means (10), (13) are point 0 plus W1 times the sum of the differences d_k = pt_k - pt_0,
  and the covariances (11), (14), (15) are taken about point 0 and corrected by the mean's
  offset (the shifted sums, see ``covariance``), so the long accumulations of the
  covariance do not wait for the mean's. One triangle of P and S is computed, P's mirrored
  on write-back;
* K = Pxz S^-1 (16) is the right divide K L D L^T = Pxz: forward substitution, a division by
  D, back substitution, row by row of K.

Accumulation orders put the term that becomes ready last at the end.

The square-root form (``form="sqrt"``, :class:`~.params.UkfParams`) keeps S, P = S S^T, in
region ``sqrtP``: sig_gen reads S instead of factoring P (and Q's and R's Cholesky factors
come from the ``noise`` step, once per write), and predict and update triangularise the
points' weighted deviations by Householder reflections (:func:`triangularize`), update the
stacked [A_z; A_x] whose factor holds S_z, P_xz S_z^-T and S^+ at once (:func:`_sqrt_form`).
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from math import isqrt

from kfgen.hdl.arith.float.format import FloatFormat

from ..linalg.matrix import (add, block, cholesky, const, fill, forward_substitute, ldl, mirrored, product,
                             row, solve_ldl, transpose)
from ..linalg.program import Copy, CopySign, Div, Dot, Layout, Max, Program, Sqrt
from .params import UkfParams, covariance_region

__all__ = ["UkfPrograms", "build_ukf", "simplex_rows", "triangularize", "qr_columns"]


def _blocks(params):
    """(first, end) of P, Q and R inside P^a."""
    n, w = params.n, params.n + params.nw
    return ((0, n), (n, w), (w, params.M))


def _sqrt(q: Fraction, bits: int = 256) -> Fraction:
    """sqrt(q) truncated to ``bits`` fraction bits, plus a sticky half-unit if inexact."""
    num = q.numerator << (2 * bits)
    r = isqrt(num // q.denominator)
    exact = r * r * q.denominator == num
    return Fraction(r, 1 << bits) + (0 if exact else Fraction(1, 1 << (bits + 1)))


def simplex_rows(M: int, w0) -> tuple[Fraction, list[Fraction], list[Fraction]]:
    """W1 and sigma's row values c_j, d_j (5)-(7), exact or rounded far below any format."""
    W1 = (1 - Fraction(w0)) / (M + 1)
    c, d = [], []
    for j in range(1, M + 1):
        s = _sqrt(1 / (j * (j + 1) * W1))
        c.append(-s)
        d.append(j * s)
    return W1, c, d


@dataclass
class UkfPrograms:
    params: UkfParams
    fmt: FloatFormat
    layout: Layout
    sig_gen: Program
    predict: Program
    update: Program

    iteration: Program | None = None
    noise: Program | None = None

    @property
    def steps(self):
        """Step name -> program, in CTRL.step's order: ``iteration`` and ``noise`` (its
        prologue) of a core with f and h on chip, else sig_gen, predict and update."""
        if self.iteration is not None:
            return {"iteration": self.iteration, "noise": self.noise}
        three = {"sig_gen": self.sig_gen, "predict": self.predict, "update": self.update}
        return three if self.noise is None else {**three, "noise": self.noise}

    @property
    def prologue(self):
        """``(pre, main, regions)`` of a core with a ``noise`` step (f and h on chip, or the
        sqrt form): a start of ``main`` (``iteration``, or ``sig_gen``) runs ``pre`` first
        when software has written one of ``regions`` since ``pre`` last ran to its end (and
        after reset); ``None`` for the chapter's three-step core, whose sig_gen factors Q and
        R itself every time."""
        if self.noise is None:
            return None
        return ("noise", "iteration" if self.iteration is not None else "sig_gen", ("Q", "R"))


def build_ukf(params: UkfParams) -> UkfPrograms:
    """The memory layout and the three step programs for one configuration (its sizes,
    ``w0`` and ``format``)."""
    fmt = params.fmt
    n, nw, nv, m = params.n, params.nw, params.nv, params.m
    M, N = params.M, params.N
    W1, c, d = simplex_rows(M, params.w0)
    lay = Layout()
    # The processor's buffer (names fixed by the issue), then work, then constants.
    sq = params.form == "sqrt"
    x = lay.add("x", n, 1, "bus")
    P = lay.add(covariance_region(params.form), n, n, "bus")  # the sqrt form: S, P = S S^T
    Q = lay.add("Q", nw, nw, "bus")
    R = lay.add("R", nv, nv, "bus")
    chi = lay.add("sigma_points", N, M, "bus")
    chif = lay.add("sigma_points_f", N, n, "bus")
    chih = lay.add("sigma_points_h", N, m, "bus")
    z = lay.add("z", m, 1, "bus")
    models = params.models
    u = lay.add("u", models.nu, 1, "bus") if models is not None and models.nu else None
    # Work. P^a's blocks share one packed triangle (F, then L below the diagonal; D; s).
    tri = [(i, j) for b0, b1 in _blocks(params) for i in range(b0, b1) for j in range(b0, i)]
    F = lay.add("F", len(tri))
    L = lay.add("L", len(tri))
    D = lay.add("D", M)
    rD = lay.add("rD", M)  # 1 / D_j (sqrt form: 1 / s_j): one division a pivot, the column's L by multiplies
    s = lay.add("s", M)
    g = lay.add("g", M)
    e = lay.add("e", M)
    T = lay.add("T", len(tri))  # suffix sums T_rk, k < r (T_rr has its own word in "Tr")
    Tr = lay.add("Tr", M)
    dx = lay.add("dx", n, N - 1)  # predict's differences from point 0, kept for Pxz
    dlx = lay.add("delta_x", n)
    if not sq:
        Gx = lay.add("Gx", n, n)
    dz = lay.add("dz", m, N - 1)
    dlz = lay.add("delta_z", m)
    if not sq:
        Gs = lay.add("Gs", m, m)
        Gxz = lay.add("Gxz", n, m)
        S = lay.add("S", m, m)
        FS = lay.add("FS", m, m)  # F of S's LDL^T below the diagonal (23)
        LS = lay.add("LS", m, m)
        DS = lay.add("DS", m)
        rDS = lay.add("rDS", m)
        Pxz = lay.add("Pxz", n, m)
        Y = lay.add("Yfw", n, m)  # forward substitution
        U = lay.add("Udiv", n, m)  # after the division by D
        K = lay.add("K", n, m)
    inn = lay.add("innov", m)
    one = const(lay, fmt, "one", [1])(0, 0)
    w1 = const(lay, fmt, "w1", [W1])(0, 0)
    sig_c = const(lay, fmt, "sigma_c", c)
    sig_d = const(lay, fmt, "sigma_d", d)
    if sq:  # the square roots of the weights, for the triangularisations' columns
        sw = const(lay, fmt, "sqrt_w", [_sqrt(W1), _sqrt(Fraction(params.w0))])
        sw1, sw0 = sw(0, 0), (sw(0, 1) if params.w0 else None)
        tiny = lay.const("tiny", [1 << fmt.frac_bits])(0, 0)  # the smallest normal: 1 / tiny is finite
        ncols = qr_columns(params)
    ti = {ij: t for t, ij in enumerate(tri)}

    def packed(reg):  # a view of the packed triangle's region, by P^a's (row, column)
        return lambda i, j: reg(ti[i, j])
    Lp = packed(L)

    def A(i, j):  # P^a's lower triangle, block by block (4)
        for reg, (b0, b1) in zip((P, Q, R), _blocks(params)):
            if b0 <= i < b1:
                return reg(i - b0, j - b0)
        raise AssertionError

    # ---- sig_gen -------------------------------------------------------------------------
    sg = Program("sig_gen", lay, fmt)
    # With f and h on chip, the factors of Q and R and the sigma points' noise rows (x^a is 0
    # there) change only when software writes Q or R: a step of their own, ``noise``, which
    # the core runs before an iteration that follows such a write (a prologue).
    nz = Program("noise", lay, fmt) if params.on_chip or sq else sg

    for k, (b0, b1) in enumerate(_blocks(params)):
        if sq:  # P's factor is kept; Q's and R's are Cholesky factors
            if k:
                cholesky(nz, block(A, b0, b0), b1 - b0, block(Lp, b0, b0), block(s, b0), block(D, b0),
                         block(rD, b0), block(packed(F), b0, b0), one)
            continue
        ldl(sg if k == 0 else nz, block(A, b0, b0), b1 - b0, block(packed(F), b0, b0), block(Lp, b0, b0),
            block(D, b0), block(rD, b0), one)
    for j in range(M if not sq else 0):  # sqrt(D) (22), folded into sigma's rows
        prog = sg if j < n else nz
        prog.emit(Sqrt(s(j), D(j)))
        prog.emit(Dot(g(j), None, [(s(j), sig_c(0, j), False)]))
        prog.emit(Dot(e(j), None, [(s(j), sig_d(0, j), False)]))

    def l2(rr, j):  # L2's entry (unit diagonal)
        return one if rr == j else Lp(rr, j)

    def factor(rr, k):  # the sqrt form's Cholesky factor of P^a: S, then Q's and R's
        if rr < n:
            return P(rr, k)
        return s(rr) if rr == k else Lp(rr, k)

    def cterm(rr, k):  # L1's entry times c_k (sigma's row k): L2 g, or the factor's times c_k
        return (factor(rr, k), sig_c(0, k), False) if sq else (l2(rr, k), g(k), False)

    def dterm(rr, k):  # L1's entry times d_k
        return (factor(rr, k), sig_d(0, k), False) if sq else (l2(rr, k), e(k), False)

    for b, (b0, b1) in enumerate(_blocks(params)):
        prog = sg if b == 0 else nz
        for rr in range(b0, b1):
            xa = x(rr) if rr < n else None  # x^a = [x; 0; 0] (3)
            base = {rr + 1: xa}  # base[k] = T_rk, the suffix sum from column k
            for k in range(rr, b0 - 1, -1):
                if k == rr and xa is None and not sq:
                    base[k] = g(rr)  # 0 + 1 * g_r needs no multiply-add
                    continue
                dst = Tr(rr) if k == rr else T(ti[rr, k])
                if k == b0:
                    dst = chi(1, rr)  # chi_1 = T_r,b0: sigma's column 1 is all c
                prog.emit(Dot(dst, base[k + 1], [cterm(rr, k)]))
                base[k] = dst
            for i in range(N):  # chi_i = x^a + L1 sigma_i (8)
                if i == 0:
                    src, term = xa, None
                else:
                    src = base[max(b0, i - 1)] if max(b0, i - 1) <= rr else xa
                    term = dterm(rr, i - 2) if b0 <= i - 2 <= rr else None
                if term is not None:
                    prog.emit(Dot(chi(i, rr), src, [term]))
                elif src is not None and src != chi(i, rr):
                    prog.emit(Copy(chi(i, rr), src))
                # src None: a noise row beyond sigma's nonzeros, zero since reset (the bus
                # cannot write sigma_points, and nothing else writes these words)

    # ---- predict -------------------------------------------------------------------------
    pr = Program("predict", lay, fmt)

    def moments(prog, pts, dim, dd, delta):
        """Differences from point 0, d_ik = pt_k[i] - pt_0[i], and the mean's offset from
        point 0, delta_i = W1 sum_k d_ik (10)/(13) with sum W = 1; d_i0 = 0."""
        add(prog, dd, transpose(block(pts, 1)), lambda i, k: pts(0, i), one, dim, N - 1, neg=True)
        # delta^T = (w1 ... w1) dd^T: the row of sums, entry i summing row i of dd
        product(prog, transpose(delta), fill(w1), transpose(dd), 1, N - 1, dim)

    def covariance(prog, da, dela, ra, db, delb, rb, G, dst, lower, check=None):
        """(11), (14), (15) by (27)-(28) about point 0 instead of the mean (the shifted sums):
        sum_k W_k (a_k - a^)(b_k - b^)^T = W1 sum_k da_k db_k^T - dela delb^T. The residuals
        and the mean's chain then run side by side instead of one after the other."""
        for i in range(ra):
            for j in range(i + 1 if lower else rb):
                prog.emit(Dot(G(i, j), None, [(da(i, k), db(j, k), False) for k in range(N - 1)]))
                prog.emit(Dot(dst(i, j), None, [(dela(i), delb(j), True), (w1, G(i, j), False)],
                              check))

    moments(pr, chif, n, dx, dlx)
    add(pr, x, row(chif, 0), dlx, one, n)  # x^- = chi_0 + delta (10)
    if sq:
        return _sqrt_form(params, lay, sg, nz, pr, u, (one, tiny), sw1, sw0, ncols, P, x, dx, dlx, dz, dlz,
                          moments, inn)
    covariance(pr, dx, dlx, n, dx, dlx, n, Gx, mirrored(P), True, "finite")

    # ---- update --------------------------------------------------------------------------
    up = Program("update", lay, fmt)
    moments(up, chih, m, dz, dlz)
    covariance(up, dz, dlz, m, dz, dlz, m, Gs, S, True)  # S (14), lower triangle
    covariance(up, dx, dlx, n, dz, dlz, m, Gxz, Pxz, False)  # Pxz (15)
    for i in range(m):
        up.emit(Dot(inn(i), z(i), [(one, chih(0, i), True), (one, dlz(i), True)]))  # z - z^
    ldl(up, S, m, FS, LS, DS, rDS, one)
    solve_ldl(up, K, Pxz, n, m, LS, DS, rDS, one, Y, U)  # K L D L^T = Pxz (16)
    # (17): K's column 0 is solved last, so it comes last
    product(up, x, K, inn, n, m, 1, init=x, reverse=True, check="finite")
    # (19), the lower triangle mirrored
    product(up, mirrored(P), Pxz, transpose(K), n, m, n, init=P, neg=True, lower=True, reverse=True,
            check="finite")
    if models is None:
        return UkfPrograms(params, fmt, lay, sg, pr, up)
    return UkfPrograms(params, fmt, lay, sg, pr, up, _iteration(params, models, lay, sg, pr, up, u), nz)


def _iteration(params, models, lay, sg, pr, up, u) -> Program:
    """One whole iteration: sig_gen, f on every sigma point into sigma_points_f, predict, h
    on every moved point into sigma_points_h, update (:mod:`.models`). Each point's
    temporaries have words of their own, so the points' f (and h) overlap; those that read no
    point are computed once."""
    fmt, n, nw, N = params.fmt, params.n, params.nw, params.N
    chi, chif, chih = lay["sigma_points"], lay["sigma_points_f"], lay["sigma_points_h"]
    consts = list(dict.fromkeys(models.f.consts + models.h.consts))
    cw = const(lay, fmt, "model_consts", consts) if consts else None
    caddr = {c: cw(0, i) for i, c in enumerate(consts)}
    it = Program("iteration", lay, fmt)
    it.ops.extend(sg.ops)

    def apply(model, label, inputs, out):
        """``model`` on every point: ``inputs(i)`` maps an input word to its address."""
        shared = sorted(model.shared)
        own = [t for t in range(model.temps) if t not in model.shared]
        ts = lay.add(f"{label}_shared", len(shared)) if shared else None
        tp = lay.add(f"{label}_temps", N, len(own)) if own else None
        sidx, oidx = {t: k for k, t in enumerate(shared)}, {t: k for k, t in enumerate(own)}
        for i in range(N):
            def addr(w, i=i):
                if w[0] == "const":
                    return caddr[w[1]]
                if w[0] == "out":
                    return out(i, w[1])
                if w[0] == "tmp":
                    return ts(sidx[w[1]]) if w[1] in sidx else tp(i, oidx[w[1]])
                return inputs(i, w[1], w[2])
            for op in model.program_ops(addr, shared_done=i > 0):
                it.emit(op)

    def f_inputs(i, name, k):  # x and w: the point's parts; u: the iteration's
        return chi(i, k) if name == "x" else chi(i, n + k) if name == "w" else u(k)

    def h_inputs(i, name, k):  # x: the moved point; v: the point's measurement-noise part
        return chif(i, k) if name == "x" else chi(i, n + nw + k)

    apply(models.f, "f", f_inputs, chif)
    it.ops.extend(pr.ops)
    apply(models.h, "h", h_inputs, chih)
    it.ops.extend(up.ops)
    return it


def qr_columns(params) -> int:
    """Columns of the square-root form's triangularisations: the N - 1 points' weighted
    deviations, and point 0's when W0 > 0 (a zero weight adds nothing)."""
    return params.N - 1 + (1 if params.w0 else 0)


#: Terms a critical sum of a triangularisation accumulates in one chain (the next row's
#: |x|^2 and y.x): longer ones are cut into chunks summed side by side and added in a tree,
#: a shorter critical path for one more multiply-add per chunk. The other sums have a
#: reflection's time to spare and stay one chain.
CHUNK = 8


def triangularize(prog, lay, label, rows, cols, a, out, one, tiny, checked=0) -> None:
    """Lower-triangular L with L L^T = A A^T and a positive diagonal (the Cholesky factor)
    for the ``rows x cols`` matrix A at ``a(r, c)`` (overwritten), by Householder reflections
    from the right, row by row; L's entry ``(i, j)``, j <= i, is written where ``out(i, j)``
    (``(address, check)``) says. Needs rows <= cols.

    Row i's reflection takes x = A[i, i:] to (alpha, 0, ..., 0), alpha = -s, s = sign(x_0) |x|:
    v = x + s e_0, v_0 = x_0 + s (no cancellation: ``CopySign`` gives the sign), and every
    later row y becomes y - (y.v) / (s v_0) v, where s v_0 = |x|^2 + |x_0| |x| and
    y.v = y.x + y_0 s is accumulated from y.x, which needs no square root. Column i is then
    multiplied by -sign(x_0), exactly (a sign), so that L's diagonal is |x|.

    |x|^2 is checked as a pivot in the first ``checked`` rows: a zero row there (a factor of
    deficient rank: the innovation covariance's) or a NaN sets err_pivot. A later row may be
    zero (a state the format knows exactly, as binary16 does where the sigma points' spread
    is below its precision): its reflection is the identity, by dividing by
    max(s v_0, ``tiny``), the smallest normal word (whose reciprocal is finite), so that
    y.v = 0 gives 0 and not a NaN.

    Cost, for rows R and columns C: sum over i of (C - i)(1 + 2(R - 1 - i)) multiply-adds,
    plus the sums' chunks, 3 a row and 3 a pair of rows for the scalars, R square roots and
    2 (R - 1) divisions (the next row's scale is a quotient: one step, not two, on the
    critical path)."""
    if rows > cols:
        raise ValueError(f"{label}: {rows} rows need at least as many columns, not {cols}")
    w = lay.add(f"{label}_row", rows, 8)  # |x|^2, |x|, s, |x_0|, |v_0|, 1 / (s v_0), sign(x_0), s v_0
    pair = lay.add(f"{label}_pair", rows, rows)  # y.x then y.v, by (reflection, row)
    scale = lay.add(f"{label}_scale", rows, rows)  # (y.v) / (s v_0)
    chunks = -(-cols // CHUNK)
    # the sums' partial sums: a row's own and its y.x with the reflecting row, words reused
    # from one reflection to the next (the next one's sums wait for this one's updates
    # anyway; reusing pair and scale too costs P = 1 about 170 cycles)
    part = lay.add(f"{label}_part", 2 * rows, max(1, 2 * chunks - 2))

    def tree(dst, terms, slot, check=None):
        """``dst = sum(terms)``: chunks of at most CHUNK terms side by side, then a tree."""
        if len(terms) <= CHUNK:
            prog.emit(Dot(dst, None, terms, check))
            return
        cut = -(-len(terms) // CHUNK)
        size = -(-len(terms) // cut)
        vals, k = [], 0
        for at in range(0, len(terms), size):
            prog.emit(Dot(part(slot, k), None, terms[at:at + size]))
            vals, k = vals + [part(slot, k)], k + 1
        while len(vals) > 2:
            nxt = []
            for q in range(0, len(vals) - 1, 2):
                prog.emit(Dot(part(slot, k), vals[q], [(one, vals[q + 1], False)]))
                nxt, k = nxt + [part(slot, k)], k + 1
            vals = nxt + vals[len(vals) - len(vals) % 2:]
        prog.emit(Dot(dst, vals[0], [(one, vals[1], False)], check))

    for i in range(rows):
        ss, sg, sgn, ax0, av0, rb, sg1, den = (w(i, k) for k in range(8))
        cols_i = range(i, cols)
        tree(ss, [(a(i, j), a(i, j), False) for j in cols_i], i, "pivot" if i < checked else None)
        for r in range(i + 1, rows):
            terms = [(a(r, j), a(i, j), False) for j in cols_i]
            tree(pair(i, r), terms, rows + r)
        prog.emit(Sqrt(sg, ss))
        prog.emit(Copy(out(i, i)[0], sg, out(i, i)[1]))  # -sign(x_0) alpha = |x|
        if i + 1 == rows:
            break
        prog.emit(CopySign(ax0, a(i, i), one))
        prog.emit(CopySign(sgn, sg, a(i, i)))
        prog.emit(CopySign(sg1, one, a(i, i)))
        prog.emit(Dot(den, ss, [(ax0, sg, False)]))  # s v_0 = |x|^2 + |x_0| |x|
        if i >= checked:
            prog.emit(Max(den, den, tiny))
        prog.emit(Div(rb, one, den))
        prog.emit(Dot(av0, ax0, [(one, sg, False)]))  # |v_0| = |x_0| + |x|
        for r in range(i + 1, rows):
            prog.emit(Dot(pair(i, r), pair(i, r), [(a(r, i), sgn, False)]))  # y.v
            if r == i + 1:  # the next row's, on the critical path: one division, not two steps
                prog.emit(Div(scale(i, r), pair(i, r), den))
            else:
                prog.emit(Dot(scale(i, r), None, [(pair(i, r), rb, False)]))
            # -sign(x_0) (y_0 - scale v_0) = -sign(x_0) y_0 + scale |v_0|, exactly signed
            prog.emit(Dot(out(r, i)[0], None, [(sg1, a(r, i), True), (scale(i, r), av0, False)], out(r, i)[1]))
            for j in range(i + 1, cols):
                prog.emit(Dot(a(r, j), a(r, j), [(scale(i, r), a(i, j), True)]))


def _sqrt_form(params, lay, sg, nz, pr, u, consts, sw1, sw0, ncols, S, x, dx, dlx, dz, dlz, moments, inn):
    """The square-root form's predict, update and iteration (:func:`build_ukf` has built
    sig_gen, noise and predict's moments): A's columns are the points' deviations from the
    mean, weighted by sqrt(W) (point 0's only when W0 > 0), so that A A^T is the covariance.

    * predict: S^- = the triangular factor of A_x (three-step core only);
    * update: the stacked [A_z; A_x] ((m + n) x (N - 1), or x N when W0 > 0) triangularised gives
      [[S_z, 0], [Kb, S^+]] with S_z S_z^T = P_zz, Kb = P_xz S_z^-T and
      S^+ S^+^T = P^- - P_xz P_zz^-1 P_xz^T = P^+: the update's cancellation happens inside
      orthogonal transformations, so the result is always a factor of a positive
      semidefinite matrix; x^+ = x^- + Kb (S_z^-1 (z - z^)), by forward substitution (the
      gain K = Kb S_z^-1 itself is not needed)."""
    n, m, N = params.n, params.m, params.N
    fmt = params.fmt
    one, tiny = consts

    def columns(prog, rows, dd, dl, label):
        """A's rows from differences ``dd`` and offsets ``dl``: sqrt(W1) (d_k - delta)
        for the points 1..N-1, then sqrt(W0) (0 - delta) when W0 > 0."""
        neg = lay.add(f"{label}_offset", len(rows))
        for r, (i, at) in enumerate(rows):
            prog.emit(Dot(neg(r), None, [(sw1, dl(i), True)]))
            for k in range(N - 1):
                prog.emit(Dot(at(k), neg(r), [(sw1, dd(i, k), False)]))
            if sw0 is not None:
                prog.emit(Dot(at(N - 1), None, [(sw0, dl(i), True)]))

    if not params.on_chip:  # S^- for sig_gen (the on-chip iteration goes straight to update)
        Ap = lay.add("Apred", n, ncols)
        columns(pr, [(i, lambda k, i=i: Ap(i, k)) for i in range(n)], dx, dlx, "Apred")
        triangularize(pr, lay, "hpred", n, ncols, Ap, lambda i, j: (S(i, j), "finite"), one, tiny)

    up = Program("update", lay, fmt)
    chih, z = lay["sigma_points_h"], lay["z"]
    moments(up, chih, m, dz, dlz)
    for i in range(m):
        up.emit(Dot(inn(i), z(i), [(one, chih(0, i), True), (one, dlz(i), True)]))  # z - z^
    Au = lay.add("Aupd", m + n, ncols)
    columns(up, [(i, lambda k, i=i: Au(i, k)) for i in range(m)], dz, dlz, "Aupd_z")
    columns(up, [(i, lambda k, i=i: Au(m + i, k)) for i in range(n)], dx, dlx, "Aupd_x")
    Sz = lay.add("Sz", m, m)
    Kb = lay.add("Kb", n, m)

    def out(i, j):
        if i < m:
            return Sz(i, j), None
        return (Kb(i - m, j), None) if j < m else (S(i - m, j - m), "finite")
    triangularize(up, lay, "hupd", m + n, ncols, Au, out, one, tiny, checked=m)
    rSz = lay.add("rSz", m)
    y = lay.add("ysolve", m)  # S_z^-1 (z - z^), by forward substitution
    t = lay.add("ypart", m)
    for i in range(m):
        up.emit(Div(rSz(i), one, Sz(i, i)))
    forward_substitute(up, y, inn, Sz, m, rdiag=rSz, work=t)
    product(up, x, Kb, y, n, m, 1, init=x, check="finite")  # x^+ = x^- + Kb y
    pd = lay.add("P_diag", n)  # the variances P_ii = sum_j S_ij^2 (the stream ports' output)
    for i in range(n):
        up.emit(Dot(pd(i), None, [(S(i, j), S(i, j), False) for j in range(i + 1)]))
    models = params.models
    if models is None:
        return UkfPrograms(params, fmt, lay, sg, pr, up, None, nz)
    return UkfPrograms(params, fmt, lay, sg, pr, up, _iteration(params, models, lay, sg, pr, up, u), nz)
