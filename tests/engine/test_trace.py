"""The model compiler (kfgen.hdl.engine.trace): what tracing folds and shares, what it
refuses (one line naming the construct, the file and the line), and that a traced function
computes what the function computes, through the golden executor."""

import math

import numpy as np
import pytest

from kfgen.hdl.arith.float.format import FloatFormat
from kfgen.hdl.engine.trace import TraceError, trace
from kfgen.hdl.linalg.program import Layout, Program
from kfgen.sim.linalg.exec import from_words, run, to_words

B64 = FloatFormat.parse("binary64")


def _dots(model):
    return [op for op in model.ops if op[0] == "dot"]


def test_constants_fold_and_zero_products_vanish():
    def f(x, u):
        return np.array([0.5 * 0.01 * x[0] + 0.0 * x[1] + 1.0 * x[2], x[1] * 1.0, 2.0 * 3.0])

    model = trace(f, {"x": 3, "u": 0})
    assert model.outputs == 3
    first = _dots(model)[0]
    # x[2] (coefficient 1) is the chain's addend; 0.5 * 0.01 folded into one constant; x[1] gone
    assert first[2] == ("in", "x", 2)
    assert first[3] == ((("const", 0.005), ("in", "x", 0), False),)
    assert ("copy", ("out", 1), ("in", "x", 1)) in model.ops
    assert ("copy", ("out", 2), ("const", 6.0)) in model.ops
    assert model.fma_count == 1


def test_common_subexpressions_once_and_shared_words():
    def f(x, u):
        om = u - x[:2]  # reads x: per point
        k = 3.0 * (u[0] + u[1])  # reads only u: once for every point
        return np.r_[om * om, k * x[0], np.sqrt(om[0]) + np.sqrt(om[0])]

    model = trace(f, {"x": 2, "u": 2}, varying=("x",))
    assert sum(op[0] == "sqrt" for op in model.ops) == 1
    # om[0] and om[1] computed once each, though each is used twice
    assert sum(1 for op in model.ops if op[0] == "dot" and op[2] == ("in", "u", 0)) == 1
    shared = [op for op in model.ops if model.op_is_shared(op)]
    assert [op[2:] for op in shared] == [(None, ((("const", 3.0), ("in", "u", 0), False),
                                                 (("const", 3.0), ("in", "u", 1), False)))]


def test_sum_is_one_chain_in_program_order():
    def f(x, u):
        return np.array([x[0] * x[1] - x[2] * x[3] + x[4] * x[5]])

    model = trace(f, {"x": 6, "u": 0})
    (dot,) = _dots(model)
    assert [(a[2], b[2], neg) for a, b, neg in dot[3]] == [(0, 1, False), (2, 3, True), (4, 5, False)]


def _golden(model, inputs: dict, fmt=B64):
    """Run ``model`` once on ``inputs`` (name -> values) through the golden executor."""
    lay = Layout()
    regs = {name: lay.add(name, max(1, len(v))) for name, v in inputs.items()}
    out = lay.add("out", model.outputs)
    tmp = lay.add("tmp", max(1, model.temps))
    consts = model.consts
    cr = lay.const("c", to_words(fmt, consts)) if consts else None
    prog = Program("m", lay, fmt)

    def addr(w):
        return {"in": lambda: regs[w[1]](w[2]), "out": lambda: out(w[1]), "tmp": lambda: tmp(w[1]),
                "const": lambda: cr(0, consts.index(w[1]))}[w[0]]()

    for op in model.program_ops(addr, shared_done=False):
        prog.emit(op)
    mem = lay.initial_memory()
    for name, v in inputs.items():
        mem[regs[name].base:regs[name].base + len(v)] = to_words(fmt, v)
    run(prog, mem)
    return np.array(from_words(fmt, mem[out.base:out.base + out.size]))


def _model_fn(x, w, u):
    """Every construct that traces, once or more."""
    x = np.asarray(x, dtype=np.float64)
    c, s = x[0], x[1]
    rot = np.array([[c, -s], [s, c]])
    v = rot @ (u - w) / 4.0 + np.maximum(x[2:4], -x[2:4])
    m = np.vstack([np.hstack([np.eye(2) * 0.5, np.zeros((2, 1))]), np.ones((1, 3)) / 3.0])
    y = np.matmul(m, np.concatenate([x[:2], [np.float64(2.0)]])) + np.diag(np.outer(u, w)).sum()
    stacked = np.stack([x[:2], w])
    return np.r_[v, np.hypot(v[0], v[1]), np.exp(-x[2] ** 2 / 2), abs(x[3]), np.minimum(x[2], x[3]),
                 (x[0] + 1.5) ** -2, np.dot(x[:2], u) / (1.0 + x[1] * x[1]), np.cross(x[:3], u[[0, 1, 0]]),
                 y, np.sum(stacked, axis=0), np.square(x[3]) - x[3] ** 3 + +x[0] - (-x[1]),
                 np.absolute(x[2]) * 0.0 + 1.0 * np.sqrt(x[0] * x[0] + 2.0),
                 np.sin(x[0]) * np.cos(x[1]), np.cos(3.0 * x[2]), np.arctan2(x[3], -x[0] + w[0])]


def test_traced_function_computes_the_function():
    """binary64 through the golden executor equals the float64 function to a few ulps."""
    model = trace(_model_fn, {"x": 4, "w": 2, "u": 2})
    rng = np.random.default_rng(5)
    for _ in range(20):
        x, w, u = rng.normal(size=4), rng.normal(size=2), rng.normal(size=2)
        want = _model_fn(x, w, u)
        got = _golden(model, {"x": x, "w": w, "u": u})
        assert np.allclose(got, want, rtol=1e-13, atol=1e-14), (got, want)


def test_traced_function_in_binary32_rounds_each_operation():
    model = trace(_model_fn, {"x": 4, "w": 2, "u": 2})
    x, w, u = np.array([0.3, -0.7, 0.25, -1.5]), np.array([0.1, 0.2]), np.array([1.0, -2.0])
    got = _golden(model, {"x": x, "w": w, "u": u}, FloatFormat.parse("binary32"))
    assert np.allclose(got, _model_fn(x, w, u), rtol=1e-5, atol=1e-6)


def _refused(fn, *says):
    with pytest.raises(TraceError) as info:
        trace(fn, {"x": 2, "u": 0})
    text = str(info.value)
    assert "\n" not in text and __file__ in text, text
    for s in says:
        assert s in text, text
    return text


def test_data_dependent_control_flow_is_refused():
    def f(x, u):
        if x[0] > 0:
            return x
        return -x
    line = f.__code__.co_firstlineno + 1
    _refused(f, "comparison", f"{__file__}:{line}")


def test_math_on_traced_values_is_refused():
    def f(x, u):
        return np.array([math.sqrt(x[0]), x[1]])
    _refused(f, "conversion")


def test_numpy_outside_the_list_is_refused():
    def f(x, u):
        return np.array([np.linalg.norm(x), x[0]])
    _refused(f, "np.linalg")


def test_functions_without_a_unit_are_refused():
    def f(x, u):
        return np.array([np.tan(x[0]), np.arctan(x[1])])
    _refused(f, "np.tan", "no unit")


def test_trigonometry_traces_to_its_units():
    """np.sin, np.cos and np.arctan2 become one operation each on their shared units (common
    subexpressions once, constants folded)."""
    def f(x, u):
        a = np.sin(x[0]) + np.cos(x[0]) * np.sin(x[0])
        return np.array([a, np.arctan2(x[1], x[0]), np.arctan2(1.0, 2.0) * x[1], np.cos(0.5)])
    model = trace(f, {"x": 2, "u": 0})
    kinds = [op[0] for op in model.ops]
    assert kinds.count("sin") == 1 and kinds.count("cos") == 1 and kinds.count("atan2") == 1
    atan2 = next(op for op in model.ops if op[0] == "atan2")
    assert atan2[2:] == (("in", "x", 1), ("in", "x", 0))  # y, then x
    assert math.atan2(1.0, 2.0) in model.consts and math.cos(0.5) in model.consts


def test_non_integer_powers_are_refused():
    def f(x, u):
        return x ** 0.5
    _refused(f, "** 0.5")


def test_results_must_be_numbers():
    with pytest.raises(TraceError, match="must return numbers"):
        trace(lambda x, u: np.array(["a", x[0]], dtype=object), {"x": 1, "u": 0})


def test_numpy_is_restored_after_tracing():
    def f(x, u):
        return np.sqrt(x)
    trace(f, {"x": 2, "u": 0})
    assert np.sqrt is not None and f.__globals__["np"] is np
