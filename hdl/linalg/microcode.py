"""The program store's ROM images: the compact instructions of :mod:`.store`, split into one
stream per issuing unit and with every address split into (bank, row).

Pure Python (no Amaranth import). A unit issues at most once a cycle, so each stream's
instructions start on distinct cycles and one ROM read a cycle keeps up with it: the engine
has one stream per PE (``pe0`` ...), and one each for the divider, the square root and the
move unit, and for the exponential and the comparator when a step uses them. A stream holds
every step, one after the other; ``bases``/``ends`` delimit them.

Addresses are stored as ``(bank, row)`` with ``a = bank + banks * row``, the memory's own
coordinates, so that no address is divided by ``banks`` (``2P``, often not a power of two)
in hardware. A stride ``s`` is stored as ``(s mod banks, floor(s / banks) mod 2**row_bits)``:
``bank + s_bank`` wraps at most once, its carry goes into the row.
"""

from __future__ import annotations

from dataclasses import dataclass

from .isa import UNITS
from .schedule import LANE_READ_LATENCY, Schedule
from .store import Instruction, encode

__all__ = ["Geometry", "StreamImage", "Microcode", "compile_steps", "LANE_READ_LATENCY"]


def _bits(v: int) -> int:
    return max(1, int(v).bit_length())


@dataclass(frozen=True)
class Geometry:
    """The banked memory: ``size`` words, word ``a`` in bank ``a % banks`` at row ``a // banks``."""

    size: int
    banks: int

    @property
    def rows(self) -> int:
        return -(-self.size // self.banks)

    @property
    def bank_bits(self) -> int:
        return _bits(self.banks - 1)

    @property
    def row_bits(self) -> int:
        return _bits(self.rows - 1)

    def addr(self, a: int) -> dict:
        return {"bank": a % self.banks, "row": a // self.banks}

    def stride(self, s: int) -> dict:
        return {"bank": s % self.banks, "row": (s // self.banks) % (1 << self.row_bits)}


@dataclass
class StreamImage:
    """One unit's instructions for every step: ``words`` (field dicts), ``bases[k]`` and
    ``ends[k]`` the first and one-past-last index of step ``k``."""

    unit: str
    words: list
    bases: list
    ends: list


@dataclass
class Microcode:
    geometry: Geometry
    streams: dict  # name -> StreamImage
    widths: dict  # field -> bits (delta, count)
    cycles: list  # per step, the scheduler's count


def _word(ins: Instruction, delta: int, g: Geometry) -> dict:
    dst = ins.dst + (ins.dst[0],) * (2 - len(ins.dst)) if ins.dst else (0, 0)
    w = {
        "delta": delta,
        "a": g.addr(ins.a0),
        "b": g.addr(ins.b0),
        "dst": g.addr(dst[0]),
        "dst1": g.addr(dst[1]),
        "mirror": int(len(ins.dst) == 2),
        "check": int(ins.check),
        **dict(zip(("pa", "pb", "pi", "pd0", "pd1"), ins.ports)),
    }
    if ins.unit == "fma":
        w.update({
            "count": ins.count,
            "sa": g.stride(ins.sa),
            "sb": g.stride(ins.sb),
            "neg": int(ins.neg),
            "first": int(ins.first),
            "init_en": int(ins.init is not None),
            "init": g.addr(ins.init or 0),
            "last": int(ins.last),
        })
    return w


def compile_steps(scheds: list[Schedule]) -> Microcode:
    """The ROM images of the steps ``scheds`` (one machine, one memory layout)."""
    mc = scheds[0].machine
    layout = scheds[0].program.layout
    for s in scheds:
        if s.machine != mc or s.program.layout is not layout:
            raise ValueError("every step must be scheduled on one machine and one memory layout")
    if mc.pes is None:
        raise ValueError("the engine needs a machine with a finite number of PEs")
    if mc.read_latency != LANE_READ_LATENCY:
        raise ValueError(f"the engine's memory has read latency {LANE_READ_LATENCY}, not {mc.read_latency}")
    g = Geometry(layout.size, mc.banks)
    shared = [u.name for u in UNITS.values() if u.name != "fma"
              and (not u.optional or any(u.name in s.program.units for s in scheds))]
    names = [f"pe{p}" for p in range(mc.pes)] + shared
    streams = {k: StreamImage("fma" if k.startswith("pe") else k, [], [], []) for k in names}
    deltas, counts = [0], [1]
    for s in scheds:
        per = {k: [] for k in names}
        for ins in encode(s):
            per[f"pe{ins.pe}" if ins.unit == "fma" else ins.unit].append(ins)
        for k, lst in per.items():
            img = streams[k]
            img.bases.append(len(img.words))
            prev = 0  # the step's first instruction counts from cycle 0
            for i, ins in enumerate(lst):
                d = ins.start - prev
                if i and d < 1:
                    raise AssertionError(f"two {k} instructions start on cycle {ins.start}")
                img.words.append(_word(ins, d, g))
                deltas.append(d)
                counts.append(ins.count)
                prev = ins.start
            img.ends.append(len(img.words))
    widths = {"delta": _bits(max(deltas)), "count": _bits(max(counts))}
    return Microcode(g, streams, widths, [s.cycles for s in scheds])
