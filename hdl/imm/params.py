"""Parameters of the IMM core, validated once (pure Python, no Amaranth).

``--models R --states n --measurements d``: R models of n states measured by d values. The
defaults are the slides' satellite-link scenario (:mod:`kfgen.sim.imm.scenario`): five
channel conditions, a constant-acceleration model of SNR and SIR (n = 6), both measured
(d = 2).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

from ..arith.float.format import FloatFormat
from ..arith.float.params import OMIT_NONE, check_target
from ..describe import ParamError
from ..schur.program import SIZE_MAX as D_MAX
from ..engine.params import BINARY32, check_bus, check_div_sqrt, check_format, check_generation, check_work
from .regmap import imm_map

__all__ = ["ImmParams", "MODELS_MAX", "STATES_MAX", "D_MAX", "PES_MAX"]

#: Largest R and n: the ID register holds each in 8 bits.
MODELS_MAX = 255
STATES_MAX = 255
#: Most processing elements (the ID register's field; the scheduler gains little beyond).
PES_MAX = 64


@dataclass(frozen=True)
class ImmParams:
    """One IMM core.

    Parameters
    ----------
    models : int
        R >= 2 models (filters), each with its own F, Q, H and R in the buffer.
    states : int
        n, the length of every model's state.
    measurements : int
        d, the length of z; S^-1 by the Schur-complement graph (d <= 8).
    pes : int
        Processing elements P.
    div_sqrt : str or None
        ``iterative`` or ``pipelined`` divider and square root; ``None``: iterative at P = 1.
    banks : int or None
        Dual-port banks of the operand memory; ``None``: 2P.
    format : FloatFormat or str
        Float format of the buffer and the arithmetic (a name is replaced by the
        :class:`FloatFormat`).
    irq : bool
    address_width : int or None
        AXI byte-address width; ``None``: the smallest that holds the map.
    target_mhz : float or None
        A clock in MHz to pipeline the engine's units for, as the UKF's
        (:class:`kfgen.hdl.ukf.params.UkfParams`); ``None``: the units' defaults.
    name : str
        Top-level module name.
    """

    models: int = 5
    states: int = 6
    measurements: int = 2
    pes: int = 1
    div_sqrt: str | None = None
    banks: int | None = None
    format: FloatFormat | str = BINARY32
    irq: bool = True
    address_width: int | None = None
    target_mhz: float | None = field(default=None, metadata=OMIT_NONE)
    name: str = "imm"

    def __post_init__(self):
        object.__setattr__(self, "target_mhz", check_target(self.target_mhz))
        for key, lo, hi, what in (("models", 2, MODELS_MAX, "models R"), ("states", 1, STATES_MAX, "states n"),
                                  ("measurements", 1, D_MAX, "measurements d")):
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
                raise ParamError(key, f"the number of {what} must be an integer in {lo}..{hi}, not {v!r}")
        if isinstance(self.pes, bool) or not isinstance(self.pes, int) or not 1 <= self.pes <= PES_MAX:
            raise ParamError("pes", f"must be an integer in 1..{PES_MAX}, not {self.pes!r}")
        object.__setattr__(self, "div_sqrt", check_div_sqrt(self.div_sqrt, self.pes))
        banks = 2 * self.pes if self.banks is None else self.banks
        if isinstance(banks, bool) or not isinstance(banks, int) or not 2 <= banks <= 2 * PES_MAX:
            raise ParamError("banks", f"must be an integer in 2..{2 * PES_MAX}, not {banks!r}")
        object.__setattr__(self, "banks", banks)
        check_generation(self.pes, banks, lambda p: 2 * p)
        # each model's covariance prediction F P F^T alone is 2 n^3 multiply-adds (the exact
        # count is checked against the program before scheduling, in .steps)
        check_work(2 * self.R * self.n ** 3, self.pes, "states", at_least=True)
        object.__setattr__(self, "format", check_format(self.format))
        check_bus(self)
        # the map checks that it fits, and gives the width it needs
        object.__setattr__(self, "address_width", imm_map(self).address_width)

    @property
    def R(self) -> int:
        return self.models

    @property
    def n(self) -> int:
        return self.states

    @property
    def d(self) -> int:
        return self.measurements

    @property
    def fmt(self) -> FloatFormat:
        """:attr:`format` itself (the name the engine's modules read it by)."""
        return self.format

    def to_dict(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self)}
