"""The engine's instruction set: one entry per unit, and the checks a result can have.

Pure Python, importing nothing of kfgen: the bottom of the engine, whose every layer reads
its unit facts here: the IR (an operation's ``unit``), the scheduler (latency and initiation
interval, from the :class:`~.schedule.Machine`), the program store and microcode (the unit's
position in the store, which lanes its instructions carry), the sequencer (the instruction
word), the engine (which units it builds) and the golden executor
(:data:`kfgen.sim.linalg.exec.GOLDEN`, the operation the unit computes, by the unit's name:
the golden model lives in ``sim``, which ``hdl`` never imports).

Adding a unit (``sin``, say) is one :class:`Unit` in :data:`UNITS` (its arity, the machine
field of its latency), the hardware that computes it in :mod:`.units`, one operation class in
:mod:`.program` naming it, a latency field in :class:`~.schedule.Machine`, and its golden
operation in :data:`kfgen.sim.linalg.exec.GOLDEN`.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

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

    The hardware that computes a unit is :mod:`.units`' (:data:`~.units.HARDWARE`,
    :data:`~.units.WORDS`): this table is plain data, which every layer above reads.
    """

    name: str
    operands: tuple
    latency: str | None
    interval: str | None = None
    registered: bool = True
    optional: bool = False

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
    Unit("div", ("a", "b"), "div_latency", "div_interval"),
    Unit("sqrt", ("a",), "sqrt_latency", "sqrt_interval"),
    Unit("copy", ("a",), None),
    Unit("exp", ("a",), "exp_latency", optional=True),
    Unit("max", ("a", "b"), None, optional=True),
    Unit("sin", ("a",), "sin_latency", "sin_interval", optional=True),
    Unit("cos", ("a",), "cos_latency", "cos_interval", optional=True),
    Unit("atan2", ("a", "b"), "atan2_latency", "atan2_interval", optional=True),
    Unit("copysign", ("a", "b"), None, optional=True),
)}


def unit(name: str) -> Unit:
    """The unit called ``name``."""
    try:
        return UNITS[name]
    except KeyError:
        raise ValueError(f"no engine unit {name!r} (units: {', '.join(UNITS)})") from None
