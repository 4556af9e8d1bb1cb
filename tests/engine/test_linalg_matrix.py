"""The matrix vocabulary of engine programs (:mod:`kfgen.hdl.linalg.matrix`): each operation's
program, run by the bit-exact golden model in binary64, against numpy on small random
matrices; and the module's Kalman-filter example against numpy's KF equations."""

import textwrap

import numpy as np
import pytest

from kfgen.hdl.arith.float.format import FloatFormat
from kfgen.hdl.linalg import matrix
from kfgen.hdl.linalg.matrix import (add, block, cholesky, const, fill, forward_substitute, hadamard, ldl, mirrored,
                                     product, row, solve_ldl, transpose)
from kfgen.hdl.linalg.program import Layout, Program
from kfgen.sim.linalg.exec import from_words, run, to_words

FMT = FloatFormat.parse("binary64")
TOL = 1e-12

#: The Kalman filter of the module's docstring (its literal block).
EXAMPLE = textwrap.dedent(matrix.__doc__.split("::\n\n", 1)[1].split("\n\n", 1)[0])


class Machine:
    """A layout, one program on it and its memory: regions placed, then filled and read as
    numpy arrays."""

    def __init__(self):
        self.lay = Layout()
        self.one = const(self.lay, FMT, "one", [1])(0, 0)
        self.prog = None

    def region(self, name, rows, cols=1):
        return self.lay.add(name, rows, cols)

    def start(self):
        self.prog = Program("p", self.lay, FMT)
        self.mem = self.lay.initial_memory()
        return self.prog

    def put(self, reg, arr):
        arr = np.asarray(arr, dtype=float).reshape(reg.rows, reg.cols)
        self.mem[reg.base:reg.base + reg.size] = to_words(FMT, arr.ravel())
        return arr

    def run(self):
        status = run(self.prog, self.mem)
        assert not status.pivot and not status.nan

    def get(self, reg):
        return np.array(from_words(FMT, self.mem[reg.base:reg.base + reg.size])).reshape(reg.rows, reg.cols)


def spd(rng, n):
    a = rng.standard_normal((n, n))
    return a @ a.T + n * np.eye(n)


@pytest.mark.parametrize("rows, inner, cols", [(1, 1, 1), (3, 4, 2), (4, 2, 5)])
def test_product_with_transposes_init_and_sign(rows, inner, cols):
    rng = np.random.default_rng(rows * 100 + inner * 10 + cols)
    mc = Machine()
    a, bt, c, d = (mc.region(k, *s) for k, s in (("a", (rows, inner)), ("bt", (cols, inner)), ("c", (rows, cols)),
                                                   ("d", (rows, cols))))
    prog = mc.start()
    av, bv, cv = mc.put(a, rng.standard_normal((rows, inner))), mc.put(bt, rng.standard_normal((cols, inner))), \
        mc.put(c, rng.standard_normal((rows, cols)))
    product(prog, d, a, transpose(bt), rows, inner, cols, init=c, neg=True, reverse=True)
    mc.run()
    np.testing.assert_allclose(mc.get(d), cv - av @ bv.T, rtol=TOL, atol=TOL)


def test_symmetric_update_writes_the_lower_triangle_mirrored():
    """P - K S K^T, as the cores' covariance updates: K S into a work matrix, then the
    lower triangle of (K S) K^T subtracted, each entry written with its mirror."""
    rng = np.random.default_rng(1)
    n, m = 4, 3
    mc = Machine()
    P, K, S, KS = mc.region("P", n, n), mc.region("K", n, m), mc.region("S", m, m), mc.region("KS", n, m)
    prog = mc.start()
    Pv, Kv, Sv = mc.put(P, spd(rng, n)), mc.put(K, rng.standard_normal((n, m))), mc.put(S, spd(rng, m))
    product(prog, KS, K, S, n, m, m)
    product(prog, mirrored(P), KS, transpose(K), n, m, n, init=P, neg=True, lower=True, check="finite")
    assert len(prog.ops) == n * m + n * (n + 1) // 2
    mc.run()
    out = mc.get(P)
    assert np.array_equal(out, out.T)
    np.testing.assert_allclose(out, Pv - Kv @ Sv @ Kv.T, rtol=TOL, atol=TOL)


def test_views_add_and_hadamard():
    """Blocks of stacked matrices, rows as vectors, a broadcast scalar."""
    rng = np.random.default_rng(2)
    mc = Machine()
    st, v, s, out = mc.region("stack", 6, 3), mc.region("v", 2, 3), mc.region("s", 1), mc.region("out", 2, 3)
    prog = mc.start()
    stv, vv, sv = mc.put(st, rng.standard_normal((6, 3))), mc.put(v, rng.standard_normal((2, 3))), mc.put(s, [0.5])
    add(prog, transpose(block(out, 1)), row(v, 0), block(st, 3), mc.one, 3)  # out[1] = v[0] + stack[3:, 0]
    hadamard(prog, row(out, 0), row(v, 1), fill(s(0)), 3)  # out[0] = v[1] * s
    mc.run()
    np.testing.assert_allclose(mc.get(out), [vv[1] * sv[0, 0], vv[0] + stv[3:, 0]], rtol=TOL)


@pytest.mark.parametrize("n, rows", [(1, 2), (2, 3), (4, 3)])
def test_ldl_and_its_right_divide(n, rows):
    """x = b A^-1 by ldl then solve_ldl; L D L^T reconstructs A."""
    rng = np.random.default_rng(n)
    mc = Machine()
    A, F, L, D, rD = mc.region("A", n, n), mc.region("F", n, n), mc.region("L", n, n), mc.region("D", n), \
        mc.region("rD", n)
    b, x, fw, dv = (mc.region(k, rows, n) for k in ("b", "x", "fw", "dv"))
    prog = mc.start()
    Av, bv = mc.put(A, spd(rng, n)), mc.put(b, rng.standard_normal((rows, n)))
    ldl(prog, A, n, F, L, D, rD, mc.one)
    solve_ldl(prog, x, b, rows, n, L, D, rD, mc.one, fw, dv)
    mc.run()
    Lv = np.tril(mc.get(L), -1) + np.eye(n)
    np.testing.assert_allclose(Lv @ np.diag(mc.get(D)[:, 0]) @ Lv.T, Av, rtol=TOL)
    np.testing.assert_allclose(mc.get(x), bv @ np.linalg.inv(Av), rtol=1e-10, atol=TOL)


def test_cholesky_and_forward_substitution():
    """C C^T = A (numpy's factor), then y = C^-1 b by reciprocals of C's diagonal."""
    rng = np.random.default_rng(3)
    n = 4
    mc = Machine()
    A, L, s, d, rs, F = (mc.region(k, *sh) for k, sh in (("A", (n, n)), ("L", (n, n)), ("s", (n, 1)),
                                                          ("d", (n, 1)), ("rs", (n, 1)), ("F", (n, n))))
    b, y, t = mc.region("b", n), mc.region("y", n), mc.region("t", n)
    prog = mc.start()
    Av, bv = mc.put(A, spd(rng, n)), mc.put(b, rng.standard_normal(n))
    cholesky(prog, A, n, L, s, d, rs, F, mc.one)
    forward_substitute(prog, y, b, L, n, rdiag=rs, work=t)
    mc.run()
    C = np.tril(mc.get(L), -1) + np.diag(mc.get(s)[:, 0])
    np.testing.assert_allclose(C, np.linalg.cholesky(Av), rtol=TOL, atol=TOL)
    np.testing.assert_allclose(mc.get(y)[:, 0], np.linalg.solve(C, bv[:, 0]), rtol=1e-10, atol=TOL)


def test_kalman_filter_example_matches_numpy():
    """The module docstring's predict and update, run as written there, against numpy's KF."""
    rng = np.random.default_rng(4)
    n, m = 3, 2
    mc = Machine()
    one = mc.one
    x, P, F, Q, H, R, z = (mc.region(k, *sh) for k, sh in (("x", (n, 1)), ("P", (n, n)), ("F", (n, n)),
                                                            ("Q", (n, n)), ("H", (m, n)), ("R", (m, m)), ("z", (m, 1))))
    xp, FP, y, HP, S = mc.region("xp", n), mc.region("FP", n, n), mc.region("y", m), mc.region("HP", m, n), \
        mc.region("S", m, m)
    FS, LS, DS, rDS = mc.region("FS", m, m), mc.region("LS", m, m), mc.region("DS", m), mc.region("rDS", m)
    K, Yfw, Udiv = mc.region("K", n, m), mc.region("Yfw", n, m), mc.region("Udiv", n, m)
    prog = mc.start()
    xv, Pv, Fv, Qv = mc.put(x, rng.standard_normal(n)), mc.put(P, spd(rng, n)), \
        mc.put(F, np.eye(n) + 0.1 * rng.standard_normal((n, n))), mc.put(Q, 0.1 * spd(rng, n))
    Hv, Rv, zv = mc.put(H, rng.standard_normal((m, n))), mc.put(R, 0.5 * spd(rng, m)), mc.put(z, rng.standard_normal(m))

    exec(EXAMPLE, {**vars(matrix), **locals()})
    mc.run()

    x1, P1 = Fv @ xv, Fv @ Pv @ Fv.T + Qv
    Sv = Hv @ P1 @ Hv.T + Rv
    Kv = P1 @ Hv.T @ np.linalg.inv(Sv)
    x2, P2 = x1 + Kv @ (zv - Hv @ x1), P1 - Kv @ Hv @ P1
    np.testing.assert_allclose(mc.get(K), Kv, rtol=1e-10, atol=TOL)
    np.testing.assert_allclose(mc.get(x), x2, rtol=1e-10, atol=TOL)
    np.testing.assert_allclose(mc.get(P), P2, rtol=1e-10, atol=1e-11)
    assert np.array_equal(mc.get(P), mc.get(P).T)
