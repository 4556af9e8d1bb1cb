"""The model compiler: an application's Python function traced once, at generation, into
engine operations.

Pure Python and numpy (no Amaranth). :func:`trace` calls the function with arrays of traced
scalars (:class:`T`) in place of its inputs; every operation on them records what it computes
instead of computing it, and constants (``dt``, the application's own numbers) fold as they
meet. The result, a :class:`Model`, is a short list of engine operations on symbolic words
(the inputs, the outputs, temporaries and constants) that :meth:`Model.instantiate` places on
a program's memory, once per sigma point.

What the tracing sees, and uses:

* a sum of terms is one :class:`~kfgen.hdl.linalg.program.Dot`: one FMA chain, the terms in
  the order the function adds them (a term with coefficient 1 and no product is the chain's
  addend). The golden model runs the same chain, so the order is part of the model;
* a multiplication by a constant 0 vanishes (the term is dropped: ``0 * x`` is taken as 0
  for every ``x``), by 1 is free, and products of constants fold into one coefficient
  (``0.5 * dt * x`` is one constant times ``x``), computed in float64 and rounded once to the
  core's format; a division by a constant is a multiplication by its reciprocal;
* equal subexpressions (the same operation on the same words) are computed once;
* words that depend on none of the per-point inputs (those that read only ``u`` and
  constants) are computed once for all points (:attr:`Model.shared`).

What traces: ``+ - * /``, unary ``-``, ``**`` by an integer constant from -8 to 8, indexing,
slicing and reshaping of numpy arrays, ``@``, and through ``np`` (the module the function's
globals name numpy): ``array``, ``asarray`` (a ``dtype`` of float is ignored), ``r_``,
``concatenate``, ``stack``, ``hstack``, ``vstack``, ``dot``, ``matmul``, ``cross``, ``sum``,
``eye``, ``zeros``, ``ones``, ``diag``, ``outer``, ``sqrt``, ``exp``, ``abs``/``absolute``,
``minimum``, ``maximum``, ``hypot``, ``square`` and ``float64``. ``abs(x)`` is ``max(x, -x)``,
``minimum(a, b)`` is ``-max(-a, -b)``, ``hypot(a, b)`` is ``sqrt(a*a + b*b)``.

What does not: a comparison, ``if``, ``bool``, ``float`` or ``int`` of a traced value
(control flow that depends on the data), ``math`` functions of traced values, and every
numpy name outside the list (``np.sin`` until the engine has a sine unit). Each is a
:class:`TraceError` naming the construct and the application's file and line.
"""

from __future__ import annotations

import math
import os
import sys
import types
from dataclasses import dataclass, field

import numpy as np

from ..linalg.program import OPS, Dot

__all__ = ["TraceError", "T", "Model", "trace", "record", "lower", "TRACED_NUMPY"]


class TraceError(ValueError):
    """A construct the model compiler cannot trace; the message is one line naming it and
    where it is (``file:line``)."""


_HERE = os.path.abspath(__file__)
_NUMPY = os.path.dirname(os.path.abspath(np.__file__))


def _where() -> str:
    """``file:line`` of the innermost frame outside this module and numpy: the user's."""
    frame = sys._getframe(1)
    while frame is not None:
        path = os.path.abspath(frame.f_code.co_filename)
        if path != _HERE and not path.startswith(_NUMPY):
            return f"{frame.f_code.co_filename}:{frame.f_lineno}"
        frame = frame.f_back
    return "?"


def _refuse(construct: str, why: str) -> TraceError:
    return TraceError(f"{construct} does not trace ({_where()}): {why}")


_CONTROL = "control flow or a conversion that depends on a traced value cannot become hardware"


def _key_order(k):
    return repr(k)


#: While :func:`record` runs: operation word -> ``file:line`` where the function first
#: computed it (what a later pass, such as differentiation, names when it refuses the word).
_sites: dict | None = None


def _const(value) -> bool:
    return not isinstance(value, T)


class T:
    """A traced scalar: ``c0 + sum(coef * w1 [* w2])`` over words.

    A word is a hashable key: ``("in", name, k)`` (the function's inputs), ``("const", v)``,
    or an operation on words (``("div", a, b)``, ``("sqrt", a)``, ``("exp", a)``, ``("sin", a)``,
    ``("cos", a)``, ``("atan2", y, x)``,
    ``("max", a, b)``, ``("lin", terms, c0)`` for a sum computed into a word of its own).
    Equal keys are the same value, computed once."""

    __slots__ = ("terms", "c0")

    def __init__(self, terms=(), c0=0.0):
        self.terms = tuple(terms)
        self.c0 = float(c0)

    @classmethod
    def word(cls, key) -> T:
        if _sites is not None and key[0] != "in":
            _sites.setdefault(key, _where())
        return cls(((1.0, key, None),))

    @classmethod
    def lift(cls, value) -> T:
        if isinstance(value, T):
            return value
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
            raise _refuse(f"a {type(value).__name__} operand", "only numbers and traced values combine")
        return cls((), float(value))

    @property
    def is_const(self) -> bool:
        return not self.terms

    def key(self):
        """The word holding this value (``("const", v)`` for a constant)."""
        if not self.terms:
            return ("const", self.c0)
        if self.c0 == 0 and len(self.terms) == 1:
            c, w1, w2 = self.terms[0]
            if c == 1.0 and w2 is None:
                return w1
        return ("lin", self.terms, self.c0)

    def _monomial(self):
        if self.c0 == 0 and len(self.terms) == 1 and self.terms[0][2] is None:
            return self.terms[0][0], self.terms[0][1]
        return None

    def scale(self, c: float) -> T:
        if c == 0:
            return T()
        return T(((coef * c, w1, w2) for coef, w1, w2 in self.terms), self.c0 * c)

    # ---- arithmetic ------------------------------------------------------------------------
    def __add__(self, other):
        if isinstance(other, np.ndarray):
            return NotImplemented
        other = T.lift(other)
        merged: dict = {}
        for coef, w1, w2 in self.terms + other.terms:
            merged[w1, w2] = merged.get((w1, w2), 0.0) + coef
        return T(((c, w1, w2) for (w1, w2), c in merged.items() if c != 0), self.c0 + other.c0)

    def __radd__(self, other):
        if isinstance(other, np.ndarray):
            return NotImplemented
        return T.lift(other) + self

    def __neg__(self):
        return self.scale(-1.0)

    def __pos__(self):
        return self

    def __sub__(self, other):
        if isinstance(other, np.ndarray):
            return NotImplemented
        return self + -T.lift(other)

    def __rsub__(self, other):
        if isinstance(other, np.ndarray):
            return NotImplemented
        return T.lift(other) + -self

    def __mul__(self, other):
        if isinstance(other, np.ndarray):
            return NotImplemented
        other = T.lift(other)
        if other.is_const:
            return self.scale(other.c0)
        if self.is_const:
            return other.scale(self.c0)
        ma, mb = self._monomial(), other._monomial()
        ca, wa = ma if ma else (1.0, self.key())
        cb, wb = mb if mb else (1.0, other.key())
        w1, w2 = sorted((wa, wb), key=_key_order)
        return T(((ca * cb, w1, w2),))

    def __rmul__(self, other):
        if isinstance(other, np.ndarray):
            return NotImplemented
        return self * other

    def __truediv__(self, other):
        if isinstance(other, np.ndarray):
            return NotImplemented
        other = T.lift(other)
        if other.is_const:
            if other.c0 == 0:
                raise _refuse("a division by the constant 0", "it is not a number")
            return self.scale(1.0 / other.c0)
        return T.word(("div", self.key(), other.key()))

    def __rtruediv__(self, other):
        if isinstance(other, np.ndarray):
            return NotImplemented
        return T.lift(other) / self

    def __pow__(self, k):
        if isinstance(k, T) or isinstance(k, bool) or not float(k).is_integer() or not -8 <= k <= 8:
            raise _refuse(f"** {k!r}", "the exponent must be an integer constant from -8 to 8")
        k = int(k)
        if k < 0:
            return 1.0 / self ** -k
        out, base = T((), 1.0), self
        while k:  # binary powers: x**4 is (x*x)*(x*x), the square computed once
            if k & 1:
                out = out * base
            k >>= 1
            if k:
                base = base * base
        return out

    def __rpow__(self, other):
        raise _refuse("a constant ** a traced value", "the exponent must be an integer constant")

    def __matmul__(self, other):
        raise _refuse("@ on a scalar", "use it on arrays")

    __rmatmul__ = __matmul__

    # ---- what does not trace ---------------------------------------------------------------
    def _control(self, *_):
        raise _refuse("a comparison, `if` or conversion of a traced value", _CONTROL)

    __bool__ = __float__ = __int__ = __index__ = __complex__ = _control
    __lt__ = __le__ = __gt__ = __ge__ = __eq__ = __ne__ = _control
    __hash__ = object.__hash__

    def __floordiv__(self, other):
        raise _refuse("//", "only true division traces")

    __rfloordiv__ = __mod__ = __rmod__ = __floordiv__

    def __repr__(self):
        return f"T({self.key()!r})"

    # numpy calls these on object arrays (np.sqrt(a) with a an array of T, through real numpy)
    def sqrt(self):
        return _sqrt(self)

    def exp(self):
        return _exp(self)

    def sin(self):
        return _sin(self)

    def cos(self):
        return _cos(self)

    def arctan2(self, other):
        return _atan2(self, other)

    def __abs__(self):
        return _abs(self)

    def hypot(self, other):
        return _hypot(self, other)

    def square(self):
        return self * self


def _unary(name, fold, build):
    def fn(a):
        if _const(a):
            return fold(float(a))
        return build(a)
    fn.__name__ = name
    return fn


def _sqrt_build(a):
    return T.word(("sqrt", a.key()))


def _exp_build(a):
    return T.word(("exp", a.key()))


_sqrt = _unary("sqrt", math.sqrt, _sqrt_build)
_exp = _unary("exp", math.exp, _exp_build)
_sin = _unary("sin", math.sin, lambda a: T.word(("sin", a.key())))
_cos = _unary("cos", math.cos, lambda a: T.word(("cos", a.key())))


def _atan2(y, x):
    if _const(y) and _const(x):
        return math.atan2(float(y), float(x))
    y, x = T.lift(y), T.lift(x)
    return T.word(("atan2", y.key(), x.key()))


def _max(a, b):
    if _const(a) and _const(b):
        return max(float(a), float(b))
    a, b = T.lift(a), T.lift(b)
    return T.word(("max", a.key(), b.key()))


def _min(a, b):
    if _const(a) and _const(b):
        return min(float(a), float(b))
    return -_max(-T.lift(a), -T.lift(b))


def _abs(a):
    if _const(a):
        return abs(float(a))
    return _max(a, -a)


def _hypot(a, b):
    if _const(a) and _const(b):
        return math.hypot(float(a), float(b))
    a, b = T.lift(a), T.lift(b)
    return _sqrt(a * a + b * b)


def _has_traced(obj) -> bool:
    if isinstance(obj, T):
        return True
    if isinstance(obj, np.ndarray):
        return obj.dtype == object and any(isinstance(v, T) for v in obj.flat)
    if isinstance(obj, (list, tuple)):
        return any(_has_traced(v) for v in obj)
    return False


def _elementwise(name, fn, nargs):
    ufunc = np.frompyfunc(fn, nargs, 1)
    real = getattr(np, name)

    def call(*args, **kwargs):
        if len(args) != nargs or kwargs:
            raise _refuse(f"np.{name} with {'keyword arguments' if kwargs else f'{len(args)} arguments'}",
                          f"np.{name} traces with {nargs} positional argument(s)")
        if not any(_has_traced(a) for a in args):
            return real(*args)
        out = ufunc(*(np.asarray(a, dtype=object) if isinstance(a, (list, tuple)) else a for a in args))
        return out
    call.__name__ = name
    return call


def _array(obj, dtype=None, *args, **kwargs):
    if not _has_traced(obj):
        return np.array(obj, dtype=dtype, *args, **kwargs)
    if dtype is not None and dtype not in (float, np.float64, object, "float64", "f8"):
        raise _refuse(f"np.array(..., dtype={dtype!r})", "traced values are floats; use dtype float or none")
    return np.array(obj, dtype=object, *args, **kwargs)


def _asarray(obj, dtype=None, *args, **kwargs):
    if isinstance(obj, np.ndarray) and obj.dtype == object and _has_traced(obj):
        _array(obj, dtype)  # the same dtype check
        return obj
    return _array(obj, dtype, *args, **kwargs) if _has_traced(obj) else np.asarray(obj, dtype, *args, **kwargs)


#: numpy names that trace, as themselves (they move, build or combine arrays, and object
#: arrays of traced values pass through them).
_PASS = ("r_", "c_", "concatenate", "stack", "hstack", "vstack", "dot", "matmul", "cross", "sum", "eye",
         "zeros", "ones", "diag", "outer", "float64", "pi", "e", "newaxis", "ndarray", "transpose", "reshape",
         "zeros_like", "ones_like", "full", "trace", "inner")

_CALLS = {
    "array": _array,
    "asarray": _asarray,
    "sqrt": _elementwise("sqrt", _sqrt, 1),
    "exp": _elementwise("exp", _exp, 1),
    "abs": _elementwise("abs", _abs, 1),
    "absolute": _elementwise("absolute", _abs, 1),
    "square": _elementwise("square", lambda a: a * a, 1),
    "minimum": _elementwise("minimum", _min, 2),
    "maximum": _elementwise("maximum", _max, 2),
    "hypot": _elementwise("hypot", _hypot, 2),
    "sin": _elementwise("sin", _sin, 1),
    "cos": _elementwise("cos", _cos, 1),
    "arctan2": _elementwise("arctan2", _atan2, 2),
}

_NO_UNIT = ("tan", "arctan", "arcsin", "arccos", "log", "log2", "log10", "tanh",
            "sinh", "cosh", "power", "fmod", "floor", "ceil", "round", "sign")


class _TracedNumpy(types.ModuleType):
    """What ``np`` is inside a traced function: the names that trace, and a
    :class:`TraceError` for every other."""

    def __getattr__(self, name):
        if name in _CALLS:
            return _CALLS[name]
        if name in _PASS:
            return getattr(np, name)
        if name in _NO_UNIT:
            raise _refuse(f"np.{name}", "the engine has no unit for it yet (see the application page)")
        raise _refuse(f"np.{name}", "it is not among the numpy names that trace (see the application page)")


#: The traced stand-in for numpy.
TRACED_NUMPY = _TracedNumpy("numpy (traced)")


# ---- lowering --------------------------------------------------------------------------------

@dataclass
class Model:
    """A traced function as engine operations on symbolic words.

    ``ops`` are tuples in program order: ``("dot", dst, init, ((a, b, neg), ...))``,
    ``("div", dst, a, b)``, ``("sqrt", dst, a)``, ``("exp", dst, a)``, ``("max", dst, a, b)``,
    ``("sin", dst, a)``, ``("cos", dst, a)``, ``("atan2", dst, y, x)``,
    ``("copy", dst, src)``. A word is ``("in", name, k)``, ``("out", k)``, ``("tmp", k)`` or
    ``("const", value)``; temporaries in :attr:`shared` read no per-point input (they are
    computed once, for every point)."""

    outputs: int
    ops: list = field(default_factory=list)
    temps: int = 0
    shared: set = field(default_factory=set)  # tmp indices computed once for all points

    @property
    def consts(self) -> list[float]:
        """The constants the operations read, in first-use order."""
        seen = {}
        for op in self.ops:
            for w in _reads(op):
                if w[0] == "const":
                    seen.setdefault(w[1], None)
        return list(seen)

    @property
    def fma_count(self) -> int:
        return sum(len(op[3]) for op in self.ops if op[0] == "dot")

    def op_is_shared(self, op) -> bool:
        return op[1][0] == "tmp" and op[1][1] in self.shared

    def program_ops(self, addr, *, shared_done: bool) -> list:
        """The operations as the engine's IR (:mod:`kfgen.hdl.linalg.program`), every word
        mapped by ``addr(word)`` to an address; the shared ones only when not ``shared_done``."""
        out = []
        for op in self.ops:
            if self.op_is_shared(op) and shared_done:
                continue
            kind, dst = op[0], addr(op[1])
            if kind == "dot":
                init = None if op[2] is None else addr(op[2])
                out.append(Dot(dst, init, [(addr(a), addr(b), neg) for a, b, neg in op[3]]))
            else:
                out.append(OPS[kind](dst, *(addr(w) for w in op[2:])))
        return out


def _reads(op):
    if op[0] == "dot":
        return ([] if op[2] is None else [op[2]]) + [w for a, b, _ in op[3] for w in (a, b)]
    return list(op[2:])


class _Lowering:
    def __init__(self, varying: frozenset):
        self.varying_inputs = varying
        self.ops: list = []
        self.addr: dict = {}  # word key -> its symbolic address
        self.temps = 0
        self.vary: dict = {}  # symbolic address -> depends on a per-point input
        self.shared: set = set()

    def _varies(self, w) -> bool:
        if w[0] == "in":
            return w[1] in self.varying_inputs
        if w[0] == "const":
            return False
        return self.vary[w]

    def _emit(self, op):
        dst = op[1]
        v = any(self._varies(w) for w in _reads(op))
        self.vary[dst] = v
        if dst[0] == "tmp" and not v:
            self.shared.add(dst[1])
        self.ops.append(op)

    def _tmp(self):
        self.temps += 1
        return ("tmp", self.temps - 1)

    def ensure(self, key, dst=None):
        """The symbolic address holding word ``key``, its operations emitted (into ``dst``
        when it is new and ``dst`` is given)."""
        if key[0] in ("in", "const"):
            return key
        if key in self.addr:
            return self.addr[key]
        kind = key[0]
        if kind == "lin":
            op = self._dot(key[1], key[2])
        else:
            op = (kind, *(self.ensure(w) for w in key[1:]))
        where = dst or self._tmp()
        self._emit((op[0], where, *op[1:]))
        self.addr[key] = where
        return where

    def _dot(self, terms, c0):
        init, rest = None, list(terms)
        for i, (c, w1, w2) in enumerate(rest):
            if c == 1.0 and w2 is None:
                init = self.ensure(w1)
                del rest[i]
                break
        if c0 != 0:
            if init is None:
                init = ("const", c0)
            else:
                rest.append((c0, ("const", 1.0), None))
        out = []
        for c, w1, w2 in rest:
            if w2 is None:
                a, b = ("const", 1.0 if abs(c) == 1 else abs(c)), self.ensure(w1)
            elif abs(c) == 1:
                a, b = self.ensure(w1), self.ensure(w2)
            else:
                a, b = self.ensure(T(((abs(c), w1, None),)).key()), self.ensure(w2)
            out.append((a, b, c < 0))
        return ("dot", init, tuple(out))


#: Word kinds an operation computes (an output of one of them is written in place, no copy).
_COMPUTED = ("lin",) + tuple(k for k in OPS if k != "copy")


def trace(fn, inputs: dict, *, varying=None, name: str = "f", scope=None) -> Model:
    """Trace ``fn`` (called with one traced array per entry of ``inputs``, name -> length, in
    order) into a :class:`Model`; ``varying`` names the inputs that differ from point to point
    (all by default). Inside ``fn``, and inside ``scope`` (a function whose module's globals
    to patch, ``fn`` by default), a global name bound to numpy is :data:`TRACED_NUMPY`.

    Raises
    ------
    TraceError
        For a construct that does not trace, or a result that is not a flat array of numbers.
    """
    outs, _ = record(fn, inputs, name=name, scope=scope)
    return lower(outs, varying=frozenset(inputs if varying is None else varying))[0]


def record(fn, inputs: dict, *, name: str = "f", scope=None) -> tuple[list[T], dict]:
    """``fn``'s results as traced values (:func:`trace`'s first half: its arguments and
    errors), and where each operation word was first computed (word -> ``file:line``)."""
    global _sites
    args = [np.array([T.word(("in", key, k)) for k in range(length)], dtype=object)
            for key, length in inputs.items()]
    func = getattr(scope or fn, "__func__", scope or fn)
    scope = getattr(func, "__globals__", {})
    patched = {k: v for k, v in scope.items() if v is np}
    sites = _sites = {}
    try:
        scope.update({k: TRACED_NUMPY for k in patched})
        try:
            result = fn(*args)
        except TraceError:
            raise
        except Exception as exc:  # the user's code, on traced values: one line
            tb = exc.__traceback__
            where = "?"
            while tb is not None:
                path = os.path.abspath(tb.tb_frame.f_code.co_filename)
                if path != _HERE and not path.startswith(_NUMPY):
                    where = f"{tb.tb_frame.f_code.co_filename}:{tb.tb_lineno}"
                tb = tb.tb_next
            text = " ".join(str(exc).split())
            raise TraceError(f"{name} does not trace ({where}): {type(exc).__name__}: {text}") from None
    finally:
        scope.update(patched)
        _sites = None
    try:
        flat = np.asarray(result, dtype=object).reshape(-1)
    except Exception:
        raise TraceError(f"{name} must return an array of numbers, not {type(result).__name__}") from None
    outs = []
    for v in flat:
        if isinstance(v, (bool, np.bool_)) or not isinstance(v, (T, int, float, np.integer, np.floating)):
            raise TraceError(f"{name} must return numbers, not {type(v).__name__}")
        outs.append(T.lift(v))
    return outs, sites


def lower(outs, words=(), *, varying=frozenset()) -> tuple[Model, list]:
    """Traced values as a :class:`Model` (:func:`trace`'s second half): ``outs`` written to
    the outputs ``("out", k)``; ``words`` computed too, each into a word of its own or one
    that already holds it (returned: an input, a constant, an output or a temporary), all
    their common terms shared. ``varying`` names the per-point inputs (:attr:`Model.shared`)."""
    low = _Lowering(frozenset(varying))
    for k, t in enumerate(outs):
        key = t.key()
        if key[0] in _COMPUTED and key not in low.addr:
            low.ensure(key, dst=("out", k))
        else:
            low._emit(("copy", ("out", k), low.ensure(key)))
    at = [low.ensure(T.lift(t).key()) for t in words]
    return Model(len(outs), low.ops, low.temps, low.shared), at
