"""Golden models of the Schur-complement unit, and the matrices its tests feed it.

* :func:`golden`: the bit-exact twin of :class:`kfgen.hdl.schur.core.Schur`: the same graph
  (:func:`kfgen.hdl.schur.program.schur_program`), every operation rounded once by the exact
  reference :func:`kfgen.sim.float_ref.ref_op` as the hardware's units round it, the same
  status word.
* :func:`evaluate_float64`: the same graph in float64, vectorised over many matrices, which
  holds the graph's algebra against :func:`reference` (numpy's ``inv`` and ``det``).
* :func:`random_spd`: seeded symmetric positive-definite matrices of a chosen condition number
  and scale; :func:`stimulus`: those, symmetric matrices that are not positive definite,
  random words (NaNs, infinities, subnormals) and the status cases, as input words.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from kfgen.hdl.arith.float.format import FloatFormat
from kfgen.hdl.schur.program import Program, upper
from kfgen.sim.float_ref import ref_op
from kfgen.sim.linalg.exec import from_words, to_words

__all__ = ["Status", "golden", "golden_many", "evaluate_float64", "reference", "random_spd", "stimulus",
           "pack", "unpack_matrix", "status_word"]


@dataclass(frozen=True)
class Status:
    """``pivot``: a pivot not > 0; ``nan``: a NaN input word; ``flags``: the OR of every
    operation's IEEE flags (NX, UF, OF, DZ, NV from bit 0)."""

    pivot: bool = False
    nan: bool = False
    flags: int = 0

    @property
    def word(self) -> int:
        """The ``m_axis_tuser`` word (:func:`kfgen.hdl.schur.core.status_layout`)."""
        return int(self.pivot) | int(self.nan) << 1 | self.flags << 2


def status_word(word: int) -> Status:
    return Status(bool(word & 1), bool(word >> 1 & 1), word >> 2 & 0x1F)


def golden(prog: Program, fmt: FloatFormat, words: list[int]) -> tuple[list[int], Status]:
    """One matrix: its upper-triangle words (row by row) in, ``(result words, status)`` out,
    the result the inverse's upper triangle row by row and then the determinant."""
    sign, one = fmt.sign_mask, fmt.pack(0, fmt.bias, 0)
    inputs = {prog.inputs[ij]: w for ij, w in zip(upper(prog.d), words)}
    val, flags = [], 0
    for n, node in enumerate(prog.nodes):
        if node.op == "in":
            w = inputs[n]
        elif node.op == "one":
            w = one
        elif node.op == "neg":
            w = val[node.args[0]] ^ sign
        else:
            w, fl = ref_op(node.op, fmt, val[node.args[0]], val[node.args[1]])
            flags |= fl
        val.append(w)
    pivot = any(fmt.is_nan(val[n]) or val[n] & sign or not val[n] & ~sign for n in prog.pivots)
    nan = any(fmt.is_nan(w) for w in words)
    return [val[n] for n in prog.outputs], Status(pivot, nan, flags)


def golden_many(prog: Program, fmt: FloatFormat, matrices) -> tuple[list[list[int]], list[Status]]:
    """:func:`golden` over a list of input word lists."""
    out = [golden(prog, fmt, list(ws)) for ws in matrices]
    return [o[0] for o in out], [o[1] for o in out]


def evaluate_float64(prog: Program, a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The graph in float64 on ``a`` (``(n, d, d)``, symmetric): ``(inverses, determinants)``."""
    a = np.asarray(a, dtype=np.float64)
    where = {n: ij for ij, n in prog.inputs.items()}
    val = []
    with np.errstate(all="ignore"):
        for n, node in enumerate(prog.nodes):
            if node.op == "in":
                v = a[:, where[n][0], where[n][1]]
            elif node.op == "one":
                v = np.ones(len(a))
            elif node.op == "neg":
                v = -val[node.args[0]]
            else:
                x, y = val[node.args[0]], val[node.args[1]]
                v = {"mul": x * y, "add": x + y, "sub": x - y, "div": x / y}[node.op]
            val.append(v)
    d = prog.d
    inv = np.empty((len(a), d, d))
    for (i, j), n in prog.inverse.items():
        inv[:, i, j] = inv[:, j, i] = val[n]
    return inv, val[prog.det]


def reference(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """numpy's float64 ``inv`` and ``det`` of ``a`` (``(n, d, d)``)."""
    return np.linalg.inv(a), np.linalg.det(a)


def random_spd(d: int, n: int, rng: np.random.Generator, cond=(1.0, 1e3), scale=(1e-3, 1e3)) -> np.ndarray:
    """``n`` symmetric positive-definite ``d x d`` matrices ``s V diag(l) V^T``: ``V`` a random
    rotation, eigenvalues ``l`` log-spaced from 1 down to ``1/kappa``, ``kappa`` log-uniform in
    ``cond``, ``s`` log-uniform in ``scale``."""
    out = np.empty((n, d, d))
    for k in range(n):
        v, _ = np.linalg.qr(rng.standard_normal((d, d)))
        kappa = math.exp(rng.uniform(*np.log(cond)))
        lam = kappa ** -np.linspace(0, 1, d) if d > 1 else np.ones(1)
        s = math.exp(rng.uniform(*np.log(scale)))
        m = s * (v * lam) @ v.T
        out[k] = (m + m.T) / 2
    return out


def pack(fmt: FloatFormat, a: np.ndarray) -> list[list[int]]:
    """The upper triangles of float64 matrices as input words, each element rounded once."""
    d = a.shape[1]
    cols = [to_words(fmt, a[:, i, j]) for i, j in upper(d)]
    return [list(ws) for ws in zip(*cols)]


def unpack_matrix(fmt: FloatFormat, d: int, words: list[int]) -> np.ndarray:
    """An upper triangle's words (an input, or a result's first words) as a float64 matrix."""
    out = np.empty((d, d))
    for (i, j), v in zip(upper(d), from_words(fmt, words)):
        out[i, j] = out[j, i] = v
    return out


def _status_cases(fmt: FloatFormat, d: int) -> list[list[int]]:
    """Matrices that must raise a status bit: a first pivot 0, -0 or negative, a later pivot
    (a Schur complement) 0 or negative, a NaN in each position, and infinities."""
    n_words = len(upper(d))
    eye = np.eye(d)

    def words(m):
        return pack(fmt, m[None])[0]

    cases = []
    for a00 in (0.0, -0.0, -1.0):
        m = eye.copy()
        m[0, 0] = a00
        cases.append(words(m))
    for s in (0.0, -2.0):  # the last pivot: A[-1, -1] - (what the rest takes away)
        m = eye.copy()
        m[0, -1] = m[-1, 0] = 1.0 if d > 1 else 0.0
        m[-1, -1] = 1.0 + s
        cases.append(words(m))
    ident = words(eye)
    for k in range(n_words):
        for special in (fmt.canonical_nan, fmt.canonical_nan | fmt.sign_mask | 1, fmt.inf(0), fmt.inf(1)):
            w = list(ident)
            w[k] = special
            cases.append(w)
    return cases


def stimulus(fmt: FloatFormat, d: int, n: int, rng: np.random.Generator) -> list[list[int]]:
    """About ``n`` input word lists: the status cases, then a shuffle of positive-definite
    matrices (condition number 1..1e3, scale 1e-3..1e3; some closer to the format's limits),
    symmetric matrices of random signs, and random words."""
    cases = _status_cases(fmt, d)
    rest = max(0, n - len(cases))
    n_spd, n_sym = rest * 6 // 10, rest * 2 // 10
    n_raw = rest - n_spd - n_sym
    spd = pack(fmt, random_spd(d, n_spd, rng))
    sym = rng.standard_normal((n_sym, d, d)) * np.exp(rng.uniform(-3, 3, (n_sym, 1, 1)))
    sym = pack(fmt, (sym + sym.transpose(0, 2, 1)) / 2)
    raw = [[int(w) for w in rng.integers(0, 1 << fmt.width, len(upper(d)), dtype=np.uint64)]
           for _ in range(n_raw)] if fmt.width <= 64 else []
    mixed = spd + sym + raw
    order = rng.permutation(len(mixed))
    return cases + [mixed[k] for k in order]
