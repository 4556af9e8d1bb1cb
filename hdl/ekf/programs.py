"""The EKF's iteration as one engine program.

One start runs one predict and one update, in the matrix vocabulary
(:mod:`kfgen.hdl.linalg.matrix`), with the application's f and h and their Jacobians compiled
(:mod:`.models`):

predict
  x^- = f(x, 0, u), F and L at (x, 0, u) (one model: their common terms computed once);
  P^- = [F L] diag(P, Q) [F L]^T = F P F^T + L Q L^T, one triangle, mirrored.
update
  z^ = h(x^-, 0), H and M at x^-; y = z - z^;
  S = [H M] diag(P^-, R) [H M]^T = H P^- H^T + M R M^T (its lower triangle);
  K = (H P^-)^T S^-1 by LDL^T (err_pivot when a pivot of S is not positive);
  x = x^- + K y, P = P^- - K (H P^-), one triangle, mirrored (err_nan on a NaN or infinity).

The Jacobians' structure is known at generation and costs nothing: a structural zero is a
view's ``None`` and its terms are dropped; a 1 is the constant 1, whose terms become a sum's
addend, so a row of F that is a unit vector makes F P's row a row of P (no operation), and
additive noise (L or M a selection) makes L Q L^T and M R M^T the words of Q and R added in;
the other constants are constant words. P^- is kept in ``P_pred`` (P is read until the update
writes it).
"""

from __future__ import annotations

from dataclasses import dataclass

from kfgen.hdl.arith.float.format import FloatFormat

from ..describe import ParamError
from ..linalg.matrix import (add, beside, const, diagonal_blocks, ldl, mirrored, product, solve_ldl, sparse_product,
                             transpose)
from ..linalg.program import Layout, Program
from .jacobian import Jacobian, Linearised
from .models import EkfModels
from .params import EkfParams

__all__ = ["EkfPrograms", "build_ekf"]


@dataclass
class EkfPrograms:
    params: EkfParams
    fmt: FloatFormat
    layout: Layout
    iteration: Program
    jacobians: dict  # name -> view of the Jacobian's entries (an address, None for a structural zero)

    @property
    def steps(self):
        """Step name -> program: the one step, ``iterate`` (the manifest's ``cycles`` key)."""
        return {"iterate": self.iteration}


def _instantiate(prog, lay, lin: Linearised, label, inputs: dict, out, caddr):
    """``lin``'s model in ``prog``: its outputs into ``out(k)``, its temporaries in a region of
    their own, ``inputs`` (name -> region) read; returns the word -> address map."""
    temps = lay.add(f"{label}_temps", lin.model.temps) if lin.model.temps else None

    def addr(w):
        if w[0] == "const":
            return caddr[w[1]]
        if w[0] == "out":
            return out(w[1])
        if w[0] == "tmp":
            return temps(w[1])
        return inputs[w[1]](w[2])
    for op in lin.model.program_ops(addr, shared_done=False):
        prog.emit(op)
    return addr


def _view(jac: Jacobian, addr):
    def view(i, j=0):
        w = jac.word(i, j)
        return None if w is None else addr(w)
    return view


def build_ekf(params: EkfParams, models: EkfModels) -> EkfPrograms:
    """The memory layout and the iteration's program for one configuration and the
    application's compiled models.

    Raises
    ------
    ParamError
        ``app``: models of other sizes than the parameters'.
    """
    if models.sizes != params.sizes:
        raise ParamError("app", f"the application has n, nw, nv, m, nu = {models.sizes}, the core {params.sizes}")
    fmt = params.fmt
    n, nw, nv, m, nu = params.sizes
    lay = Layout()
    # The processor's buffer, then work, then constants.
    x = lay.add("x", n, 1, "bus")
    P = lay.add("P", n, n, "bus")
    Q = lay.add("Q", nw, nw, "bus")
    R = lay.add("R", nv, nv, "bus")
    z = lay.add("z", m, 1, "bus")
    u = lay.add("u", nu, 1, "bus") if nu else None
    xp = lay.add("x_pred", n)
    Pp = lay.add("P_pred", n, n)
    GX = lay.add("FL_PQ", n, n + nw)  # [F L] diag(P, Q), where it takes an operation
    zh = lay.add("z_pred", m)
    y = lay.add("innov", m)
    HX = lay.add("HM_PR", m, n + nv)  # [H M] diag(P^-, R)
    S = lay.add("S", m, m)
    FS = lay.add("FS", m, m)  # F of S's LDL^T below the diagonal
    LS = lay.add("LS", m, m)
    DS = lay.add("DS", m)
    rDS = lay.add("rDS", m)
    K = lay.add("K", n, m)
    Y = lay.add("Yfw", n, m)  # forward substitution
    U = lay.add("Udiv", n, m)  # after the division by D
    one = const(lay, fmt, "one", [1])(0, 0)
    words = [w for lin in (models.f, models.h) for w in lin.model.consts]
    words += [w[1] for jac in models.jacobians.values() for w in jac.entries.values() if w[0] == "const"]
    consts = [c for c in dict.fromkeys(words) if c != 1.0]
    cw = const(lay, fmt, "model_consts", consts) if consts else None
    caddr = {1.0: one} | {c: cw(0, k) for k, c in enumerate(consts)}

    it = Program("iteration", lay, fmt)
    # ---- predict -------------------------------------------------------------------------
    fa = _instantiate(it, lay, models.f, "f", {"x": x, "u": u}, xp, caddr)
    F, L = _view(models.F, fa), _view(models.L, fa)
    G = beside(F, L, n)
    A = sparse_product(it, GX, G, diagonal_blocks(P, Q, n), n, n + nw, n + nw, one)
    product(it, mirrored(Pp), A, transpose(G), n, n + nw, n, lower=True, one=one)
    # ---- update --------------------------------------------------------------------------
    ha = _instantiate(it, lay, models.h, "h", {"x": xp}, zh, caddr)
    H, M = _view(models.H, ha), _view(models.M, ha)
    add(it, y, z, zh, one, m, neg=True)  # y = z - z^
    Gh = beside(H, M, n)
    B = sparse_product(it, HX, Gh, diagonal_blocks(Pp, R, n), m, n + nv, n + nv, one)
    product(it, S, B, transpose(Gh), m, n + nv, m, lower=True, one=one)
    ldl(it, S, m, FS, LS, DS, rDS, one)
    zero = {}

    def HP(i, j):  # H P^-: a row of H that is all zero leaves a zero row (a constant word)
        a = B(i, j)
        if a is None:
            if not zero:
                zero[0] = const(lay, fmt, "zero", [0])(0, 0)
            a = zero[0]
        return a
    solve_ldl(it, K, transpose(HP), n, m, LS, DS, rDS, one, Y, U)  # K L D L^T = P^- H^T
    product(it, x, K, y, n, m, 1, init=xp, check="finite")
    product(it, mirrored(P), K, HP, n, m, n, init=Pp, neg=True, lower=True, check="finite")
    return EkfPrograms(params, fmt, lay, it, {"F": F, "L": L, "H": H, "M": M})
