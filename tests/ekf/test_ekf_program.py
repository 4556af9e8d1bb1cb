"""The EKF's parameters and program: validation, the structured products of the matrix
vocabulary (structural zeros dropped, ones folded) against numpy through the golden executor,
and what the Jacobians' structure saves in the shipped applications' iterations."""

import numpy as np
import pytest

from kfgen.hdl.arith.float.format import FloatFormat
from kfgen.hdl.describe import ParamError
from kfgen.hdl.ekf.params import EkfParams
from kfgen.hdl.ekf.steps import programs
from kfgen.hdl.linalg.matrix import beside, const, diagonal_blocks, mirrored, product, sparse_product, transpose
from kfgen.hdl.linalg.program import Copy, Dot, Layout, Program
from kfgen.sim.linalg.exec import from_words, run, to_words

B64 = FloatFormat.parse("binary64")
SIZES = dict(states=4, observations=2, process_noise=2, measurement_noise=2)


def test_params_defaults_and_sizes():
    p = EkfParams("tracker:Tracker", **SIZES, inputs=0, pes=2)
    assert p.sizes == (4, 2, 2, 2, 0) and p.div_sqrt == "pipelined" and p.banks == 4 and p.format.name == "binary32"
    assert EkfParams("tracker:Tracker", **SIZES, format="binary64").fmt.width == 64


@pytest.mark.parametrize("kw, param", [
    (dict(app=""), "app"), (dict(app=3), "app"), (dict(states=0), "states"), (dict(observations=256), "observations"),
    (dict(process_noise=True), "process_noise"), (dict(inputs=-1), "inputs"), (dict(pes=0), "pes"),
    (dict(pes=17), "pes"), (dict(div_sqrt="fast"), "div_sqrt"), (dict(banks=1), "banks"),
    (dict(pes=8, banks=32), "pes"),
    (dict(format="binary128"), "format"), (dict(streams=1), "streams"), (dict(irq="yes"), "irq"),
    (dict(name="module"), "name"), (dict(name="2x"), "name"), (dict(app=None), "app"),
    (dict(app="nowhere:Nothing"), "app"), (dict(states=5), "app"), (dict(address_width=4), "address_width"),
])
def test_params_refused_in_one_line(kw, param):
    args = {"app": "tracker:Tracker", **SIZES, **kw}
    with pytest.raises(ParamError) as err:
        EkfParams(**args)
    assert err.value.param == param and "\n" not in str(err.value)


def test_the_application_sizes_the_core(tracker):
    p = EkfParams("tracker:Tracker")
    assert p.sizes == (4, 2, 2, 2, 0) and p.address_width == 8 and p.models is EkfParams("tracker:Tracker").models


def test_models_of_other_sizes_are_refused(tracker, nanosat):
    _, models = nanosat
    with pytest.raises(ParamError, match=r"app: the application has n, nw, nv, m, nu = \(7, 7, 6, 6, 3\)"):
        programs(EkfParams("tracker:Tracker"), models)


def test_structured_products_are_numpy():
    """[F L] diag(P, Q) [F L]^T with F's zeros and ones and L a selection: the same as numpy,
    fewer multiply-adds than dense, and rows of F that are unit vectors cost nothing."""
    rng = np.random.default_rng(2)
    n, nw = 4, 2
    F = rng.normal(size=(n, n))
    F[2] = [0, 0, 1, 0]  # a unit row: F P's row is P's
    F[0, 1] = F[3, 0] = 0
    F[1, 1] = 1.0
    L = np.array([[0, 0], [1, 0], [0, 0], [0, 1.0]])
    A = rng.normal(size=(n, n))
    P = A @ A.T
    Q = np.diag([2.0, 3.0])
    lay = Layout()
    Fr, Lr, Pr, Qr = (lay.add(k, *v.shape) for k, v in (("F", F), ("L", L), ("P", P), ("Q", Q)))
    W = lay.add("W", n, n + nw)
    out = lay.add("out", n, n)
    one = const(lay, B64, "one", [1])(0, 0)

    def structured(reg, mat):
        return lambda i, j=0: None if mat[i, j] == 0 else one if mat[i, j] == 1 else reg(i, j)
    G = beside(structured(Fr, F), structured(Lr, L), n)
    prog = Program("p", lay, B64)
    V = sparse_product(prog, W, G, diagonal_blocks(Pr, Qr, n), n, n + nw, n + nw, one)
    assert [V(2, j) for j in range(n)] == [Pr(2, j) for j in range(n)]  # no operation
    assert V(0, n) is None and V(1, n) == Qr(0, 0)  # L's zero row, and a one: Q's own word
    product(prog, mirrored(out), V, transpose(G), n, n + nw, n, lower=True, one=one)
    # dense: n (n + nw) (n + nw) for [F L] diag(P, Q), n (n + 1) / 2 (n + nw) for the triangle
    assert prog.fma_count < (n * (n + nw) + n * (n + 1) // 2) * (n + nw) // 2
    mem = lay.initial_memory()
    for reg, mat in ((Fr, F), (Lr, L), (Pr, P), (Qr, Q)):
        mem[reg.base:reg.base + reg.size] = to_words(B64, mat.ravel())
    run(prog, mem)
    got = np.array(from_words(B64, mem[out.base:out.base + out.size])).reshape(n, n)
    np.testing.assert_allclose(got, F @ P @ F.T + L @ Q @ L.T, rtol=1e-13)


def test_a_product_of_a_word_and_ones_is_a_copy_or_nothing():
    lay = Layout()
    a, d = lay.add("a", 2, 2), lay.add("d", 2, 2)
    one = const(lay, B64, "one", [1])(0, 0)
    prog = Program("p", lay, B64)
    eye = lambda i, j=0: one if i == j else None  # noqa: E731
    product(prog, d, eye, a, 2, 2, 2, one=one)
    assert prog.ops == [Copy(d(0, 0), a(0, 0)), Copy(d(0, 1), a(0, 1)), Copy(d(1, 0), a(1, 0)), Copy(d(1, 1), a(1, 1))]
    prog.ops.clear()
    product(prog, d, lambda i, j=0: None, a, 2, 2, 2)
    assert prog.ops == []  # every entry a structural zero: nothing written
    product(prog, d, eye, a, 2, 2, 2)  # without one: the ones are multiplied
    assert prog.ops[0] == Dot(d(0, 0), None, [(one, a(0, 0), False)])


def test_additive_noise_costs_no_product(tracker, nanosat):
    """M = I: S's entries start from R's words (M R M^T is no operation); L = dt I: one
    multiply-add a word of Q, and one an entry of P^-."""
    app, models = tracker
    progs = programs(EkfParams("tracker:Tracker", **SIZES, format="binary64"), models)
    lay = progs.layout
    S, R = lay["S"], lay["R"]
    inits = {op.dst[0]: op.init for op in progs.iteration.ops if isinstance(op, Dot) and op.dst[0] in
             {S(i, j) for i in range(2) for j in range(i + 1)}}
    assert inits == {S(i, j): R(i, j) for i in range(2) for j in range(i + 1)}
    app, models = nanosat
    p = EkfParams("nanosat:Nanosat", 7, 6, 7, 6, 3)
    progs = programs(p, models)
    W = progs.layout["FL_PQ"]
    lq = {W(i, 7 + j) for i in range(7) for j in range(7)}  # L Q
    noise = [op for op in progs.iteration.ops if isinstance(op, Dot) and op.dst[0] in lq]
    assert len(noise) == 49 and all(len(op.terms) == 1 for op in noise)
