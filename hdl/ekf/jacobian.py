"""Jacobians of a traced function by forward-mode differentiation, at generation.

Pure Python (no Amaranth). The function is recorded by the tracer
(:func:`kfgen.hdl.engine.trace.record`: its results as traced values, each a sum of terms over
operation words) and differentiated word by word, forward: every word's value at the
linearisation point and its derivative with respect to each input differentiated against are
built from the tracer's own traced values (:class:`~kfgen.hdl.engine.trace.T`), so that

* the inputs set to 0 at the point (the noise: f's ``w``, h's ``v``) become the constant 0 and
  fold away, in the values and in the derivatives;
* constants fold (``d(dt * x)/dx`` is the constant dt, no operation), and a derivative that
  is identically zero is the constant 0: a structural zero of the Jacobian, no word, no
  operation, and a sparse tangent (each word carries only its nonzero derivatives);
* equal subexpressions are one word (the tracer's lowering shares them): the derivative of
  ``sin a`` is the function's own ``cos a`` when it computes one, ``hypot`` and ``atan2`` of
  the same point share ``x*x + y*y``.

The rules, for a word ``q`` (``d`` a derivative, ``r = 1 / b`` one division per word):

* a sum ``c0 + sum c_k a_k [b_k]``: ``sum c_k (d a_k b_k + a_k d b_k)``;
* ``q = a / b``: ``d a r - d b (q r)``; ``q = sqrt(a)``: ``(d a / 2) (1 / q)``;
* ``exp``: ``d a q``; ``sin``: ``d a cos a``; ``cos``: ``-d a sin a``;
* ``atan2(y, x)``: ``(d y x - d x y) / (x*x + y*y)``;
* ``max`` (``np.maximum``, ``np.minimum``, ``abs``) has no derivative where its arguments are
  equal and is refused (:class:`~kfgen.hdl.engine.trace.TraceError`, one line naming it and
  the application's file and line), as is a derivative that does not exist at the point
  (``sqrt`` of a constant 0, ``atan2`` at the constant origin).

Integer powers, ``hypot`` and ``square`` arrive as the sums, products, divisions and square
roots the tracer makes of them, and differentiate as those.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..engine.trace import Model, T, TraceError, lower, record

__all__ = ["Jacobian", "Linearised", "linearise"]


@dataclass(frozen=True)
class Jacobian:
    """One Jacobian of a :class:`Linearised` function: ``rows x cols``, its nonzero entries.

    ``entries`` maps ``(i, j)`` to the word holding the entry: ``("const", v)`` for a
    constant (a 1 among them), else a word of the model (``("out", k)``, ``("tmp", t)`` or an
    input ``("in", name, k)``); an entry not in it is a structural zero. ``dense`` is the
    multiply-adds of forward mode without structure (every operation's rule for every input:
    what differentiating costs before zero-dropping), ``sparse`` those its entries add to the
    function's own."""

    name: str
    rows: int
    cols: int
    entries: dict
    dense: int
    sparse: int

    def word(self, i: int, j: int):
        """The word of entry ``(i, j)``, or ``None`` for a structural zero."""
        return self.entries.get((i, j))

    @property
    def pattern(self) -> np.ndarray:
        """The nonzero pattern, ``rows x cols`` booleans."""
        out = np.zeros((self.rows, self.cols), dtype=bool)
        for i, j in self.entries:
            out[i, j] = True
        return out

    @property
    def constants(self) -> int:
        """Entries known at generation (no word computed for them)."""
        return sum(1 for w in self.entries.values() if w[0] == "const")


@dataclass(frozen=True)
class Linearised:
    """A function's value and Jacobians at a point, as one traced model: its outputs are the
    function's values; the Jacobians' entries are words of it (:class:`Jacobian`), every
    common term computed once."""

    name: str
    model: Model
    jacobians: dict  # input name -> Jacobian

    @property
    def fma_count(self) -> int:
        return self.model.fma_count


def _zero(t: T) -> bool:
    return t.is_const and t.c0 == 0


class _Forward:
    """Values at the point and sparse tangents of the tracer's words, memoised by word."""

    def __init__(self, wrt, zero, sites: dict, name: str):
        self.wrt, self.zero, self.sites, self.name = frozenset(wrt), frozenset(zero), sites, name
        self._values: dict = {}
        self._tangents: dict = {}

    def _refuse(self, key, why: str) -> TraceError:
        what = {"max": "max (np.maximum, np.minimum or abs) of traced values"}.get(key[0], key[0])
        return TraceError(f"{self.name} does not differentiate ({self.sites.get(key, '?')}): {what} {why}")

    def _unit(self, kind, args, key):
        """``kind`` of the values ``args``, folded when they are constants (a division as the
        tracer divides: by a constant, a multiplication by its reciprocal)."""
        if kind == "div":
            return args[0] / args[1]
        if not all(a.is_const for a in args):
            return T.word((kind, *(a.key() for a in args)))
        vals = [a.c0 for a in args]
        if kind == "sqrt" and vals[0] < 0:
            raise self._refuse(key, "of a negative constant at the linearisation point")
        fold = {"sqrt": math.sqrt, "exp": math.exp, "sin": math.sin, "cos": math.cos, "atan2": math.atan2, "max": max}
        return T((), fold[kind](*vals))

    def value(self, key) -> T:
        """The word's value at the point, rebuilt (the zeroed inputs folded)."""
        if key in self._values:
            return self._values[key]
        kind = key[0]
        if kind == "in":
            v = T() if key[1] in self.zero else T.word(key)
        elif kind == "const":
            v = T((), key[1])
        elif kind == "lin":
            v = T((), key[2])
            for c, w1, w2 in key[1]:
                v = v + (self.value(w1) if w2 is None else self.value(w1) * self.value(w2)).scale(c)
        else:
            args = [self.value(w) for w in key[1:]]
            if kind == "div" and _zero(args[1]):
                raise self._refuse(key, "divides by 0 at the linearisation point")
            v = self._unit(kind, args, key)
        self._values[key] = v
        return v

    def _reciprocal(self, v: T, key) -> T:
        if _zero(v):
            raise self._refuse(key, "has no derivative at the linearisation point (a division by 0)")
        return T((), 1.0) / v

    def tangent(self, key) -> dict:
        """The word's nonzero derivatives at the point: input word -> value."""
        if key in self._tangents:
            return self._tangents[key]
        kind, acc = key[0], {}

        def axpy(c, tan, factor=None):
            for j, d in tan.items():
                acc[j] = acc.get(j, T()) + (d if factor is None else d * factor).scale(c)

        if kind == "in":
            if key[1] in self.wrt:
                acc[key] = T((), 1.0)
        elif kind == "lin":
            for c, w1, w2 in key[1]:
                if w2 is None:
                    axpy(c, self.tangent(w1))
                else:
                    axpy(c, self.tangent(w1), self.value(w2))
                    axpy(c, self.tangent(w2), self.value(w1))
        elif kind == "div":
            ta, tb = self.tangent(key[1]), self.tangent(key[2])
            if ta or tb:
                r = self._reciprocal(self.value(key[2]), key)
                axpy(1.0, ta, r)
                axpy(-1.0, tb, self.value(key) * r)
        elif kind == "sqrt":
            ta = self.tangent(key[1])
            if ta:
                axpy(0.5, ta, self._reciprocal(self.value(key), key))
        elif kind == "exp":
            axpy(1.0, self.tangent(key[1]), self.value(key))
        elif kind in ("sin", "cos"):
            ta = self.tangent(key[1])
            if ta:
                other = "cos" if kind == "sin" else "sin"
                axpy(1.0 if kind == "sin" else -1.0, ta, self._unit(other, [self.value(key[1])], key))
        elif kind == "atan2":
            ty, tx = self.tangent(key[1]), self.tangent(key[2])
            if ty or tx:
                y, x = self.value(key[1]), self.value(key[2])
                r = self._reciprocal(x * x + y * y, key)
                axpy(1.0, ty, x * r)
                axpy(-1.0, tx, y * r)
        elif kind == "max":
            if self.tangent(key[1]) or self.tangent(key[2]):
                raise self._refuse(key, "has no derivative where its arguments are equal")
        elif kind != "const":
            raise self._refuse(key, "has no differentiation rule")
        out = {j: d for j, d in acc.items() if not _zero(d)}
        self._tangents[key] = out
        return out


#: Multiply-adds of one operation's forward-mode rule per input, and once per operation.
_DENSE = {"div": (2, 1), "sqrt": (1, 0), "exp": (1, 0), "sin": (1, 0), "cos": (1, 0), "atan2": (2, 2)}


def _dense_cost(outs, inputs: int) -> int:
    """Multiply-adds of forward mode with dense tangents of ``inputs`` entries over the words
    ``outs`` read (each product term two per input, every other term one; :data:`_DENSE`)."""
    seen, total, stack = set(), 0, [t.key() for t in outs]
    while stack:
        key = stack.pop()
        if key in seen or key[0] in ("in", "const"):
            continue
        seen.add(key)
        if key[0] == "lin":
            total += inputs * sum(1 if w2 is None else 2 for _, _, w2 in key[1])
            stack += [w for _, w1, w2 in key[1] for w in (w1, w2) if w is not None]
        else:
            per, once = _DENSE.get(key[0], (1, 0))
            total += per * inputs + once
            stack += list(key[1:])
    return total


def linearise(fn, inputs: dict, wrt: dict, zero=(), *, name: str, scope=None) -> Linearised:
    """``fn`` (traced with one array per entry of ``inputs``, name -> length) at the point
    where the inputs named in ``zero`` are 0, with its Jacobian with respect to each input
    ``wrt`` names (input name -> the Jacobian's name, e.g. ``{"x": "F", "w": "L"}``).

    Raises
    ------
    TraceError
        One line: a construct that does not trace, or a word that does not differentiate
        (its operation, and the file and line where the function computes it).
    """
    outs, sites = record(fn, inputs, name=name, scope=scope)
    fwd = _Forward(wrt, zero, sites, name)
    values = [fwd.value(t.key()) for t in outs]
    tangents = [fwd.tangent(t.key()) for t in outs]
    found = {}
    for inp in wrt:
        found[inp] = [(i, j, tan[("in", inp, j)]) for i, tan in enumerate(tangents)
                      for j in range(inputs[inp]) if ("in", inp, j) in tan]
    words = [t for inp in wrt for _, _, t in found[inp]]
    model, at = lower(values, words)
    base = lower(values)[0].fma_count
    jacobians, k = {}, 0
    for inp, jname in wrt.items():
        entries = {(i, j): at[k + e] for e, (i, j, _) in enumerate(found[inp])}
        k += len(entries)
        alone = lower(values, [t for _, _, t in found[inp]])[0].fma_count
        jacobians[inp] = Jacobian(jname, len(outs), inputs[inp], entries, _dense_cost(outs, inputs[inp]),
                                  alone - base)
    return Linearised(name, model, jacobians)
