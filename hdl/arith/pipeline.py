"""A small scheduler for feed-forward datapaths: every value knows its pipeline stage.

Operands are delayed to a common stage before an operation, so a datapath written as a
sequence of operations is register-balanced by construction (as-soon-as-possible
scheduling). The pipeline never stalls: a ``valid`` bit travels beside the data and the
consumer decides what to do with it, which keeps clock-enable fan-out off the datapath.
Registers made here have no reset; a delayed signal keeps the reset of its source, so
a ``valid`` bit with a reset delays through registers with a reset.
"""

from __future__ import annotations

from amaranth.hdl import Const, Signal, Value

__all__ = ["Staged", "Pipeline"]


class Staged:
    """A signal whose value belongs to pipeline stage ``stage`` (cycles after stage 0)."""

    __slots__ = ("sig", "stage")

    def __init__(self, sig, stage: int):
        self.sig, self.stage = sig, stage

    def __repr__(self):
        return f"Staged({self.sig!r}, {self.stage})"


class Pipeline:
    """Builds registered operations into module ``m``'s ``sync`` domain."""

    def __init__(self, m):
        self._m = m
        self._delays: dict[Staged, list] = {}

    def at(self, v: Staged, stage: int) -> Value:
        """``v`` delayed to ``stage`` (a shared chain of registers, made once)."""
        if stage < v.stage:
            raise ValueError(f"{v!r} is not available before stage {v.stage}, wanted at {stage}")
        if isinstance(v.sig, Const):  # constants need no registers
            return v.sig
        chain = self._delays.setdefault(v, [v.sig])
        while len(chain) <= stage - v.stage:
            prev = chain[-1]
            reg = Signal.like(prev, name=f"{v.sig.name}_d{len(chain)}")
            self._m.d.sync += reg.eq(prev)
            chain.append(reg)
        return chain[stage - v.stage]

    def _apply(self, fn, vals, stage):
        stage = max([v.stage for v in vals] + [0 if stage is None else stage])
        return Value.cast(fn(*(self.at(v, stage) for v in vals))), stage

    def reg(self, name: str, fn, *vals: Staged, shape=None, stage: int | None = None) -> Staged:
        """Register ``fn(*vals)``: the result is one stage after the latest operand."""
        expr, s = self._apply(fn, vals, stage)
        # Data registers have no reset (only valid bits need one): delay chains can then
        # become shift-register LUTs, and the reset net stays small.
        out = Signal(shape if shape is not None else expr.shape(), name=name, reset_less=True)
        self._m.d.sync += out.eq(expr)
        return Staged(out, s + 1)

    def comb(self, name: str, fn, *vals: Staged, shape=None) -> Staged:
        """``fn(*vals)`` without a register: for wiring and single gates only."""
        expr, s = self._apply(fn, vals, None)
        out = Signal(shape if shape is not None else expr.shape(), name=name)
        self._m.d.comb += out.eq(expr)
        return Staged(out, s)
