"""The golden executor (:func:`kfgen.sim.linalg.exec.run`) across many memories at once, for
Monte Carlo runs: one numpy operation per program operation, over every seed's memory.

The memories are float64 arrays of shape (seeds, words) holding values of the program's
format (every format of at most 25 significand bits: binary32, binary16, bfloat16 and the
smaller ones). Each operation is rounded exactly as the hardware rounds it:

* a product of two such values is exact in float64 (at most 2 x 25 bits), and a sum
  ``p + c`` is made exact by TwoSum and rounded to odd in float64 (53 bits); rounding that
  to the format (p <= 25, 53 >= 2p + 2) is then the FMA's single rounding to nearest even;
* a quotient and a square root rounded to float64 and then to the format are correctly
  rounded for the same reason (double rounding is innocuous when 53 >= 2p + 2);
* ``copy``, ``copysign`` and ``max`` are exact; an arithmetic NaN is the canonical one (a
  positive NaN), and only ``copy`` and ``copysign`` give a NaN a sign.

Every other unit (exp, sin, cos, atan2) runs word by word through
:data:`~kfgen.sim.linalg.exec.GOLDEN`, slower but the same bits. IEEE flags are not kept:
the statuses are the hardware's ``err_pivot`` and ``err_nan``, per memory. A test holds this
executor equal, word for word, to :func:`~kfgen.sim.linalg.exec.run`.
"""

from __future__ import annotations

import numpy as np

from kfgen.hdl.linalg.isa import Check
from kfgen.hdl.linalg.program import Dot, Program

from .exec import GOLDEN, from_words, to_words

__all__ = ["BatchStatus", "round_to", "run_batch"]


class BatchStatus:
    """Per memory: ``pivot`` and ``nan`` (bool arrays), as :class:`~.exec.Status` says."""

    def __init__(self, seeds: int):
        self.pivot = np.zeros(seeds, dtype=bool)
        self.nan = np.zeros(seeds, dtype=bool)


def _limits(fmt):
    p = fmt.frac_bits + 1
    if p > 25:
        raise ValueError(f"the batch executor rounds formats of at most 25 significand bits, not {p} ({fmt})")
    bias = (1 << (fmt.exp_bits - 1)) - 1
    return p, 1 - bias, bias  # p, emin, emax


def round_to(fmt, x: np.ndarray) -> np.ndarray:
    """``x`` (float64, at most 53 significant bits, rounded to odd where it was inexact)
    rounded to nearest even in ``fmt``, subnormals and overflow to infinity included."""
    p, emin, emax = _limits(fmt)
    with np.errstate(invalid="ignore", over="ignore"):
        _, e = np.frexp(x)  # |x| = m 2^e, 1/2 <= m < 1: the leading bit's weight is 2^(e - 1)
        q = np.maximum(e - p, emin - p + 1)  # the weight of the format's last bit
        r = np.ldexp(np.rint(np.ldexp(x, -q)), q)
        top = np.ldexp(2.0 - 2.0 ** (1 - p), emax)
        return np.where(np.isfinite(x) & (np.abs(r) > top), np.copysign(np.inf, x), r)


def _odd(s: np.ndarray, err: np.ndarray) -> np.ndarray:
    """``s + err`` (exact, |err| below s's last bit) rounded to odd in float64."""
    inexact = err != 0
    bits = s.view(np.int64).copy()
    toward_zero = inexact & ((err < 0) != (s < 0))  # s was rounded away from zero: step back
    bits = np.where(toward_zero, bits - 1, bits)
    bits = np.where(inexact, bits | 1, bits)
    return bits.view(np.float64)


def _fma(fmt, a, b, c):
    with np.errstate(invalid="ignore", over="ignore"):
        p = a * b
        s = p + c
        bb = s - p
        err = (p - (s - bb)) + (c - bb)
    err = np.where(np.isfinite(s), err, 0.0)
    return round_to(fmt, _odd(s, err))


def _word_unit(fmt, unit, *cols):
    """A unit without a vector form: word by word through the golden operation."""
    out = []
    for vals in zip(*cols):
        words = [to_words(fmt, [v])[0] for v in vals]
        out.append(from_words(fmt, [GOLDEN[unit](fmt, *words, subnormals="ieee")[0]])[0])
    return np.array(out)


def _max(a, b):
    nan = np.isnan(a) | np.isnan(b)
    b_wins = (b > a) | ((a == 0) & (b == 0) & np.signbit(a) & ~np.signbit(b))
    return np.where(nan, np.nan, np.where(b_wins, b, a))


def run_batch(prog: Program, mem: np.ndarray, st: BatchStatus | None = None) -> BatchStatus:
    """Execute ``prog`` on every row of ``mem`` ((seeds, words) float64, changed in place);
    the statuses, OR-ed into ``st`` when given."""
    fmt = prog.fmt
    _limits(fmt)
    st = st or BatchStatus(mem.shape[0])
    for op in prog.ops:
        if isinstance(op, Dot):
            acc = np.full(mem.shape[0], -0.0) if op.init is None else mem[:, op.init]
            for a, b, neg in op.terms:
                acc = _fma(fmt, -mem[:, a] if neg else mem[:, a], mem[:, b], acc)
        else:
            vals = [mem[:, r] for r in op.reads]
            unit = op.unit
            if unit == "copy":
                acc = vals[0].copy()
            elif unit == "copysign":
                acc = np.copysign(vals[0], vals[1])
            elif unit == "max":
                acc = _max(*vals)
            elif unit == "div":
                with np.errstate(divide="ignore", invalid="ignore"):
                    acc = round_to(fmt, vals[0] / vals[1])
            elif unit == "sqrt":
                with np.errstate(invalid="ignore"):
                    acc = round_to(fmt, np.sqrt(vals[0]))
            else:
                acc = _word_unit(fmt, unit, *vals)
        if op.unit not in ("copy", "copysign"):
            acc = np.where(np.isnan(acc), np.nan, acc)  # the canonical NaN: positive
        if op.check == Check.PIVOT:
            st.pivot |= np.isnan(acc) | (acc < 0) | ((acc == 0))  # -0 and +0 alike
        elif op.check == Check.FINITE:
            st.nan |= ~np.isfinite(acc)
        for d in op.dst:
            mem[:, d] = acc
    return st
