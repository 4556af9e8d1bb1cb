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

The microcode (:mod:`.microcode`) packs the instructions into one ROM per PE and shared
unit, each word as wide as that unit's fields need (:attr:`.engine.Engine.program_roms`
gives the ROMs built).
"""

from __future__ import annotations

from dataclasses import dataclass

from .isa import UNITS, Check
from .program import Dot
from .schedule import Schedule

__all__ = ["Instruction", "encode"]

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
