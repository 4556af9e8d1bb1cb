"""The Schur-complement graph and its golden model: the algebra against numpy in float64, the
rounded model's accuracy against float64 as a function of the condition number, the status
word, and the schedule's latency."""

import numpy as np
import pytest

from kfgen.hdl.arith.float.format import FLAG_DZ, FLAG_NV, FLAG_NX, FLAG_UF, FloatFormat
from kfgen.hdl.schur.program import SIZE_MAX, schedule, schur_program
from kfgen.sim.linalg.exec import from_words
from kfgen.sim.schur.model import (evaluate_float64, golden, golden_many, pack, random_spd, reference,
                                   status_word, unpack_matrix)


@pytest.mark.parametrize("d", range(1, SIZE_MAX + 1))
def test_graph_is_the_inverse_and_determinant(d):
    """The graph in float64 gives numpy's inverse and determinant to float64 rounding."""
    prog = schur_program(d)
    a = random_spd(d, 200, np.random.default_rng(d), cond=(1, 1e3))
    inv, det = evaluate_float64(prog, a)
    ref_inv, ref_det = reference(a)
    scale = np.max(np.abs(ref_inv), axis=(1, 2))[:, None, None]
    assert np.max(np.abs(inv - ref_inv) / scale) < 1e-11
    assert np.max(np.abs(det - ref_det) / np.abs(ref_det)) < 1e-11
    assert prog.count("div") == d == len(prog.pivots), "one division per 1 x 1 block, its pivot checked"


def test_two_by_two_is_the_slides_formula():
    """d = 2: two divisions (1/a, 1/s), seven multiplies, one add, one subtract, and a longest
    path of two divisions, two multiplies and two adds."""
    prog = schur_program(2)
    assert {op: prog.count(op) for op in ("div", "mul", "add", "sub")} == {"div": 2, "mul": 7, "add": 1, "sub": 1}
    for lm, la, ld in ((7, 6, 32), (1, 1, 15), (3, 7, 27), (6, 7, 27), (2, 3, 5)):
        ready = schedule(prog, {"mul": lm, "add": la, "sub": la, "div": ld})
        assert max(ready[n] for n in prog.outputs) == 2 * ld + 2 * lm + 2 * la
    a, b, c = 4.0, 1.0, 3.0
    inv, det = evaluate_float64(prog, np.array([[[a, b], [b, c]]]))
    s = c - b * b / a
    assert np.allclose(inv[0], [[1 / a + b * b / (a * a * s), -b / (a * s)], [-b / (a * s), 1 / s]], rtol=1e-15)
    assert det[0] == pytest.approx(a * s, rel=1e-15)


# (format, d, matrices, condition numbers, scales): the accuracy runs. binary16's scale keeps
# the determinant and the inverse inside its range.
ACCURACY = [
    ("binary32", 2, 400, (1, 1e5), (1e-3, 1e3)),
    ("binary32", 3, 300, (1, 1e5), (1e-3, 1e3)),
    ("binary32", 4, 300, (1, 1e5), (1e-3, 1e3)),
    ("binary16", 2, 400, (1, 1e2), (0.5, 2)),
    ("binary16", 4, 200, (1, 1e2), (0.5, 2)),
]


@pytest.mark.parametrize("fmt_name, d, n, cond, scale", ACCURACY, ids=[f"{a[0]}-d{a[1]}" for a in ACCURACY])
def test_accuracy_against_float64(fmt_name, d, n, cond, scale):
    """The rounded model's inverse and determinant against numpy's float64 ones, for the matrix
    the words hold: max|X - A^-1| / max|A^-1| and |det - det A| / |det A| are at most
    2 d kappa(A) kappa(P) u, u = 2^-p, kappa the 2-norm condition number and P the leading
    floor(d/2) block, whose inverse the recursion forms explicitly (kappa(P) = 1 for d <= 3)."""
    fmt = FloatFormat.parse(fmt_name)
    u = 2.0 ** -fmt.precision
    prog = schur_program(d)
    words = pack(fmt, random_spd(d, n, np.random.default_rng(10 + d), cond=cond, scale=scale))
    results, status = golden_many(prog, fmt, words)
    worst_inv = worst_det = 0.0
    for w, r, st in zip(words, results, status):
        # at most inexact, and underflow (a tiny off-diagonal's square in binary16)
        assert not st.pivot and not st.nan and not st.flags & ~(FLAG_NX | FLAG_UF), st
        a = unpack_matrix(fmt, d, w)
        bound = 2 * d * np.linalg.cond(a) * np.linalg.cond(a[:d // 2, :d // 2]) * u
        ref = np.linalg.inv(a)
        err_inv = np.max(np.abs(unpack_matrix(fmt, d, r[:-1]) - ref)) / np.max(np.abs(ref))
        err_det = abs(from_words(fmt, [r[-1]])[0] / np.linalg.det(a) - 1)
        worst_inv, worst_det = max(worst_inv, err_inv / bound), max(worst_det, err_det / bound)
    assert worst_inv <= 1 and worst_det <= 1, (worst_inv, worst_det)
    assert worst_inv > 0.02, "the bound should not be loose by orders of magnitude"


def _status(fmt, d, m):
    prog = schur_program(d)
    return golden(prog, fmt, pack(fmt, np.asarray(m, dtype=float)[None])[0])[1]


@pytest.mark.parametrize("m, pivot", [
    ([[4.0, 1.0], [1.0, 3.0]], False),
    ([[0.0, 1.0], [1.0, 3.0]], True),     # a = 0
    ([[-0.0, 0.0], [0.0, 3.0]], True),    # a = -0
    ([[-2.0, 1.0], [1.0, 3.0]], True),    # a < 0
    ([[1.0, 2.0], [2.0, 4.0]], True),     # s = 0: singular
    ([[1.0, 2.0], [2.0, 1.0]], True),     # s < 0: indefinite
    ([[1.0, 0.0], [0.0, -1e-30]], True),  # s < 0, tiny
])
def test_status_pivot(m, pivot):
    st = _status(FloatFormat.parse("binary32"), 2, m)
    assert st.pivot == pivot and not st.nan


def test_status_words():
    fmt = FloatFormat.parse("binary32")
    prog = schur_program(2)
    one, nan = fmt.pack(0, fmt.bias, 0), fmt.canonical_nan
    # a NaN anywhere: nan; in a pivot's path also pivot; NaN operands of the units are quiet:
    # no NV (a signalling one would raise it)
    for k in range(3):
        words = [one, 0, one]
        words[k] = nan
        res, st = golden(prog, fmt, words)
        assert st.nan and st.pivot and all(fmt.is_nan(w) for w in res), k
        assert not st.flags & FLAG_NV, k
    _, st = golden(prog, fmt, [one, fmt.canonical_nan ^ fmt.quiet_bit | 1, one])  # signalling NaN
    assert st.nan and st.flags & FLAG_NV
    # a zero pivot divides by zero: pivot and DZ
    _, st = golden(prog, fmt, [0, 0, one])
    assert st.pivot and st.flags & FLAG_DZ and not st.nan
    # the m_axis_tuser word round-trips
    for word in range(1 << 7):
        assert status_word(word).word == word
