"""The engine's instruction set: one entry per unit, and the checks a result can have.

Pure Python (no Amaranth import at module level). Every layer of the engine reads its unit
facts here: the IR (an operation's ``unit``), the scheduler (latency and initiation
interval, from the :class:`~.schedule.Machine`), the program store and microcode (the unit's
position in the store, which lanes its instructions carry), the sequencer (the instruction
word), the engine (which units it builds, and how) and the golden executor
(:data:`kfgen.sim.linalg.exec.GOLDEN`, the operation the unit computes, by the unit's name:
the golden model lives in ``sim``, which ``hdl`` never imports).

Adding a unit (``sin``, say) is one :class:`Unit` in :data:`UNITS` (its arity, the machine
field of its latency, the hardware that computes it), one operation class in
:mod:`.program` naming it, a latency field in :class:`~.schedule.Machine`, and its golden
operation in :data:`kfgen.sim.linalg.exec.GOLDEN`.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import Callable

__all__ = ["Check", "CHECK_BITS", "Unit", "UNITS", "unit"]


class Check(enum.IntEnum):
    """What the hardware watches in an operation's result (the instruction's ``check``
    field, :data:`CHECK_BITS` wide). An operation's ``check`` is given as ``None``,
    ``"pivot"`` or ``"finite"`` (or a member) and kept as a member."""

    #: Not watched.
    NONE = 0
    #: A pivot (``D_j`` of LDL^T, a Schur pivot, a sum of weights): <= 0 (``-0`` included) or
    #: NaN sets ``err_pivot``.
    PIVOT = 1
    #: A result reaching the filter's state: a NaN or an infinity sets ``err_nan``.
    FINITE = 2

    @classmethod
    def of(cls, value) -> Check:
        """The member of ``value``: ``None``, a lowercase name or a member."""
        if isinstance(value, cls):
            return value
        if value is None:
            return cls.NONE
        if isinstance(value, str) and value != "none" and value.upper() in cls.__members__:
            return cls[value.upper()]
        raise ValueError(f"check must be None, 'pivot' or 'finite', not {value!r}")


#: Bits of the instruction's ``check`` field.
CHECK_BITS = max(Check).bit_length()


def _div(fmt, stages, cycles_per_op):
    from ..arith.float.div import FloatDiv
    return FloatDiv(fmt, stages=stages, cycles_per_op=cycles_per_op)


def _sqrt(fmt, stages, cycles_per_op):
    from ..arith.float.sqrt import FloatSqrt
    return FloatSqrt(fmt, stages=stages, cycles_per_op=cycles_per_op)


def _exp(fmt, stages, cycles_per_op):
    from ..arith.float.exp import FloatExp
    return FloatExp(fmt, stages=stages)


def _trig(name):
    def build(fmt, stages, cycles_per_op):
        from ..arith.float import trig
        return {"sin": trig.FloatSin, "cos": trig.FloatCos, "atan2": trig.FloatAtan2}[name](fmt, stages=stages)
    return build


def _copy_word(fmt, a):
    return a, None


def _max_word(fmt, a, b):
    from .units import max_word
    return max_word(fmt, a, b)


def _copysign_word(fmt, a, b):
    from .units import copysign_word
    return copysign_word(fmt, a, b), None


@dataclass(frozen=True)
class Unit:
    """One executing unit of the engine.

    Parameters
    ----------
    name : str
        The operations' ``unit`` (and the unit's submodule name, but for the PEs).
    operands : tuple of str
        The read lanes of its instructions: ``("a",)`` or ``("a", "b")`` (the FMA's are the
        ``a_k``, ``b_k`` of its terms, plus ``init``).
    latency : str or None
        The :class:`~.schedule.Machine` field holding its pipeline's latency; ``None``: 0 (a
        move or a comparison, done in the result's register).
    interval : str or None
        The machine field of its initiation interval; ``None``: 1 (pipelined).
    registered : bool
        Whether the machine's ``unit_register`` adds to its latency (every unit but the PEs).
    optional : bool
        Built only when a program issues to it (the engine always has the others).
    hardware : callable or None
        ``(fmt, stages, cycles_per_op) -> float unit`` (a component with ``i_valid``,
        ``i_a``[, ``i_b``], ``o_valid``, ``o_y``, ``o_flags``, ``latency``) of an arithmetic
        shared unit; ``None`` for the PEs (:class:`~.units.ProcessingElement`) and the word
        functions.
    word : callable or None
        ``(fmt, *operand words) -> (result, nan or None)``, the Amaranth expression of a unit
        without a pipeline (a move, a comparison).
    """

    name: str
    operands: tuple
    latency: str | None
    interval: str | None = None
    registered: bool = True
    optional: bool = False
    hardware: Callable | None = None
    word: Callable | None = None

    def pipeline(self, mc) -> int | None:
        """Its pipeline's latency on machine ``mc`` (``None``: it has none)."""
        return None if self.latency is None else getattr(mc, self.latency)

    def cycles(self, mc) -> int:
        """Cycles from the arrival of its operands to its write on ``mc`` (the scheduler's
        ``L``): the unit register, if any, and its pipeline."""
        return (mc.unit_register if self.registered else 0) + (self.pipeline(mc) or 0)

    def issue_interval(self, mc) -> int:
        """Cycles from one issue to the next on ``mc`` (1: pipelined)."""
        return 1 if self.interval is None else getattr(mc, self.interval)


#: The units, in the program store's order (an instruction's ``unit`` field is the index).
UNITS: dict[str, Unit] = {u.name: u for u in (
    Unit("fma", ("a", "b"), "fma_latency", registered=False),
    Unit("div", ("a", "b"), "div_latency", "div_interval", hardware=_div),
    Unit("sqrt", ("a",), "sqrt_latency", "sqrt_interval", hardware=_sqrt),
    Unit("copy", ("a",), None, word=_copy_word),
    Unit("exp", ("a",), "exp_latency", optional=True, hardware=_exp),
    Unit("max", ("a", "b"), None, optional=True, word=_max_word),
    Unit("sin", ("a",), "sin_latency", "sin_interval", optional=True, hardware=_trig("sin")),
    Unit("cos", ("a",), "cos_latency", "cos_interval", optional=True, hardware=_trig("cos")),
    Unit("atan2", ("a", "b"), "atan2_latency", "atan2_interval", optional=True, hardware=_trig("atan2")),
    Unit("copysign", ("a", "b"), None, optional=True, word=_copysign_word),
)}


def unit(name: str) -> Unit:
    """The unit called ``name``."""
    try:
        return UNITS[name]
    except KeyError:
        raise ValueError(f"no engine unit {name!r} (units: {', '.join(UNITS)})") from None
