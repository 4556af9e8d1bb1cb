"""Compact program store: one instruction per accumulation segment instead of one ROM word
per cycle.

An instruction starts one operation (or one affine run of an accumulation's terms) at a
cycle given as a delta from the previous instruction's start. An FMA segment names its PE and
two address generators, ``a_k = a0 + k sa`` and ``b_k = b0 + k sb``, issued every ``Lf``
cycles for ``count`` terms; the first segment of an accumulation is marked ``first`` (its
addend is ``init``, or ``-0`` without one, instead of the PE's feedback) and carries
``init``, the last its destination(s) and check. A division, square root, copy,
exponential or maximum is one instruction. The sequencer keeps one segment generator per PE
interleave slot (``Lf`` per PE).

Field widths are the fewest bits that hold every value of the program set (the three UKF
steps share one store), so the size is exact for this configuration.
"""

from __future__ import annotations

from dataclasses import dataclass

from .isa import CHECK_BITS, UNITS, Check
from .program import Dot
from .schedule import Schedule

__all__ = ["Instruction", "encode", "StoreSize", "store_size"]

_CODE = {name: k for k, name in enumerate(UNITS)}  # the unit field's value


@dataclass(frozen=True)
class Instruction:
    start: int
    unit: str
    pe: int
    count: int  # FMA terms in this segment (1 for the other units)
    a0: int
    sa: int
    b0: int
    sb: int
    neg: bool
    first: bool  # first segment of an accumulation (every div, sqrt and copy)
    init: int | None  # first segment of an FMA accumulation
    dst: tuple[int, ...]  # last segment (empty otherwise)
    last: bool
    check: Check
    ports: tuple = (0, 0, 0, 0, 0)  # memory port of lanes a, b, init, dst0, dst1


def _runs(terms):
    """Split terms into maximal runs with constant address strides and sign."""
    runs, i = [], 0
    while i < len(terms):
        j = i + 1
        if j < len(terms) and terms[j][2] == terms[i][2]:
            sa, sb = terms[j][0] - terms[i][0], terms[j][1] - terms[i][1]
            while (j < len(terms) and terms[j][2] == terms[i][2]
                   and terms[j][0] - terms[j - 1][0] == sa and terms[j][1] - terms[j - 1][1] == sb):
                j += 1
        else:
            sa = sb = 0
        runs.append((i, j, sa, sb))
        i = j
    return runs


def _ports(p) -> tuple:
    return tuple(p.ports.get(k, 0) for k in ("a", "b", "init", "dst0", "dst1"))


def encode(sched: Schedule) -> list[Instruction]:
    """The instructions of one scheduled step, in start order."""
    lf = sched.machine.fma_latency
    out = []
    for p in sched.placements:
        op = sched.program.ops[p.op]
        if isinstance(op, Dot):
            runs = _runs(op.terms)
            for r, (i, j, sa, sb) in enumerate(runs):
                last = r == len(runs) - 1
                out.append(Instruction(p.start + i * lf, "fma", p.pe, j - i, op.terms[i][0], sa,
                                       op.terms[i][1], sb, op.terms[i][2], r == 0,
                                       op.init if r == 0 else None, op.dst if last else (),
                                       last, op.check if last else Check.NONE, _ports(p)))
        else:
            rd = op.reads
            out.append(Instruction(p.start, p.unit, 0, 1, rd[0], 0, rd[1] if len(rd) > 1 else 0,
                                   0, False, True, None, op.dst, True, op.check, _ports(p)))
    out.sort(key=lambda ins: (ins.start, _CODE[ins.unit], ins.pe))
    return out


def _bits(v: int) -> int:
    return max(1, int(v).bit_length())


def _sbits(v: int) -> int:
    return _bits(abs(v)) + 1


@dataclass(frozen=True)
class StoreSize:
    instructions: int
    word_bits: int
    fields: dict

    @property
    def bits(self) -> int:
        return self.instructions * self.word_bits


def store_size(scheds: list[Schedule], memory_words: int) -> StoreSize:
    """Size of one store holding every step in ``scheds`` (start deltas reset per step)."""
    progs = [encode(s) for s in scheds]
    allins = [i for p in progs for i in p]
    deltas = [b.start - a.start for p in progs for a, b in zip([p[0]] + p, p)]
    pes = max(s.machine.pes or 1 for s in scheds)
    A = _bits(memory_words - 1)
    f = {
        "unit": _bits(max([_CODE[u.name] for u in UNITS.values() if not u.optional]
                          + [_CODE[i.unit] for i in allins])),
        "pe": _bits(pes - 1),
        "delta": _bits(max(deltas)),
        "count": _bits(max(i.count for i in allins)),
        "a0": A, "sa": max(_sbits(i.sa) for i in allins),
        "b0": A, "sb": max(_sbits(i.sb) for i in allins),
        "neg": 1,
        "first": 1,
        "init": 1 + A,  # valid + address
        "dst": 1 + 2 * A,  # a mirror flag, two addresses (the second only when mirrored)
        "last": 1,
        "check": CHECK_BITS,
        "ports": 5,  # a, b, init, dst0, dst1
    }
    return StoreSize(len(allins), sum(f.values()), f)
