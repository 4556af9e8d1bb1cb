"""Bit-exact golden model of the linear-algebra engine: runs a step program on memory words.

Every multiply-add, division and square root is rounded once by the exact reference
:func:`kfgen.sim.float_ref.ref_op`, every exponential as the unit computes it
(:func:`kfgen.sim.fpu.exp_model.exp_model`, itself checked against an exact exp), in the
program's order; since the order of every
accumulation is part of the program, this is what the hardware computes, word for word,
whatever the schedule.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction

from kfgen.hdl.linalg.isa import Check
from kfgen.hdl.linalg.program import Dot, Program
from kfgen.sim.float_ref import decode, ref_op, round_to_format
from kfgen.sim.fpu.exp_model import exp_model
from kfgen.sim.fpu.trig_model import trig_word

__all__ = ["Status", "run", "GOLDEN", "max_value", "to_words", "from_words"]


@dataclass
class Status:
    """What the hardware raises: ``pivot`` (a checked pivot <= 0 or NaN), ``nan`` (a NaN or
    infinity in a checked result), and the OR of the units' IEEE flags (NX UF OF DZ NV)."""

    pivot: bool = False
    nan: bool = False
    flags: int = 0


def run(prog: Program, mem: list[int], subnormals: str = "ieee") -> Status:
    """Execute ``prog`` on ``mem`` (a list of words, changed in place); return the status.

    The whole program runs even after a fault, as the engine does (it latches the error
    bit and finishes the step: the same cycles, the same memory)."""
    fmt = prog.fmt
    sign = 1 << (fmt.width - 1)
    exp_all = fmt.exp_max_field << fmt.frac_bits
    st = Status()
    for op in prog.ops:
        if isinstance(op, Dot):
            acc = sign if op.init is None else mem[op.init]  # -0: the neutral addend
            for a, b, neg in op.terms:
                acc, fl = ref_op("fma", fmt, mem[a] ^ (sign if neg else 0), mem[b], acc, subnormals)
                st.flags |= fl
        elif op.unit in GOLDEN:
            acc, fl = GOLDEN[op.unit](fmt, *(mem[a] for a in op.reads), subnormals=subnormals)
            st.flags |= fl
        else:
            raise TypeError(f"unknown operation {op!r}")
        special = acc & exp_all == exp_all  # NaN or infinity
        if op.check == Check.PIVOT and (special and acc & fmt.frac_mask or acc & sign or not acc & ~sign):
            st.pivot = True  # NaN, negative (or -0), +0
        elif op.check == Check.FINITE and special:
            st.nan = True
        for d in op.dst:
            mem[d] = acc
    return st


def _exp(fmt, a, subnormals):
    y, fl = exp_model(fmt, [a], subnormals)
    return int(y[0]), int(fl[0])


def _max(fmt, a, b, subnormals):
    y, nan = max_value(fmt, a, b)
    return y, 0b10000 if nan else 0  # NV, as a comparison


#: The golden operation of every engine unit but the FMA (:data:`kfgen.hdl.linalg.isa.UNITS`):
#: ``(fmt, *operand words, subnormals=...) -> (word, IEEE flags)``, rounded as the unit rounds.
GOLDEN = {
    "div": lambda fmt, a, b, subnormals: ref_op("div", fmt, a, b, None, subnormals),
    "sqrt": lambda fmt, a, subnormals: ref_op("sqrt", fmt, a, None, None, subnormals),
    "copy": lambda fmt, a, subnormals: (a, 0),
    "exp": _exp,
    "max": _max,
    "copysign": lambda fmt, a, b, subnormals: ((a & ~(1 << (fmt.width - 1))) | (b & (1 << (fmt.width - 1))), 0),
    "sin": lambda fmt, a, subnormals: trig_word("sin", fmt, a, None, subnormals),
    "cos": lambda fmt, a, subnormals: trig_word("cos", fmt, a, None, subnormals),
    "atan2": lambda fmt, a, b, subnormals: trig_word("atan2", fmt, a, b, subnormals),
}


def max_value(fmt, a: int, b: int) -> tuple[int, bool]:
    """``(max(a, b), a NaN was read)`` of two words, as :class:`Max` defines it."""
    exp_all = fmt.exp_max_field << fmt.frac_bits
    if any(x & exp_all == exp_all and x & fmt.frac_mask for x in (a, b)):
        return fmt.canonical_nan, True
    sign = 1 << (fmt.width - 1)

    def key(x):  # order of the values: -inf < ... < -0 < +0 < ... < +inf
        return -(x & ~sign) - 1 if x & sign else x
    return (b if key(b) > key(a) else a), False


def to_words(fmt, values) -> list[int]:
    """Float64 values rounded once to ``fmt``'s words (NaN: the canonical NaN)."""
    out = []
    for v in map(float, values):
        sign = int(math.copysign(1.0, v) < 0)
        if math.isnan(v):
            out.append(fmt.canonical_nan)
        elif math.isinf(v):
            out.append(fmt.inf(sign))
        else:
            out.append(round_to_format(fmt, sign, abs(Fraction(v)))[0])
    return out


def from_words(fmt, words) -> list[float]:
    """The values of ``fmt`` words as float64 (exact for every format up to binary64)."""
    return [float(decode(fmt, w)) for w in words]
