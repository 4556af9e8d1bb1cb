"""The engine's intermediate representation: a step is a list of operations on one
word-addressed operand memory.

Pure Python (no Amaranth import). An operation is one of

* :class:`Dot`: ``acc = init; acc = fma(+-a_k, b_k, acc)`` for the terms in their listed order,
  each FMA rounded once. The listed order is part of the program, so every schedule of it and
  the golden model give the same bits. Without ``init`` the accumulation starts from ``-0`` (the neutral addend: ``x + -0 = x`` for
  every ``x``, zeros included). Negating a product costs nothing in hardware (a sign bit).
* :class:`Div` ``a / b`` and :class:`Sqrt` ``sqrt(a)``, on the one shared divider and
  square root;
* :class:`Copy` ``dst = src``, the word unchanged, on the memory's move unit (no PE);
* :class:`Exp` ``exp(a)`` on a shared pipelined exponential (the IMM's likelihoods), and
  :class:`Max` ``max(a, b)`` on a comparator and :class:`CopySign` (a sign bit moved) (latency
  0, like the move unit). An engine has
  these units only when one of its programs uses them.

The program's order is its meaning: an operation reads what earlier operations wrote (the
scheduler keeps read-after-write, write-after-read and write-after-write order). ``check``
marks the results the hardware watches: ``"pivot"`` (a pivot ``D_j <= 0`` or NaN: err_pivot)
and ``"finite"`` (a NaN or infinity reaching the filter's state: err_nan).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from . import isa
from .isa import Check

__all__ = ["Region", "Layout", "Dot", "Div", "Sqrt", "Copy", "Exp", "Max", "CopySign", "Sin", "Cos", "Atan2", "Program",
           "UNITS", "OPS"]

#: The executing units' names, in the program store's order (:data:`.isa.UNITS`).
UNITS = tuple(isa.UNITS)


@dataclass(frozen=True)
class Region:
    """``rows x cols`` words from ``base``, row-major. ``kind`` is ``bus`` (the processor's
    buffer), ``work`` (internal) or ``const`` (initialised at generation, never written)."""

    name: str
    base: int
    rows: int
    cols: int
    kind: str

    @property
    def size(self) -> int:
        return self.rows * self.cols

    def __call__(self, i: int, j: int = 0) -> int:
        if not (0 <= i < self.rows and 0 <= j < self.cols):
            raise IndexError(f"{self.name}[{i}, {j}] outside {self.rows} x {self.cols}")
        return self.base + i * self.cols + j


@dataclass
class Layout:
    """The operand memory: regions placed one after another, and the constant words."""

    regions: dict[str, Region] = field(default_factory=dict)
    size: int = 0
    consts: dict[int, int] = field(default_factory=dict)  # address -> word

    def add(self, name: str, rows: int, cols: int = 1, kind: str = "work") -> Region:
        if name in self.regions:
            raise ValueError(f"region {name!r} is already placed")
        if kind not in ("bus", "work", "const"):
            raise ValueError(f"kind must be bus, work or const, not {kind!r}")
        r = Region(name, self.size, rows, cols, kind)
        self.regions[name] = r
        self.size += r.size
        return r

    def const(self, name: str, words: list[int]) -> Region:
        """A constant region holding ``words`` (one row)."""
        r = self.add(name, 1, len(words), "const")
        for i, w in enumerate(words):
            self.consts[r(0, i)] = w
        return r

    def __getitem__(self, name: str) -> Region:
        return self.regions[name]

    def initial_memory(self) -> list[int]:
        """Zeros everywhere but the constants (what the hardware's memory holds at reset)."""
        mem = [0] * self.size
        for a, w in self.consts.items():
            mem[a] = w
        return mem


def _addr(x, what):
    if isinstance(x, bool) or not isinstance(x, int) or x < 0:
        raise ValueError(f"{what} must be a memory address, not {x!r}")
    return x


def _dst(dst):
    dst = (dst,) if isinstance(dst, int) else tuple(dst)
    if not 1 <= len(dst) <= 2 or len(set(dst)) != len(dst):
        raise ValueError(f"dst must be one address or two distinct ones (a mirror), not {dst!r}")
    return tuple(_addr(d, "dst") for d in dst)


def _check(check) -> Check:
    return Check.of(check)


@dataclass(frozen=True)
class Dot:
    """``dst = init + sum(+-a_k * b_k)`` accumulated in the listed order, one rounding per term.

    ``terms`` are ``(a, b, neg)``; ``dst`` one address, or two for a symmetric matrix's mirror
    (the same word written twice)."""

    dst: tuple[int, ...]
    init: int | None
    terms: tuple[tuple[int, int, bool], ...]
    check: Check = Check.NONE

    def __init__(self, dst, init=None, terms=(), check=None):
        object.__setattr__(self, "dst", _dst(dst))
        object.__setattr__(self, "init", None if init is None else _addr(init, "init"))
        ts = tuple((_addr(a, "a"), _addr(b, "b"), bool(neg)) for a, b, neg in terms)
        if not ts:
            raise ValueError("a Dot needs at least one term (a copy is a Copy)")
        object.__setattr__(self, "terms", ts)
        object.__setattr__(self, "check", _check(check))

    @property
    def reads(self) -> tuple[int, ...]:
        head = () if self.init is None else (self.init,)
        return head + tuple(x for a, b, _ in self.terms for x in (a, b))

    @property
    def unit(self) -> str:
        return "fma"


@dataclass(frozen=True)
class _Binary:
    """``dst = unit(a, b)`` on a shared unit (``UNIT``)."""

    dst: tuple[int, ...]
    a: int
    b: int
    check: Check = Check.NONE

    def __init__(self, dst, a, b, check=None):
        object.__setattr__(self, "dst", _dst(dst))
        object.__setattr__(self, "a", _addr(a, "a"))
        object.__setattr__(self, "b", _addr(b, "b"))
        object.__setattr__(self, "check", _check(check))

    @property
    def reads(self):
        return (self.a, self.b)

    @property
    def unit(self) -> str:
        return self.UNIT


@dataclass(frozen=True)
class _Unary:
    """``dst = unit(a)`` on a shared unit (``UNIT``)."""

    dst: tuple[int, ...]
    a: int
    check: Check = Check.NONE

    def __init__(self, dst, a, check=None):
        object.__setattr__(self, "dst", _dst(dst))
        object.__setattr__(self, "a", _addr(a, "a"))
        object.__setattr__(self, "check", _check(check))

    @property
    def reads(self):
        return (self.a,)

    @property
    def unit(self) -> str:
        return self.UNIT


class Div(_Binary):
    """``dst = a / b`` on the shared divider."""

    UNIT = "div"


class Max(_Binary):
    """``dst = max(a, b)``, exact: the larger value (``+0`` above ``-0``), ``a`` when they are
    equal, the canonical NaN when either is a NaN."""

    UNIT = "max"


class CopySign(_Binary):
    """``dst = copysign(a, b)``, exact: ``a``'s magnitude with ``b``'s sign bit (IEEE 754
    ``copySign``, a NaN's payload kept, no flags), in the result's register (latency 0)."""

    UNIT = "copysign"


class Sqrt(_Unary):
    """``dst = sqrt(a)`` on the shared square root."""

    UNIT = "sqrt"


class Exp(_Unary):
    """``dst = exp(a)`` on the shared exponential (faithfully rounded, :class:`FloatExp`)."""

    UNIT = "exp"


@dataclass(frozen=True)
class Copy:
    """``dst = src``, bit for bit, on the move unit."""

    dst: tuple[int, ...]
    src: int
    check: Check = Check.NONE

    def __init__(self, dst, src, check=None):
        object.__setattr__(self, "dst", _dst(dst))
        object.__setattr__(self, "src", _addr(src, "src"))
        object.__setattr__(self, "check", _check(check))

    @property
    def reads(self):
        return (self.src,)

    @property
    def unit(self) -> str:
        return "copy"


class Sin(_Unary):
    """``dst = sin(a)`` on the shared iterative sine (faithfully rounded, :class:`FloatSin`)."""

    UNIT = "sin"


class Cos(_Unary):
    """``dst = cos(a)`` on the shared iterative cosine (faithfully rounded, :class:`FloatCos`)."""

    UNIT = "cos"


class Atan2(_Binary):
    """``dst = atan2(a, b)`` (``a`` is y, ``b`` is x) on the shared iterative arctangent
    (faithfully rounded, :class:`FloatAtan2`)."""

    UNIT = "atan2"


#: The operation class of each unit but the FMA's (:class:`Dot`), by the unit's name.
OPS = {cls.UNIT: cls for cls in (Div, Max, CopySign, Sqrt, Exp, Sin, Cos, Atan2)} | {"copy": Copy}


@dataclass
class Program:
    """One step: its operations in program order, on ``layout``'s memory, in format ``fmt``."""

    name: str
    layout: Layout
    fmt: object
    ops: list = field(default_factory=list)

    def emit(self, op):
        for a in (*op.reads, *op.dst):
            if a >= self.layout.size:
                raise ValueError(f"address {a} outside the {self.layout.size}-word memory")
        for a in op.dst:
            if a in self.layout.consts:
                raise ValueError(f"address {a} is a constant and cannot be written")
        self.ops.append(op)
        return op

    @property
    def fma_count(self) -> int:
        """Multiply-adds."""
        return sum(len(op.terms) for op in self.ops if isinstance(op, Dot))

    @property
    def units(self) -> set:
        """The units this program issues to."""
        return {op.unit for op in self.ops}

    def count(self, unit: str) -> int:
        return sum(1 for op in self.ops if op.unit == unit)
