"""Parameters of the linear Kalman filter core, validated once (pure Python, no Amaranth).

``--states n --measurements m --inputs nu``: a state of n, m measurements, nu control inputs
(B u; 0: no control), the IMM's spellings. The user's F, B, H, Q, R, the state x and its
covariance P live in the buffer. ``--steady-gain``: a fixed gain K in the buffer instead of
P, Q and R (the cheapest core: x = F x + B u; x = x + K (z - H x)).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

from ..arith.float.format import FloatFormat
from ..arith.float.params import OMIT_NONE, check_target
from ..describe import ParamError
from ..engine.params import check_bus, check_div_sqrt, check_format, check_generation, check_work
from .regmap import kf_map

__all__ = ["KfParams", "STATES_MAX", "MEASUREMENTS_MAX", "INPUTS_MAX", "PES_MAX"]

#: Largest n, m and nu: the ID register holds each in 8 bits.
STATES_MAX = 255
MEASUREMENTS_MAX = 255
INPUTS_MAX = 255
#: Most processing elements (the ID register's field; the scheduler gains little beyond).
PES_MAX = 64


def _count(key: str, value, lo: int, hi: int, what: str) -> None:
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise ParamError(key, f"the number of {what} must be an integer in {lo}..{hi}, not {value!r}")


@dataclass(frozen=True)
class KfParams:
    """One linear Kalman filter core.

    Parameters
    ----------
    states : int
        n, the length of the state x.
    measurements : int
        m, the length of z; S = H P H^T + R (m x m) is factored by LDL^T.
    inputs : int
        nu, the length of the control u (x^- = F x + B u); 0: no control, no B and u.
    pes : int
        Processing elements P.
    div_sqrt : str or None
        ``iterative`` or ``pipelined`` divider and square root; ``None``: iterative at P = 1.
    banks : int or None
        Dual-port banks of the operand memory; ``None``: 2P.
    format : str
        Float format of the buffer and the arithmetic.
    irq : bool
    streams : bool
        The optional AXI4-Stream ports: z (and u) in, x and P's diagonal out.
    steady_gain : bool
        A fixed gain K in the buffer, written by software (the discrete algebraic Riccati
        equation's, :func:`kfgen.sim.kf.reference.steady_gain`, computed in float64): no P, Q,
        R, S; an iteration is a few multiply-adds an entry.
    address_width : int or None
        AXI byte-address width; ``None``: the smallest that holds the map (replaced by it).
    target_mhz : float or None
        A clock in MHz to pipeline the engine's units for, as the UKF's; ``None``: the units'
        defaults.
    name : str
        Top-level module name.
    """

    states: int = 4
    measurements: int = 2
    inputs: int = 0
    pes: int = 1
    div_sqrt: str | None = None
    banks: int | None = None
    format: str = "binary32"
    irq: bool = True
    streams: bool = False
    steady_gain: bool = False
    address_width: int | None = None
    target_mhz: float | None = field(default=None, metadata=OMIT_NONE)
    name: str = "kf"

    def __post_init__(self):
        object.__setattr__(self, "target_mhz", check_target(self.target_mhz))
        _count("states", self.states, 1, STATES_MAX, "states n")
        _count("measurements", self.measurements, 1, MEASUREMENTS_MAX, "measurements m")
        _count("inputs", self.inputs, 0, INPUTS_MAX, "inputs nu")
        if isinstance(self.pes, bool) or not isinstance(self.pes, int) or not 1 <= self.pes <= PES_MAX:
            raise ParamError("pes", f"must be an integer in 1..{PES_MAX}, not {self.pes!r}")
        object.__setattr__(self, "div_sqrt", check_div_sqrt(self.div_sqrt, self.pes))
        banks = 2 * self.pes if self.banks is None else self.banks
        if isinstance(banks, bool) or not isinstance(banks, int) or not 2 <= banks <= 2 * PES_MAX:
            raise ParamError("banks", f"must be an integer in 2..{2 * PES_MAX}, not {banks!r}")
        object.__setattr__(self, "banks", banks)
        check_generation(self.pes, banks, lambda p: 2 * p)
        for key in ("streams", "steady_gain"):
            if not isinstance(getattr(self, key), bool):
                raise ParamError(key, f"must be true or false, not {getattr(self, key)!r}")
        # the covariance prediction F P F^T and Joseph's (I - K H) P^- (I - K H)^T alone are
        # 2 n^2 (3n + 1) / 2 multiply-adds, the steady gain's state prediction n^2 (the exact
        # count is checked against the program before scheduling, in .steps)
        n = self.n
        check_work(n * n if self.steady_gain else n * n * (3 * n + 1), self.pes, "states", at_least=True)
        object.__setattr__(self, "format", check_format(self.format))
        check_bus(self)
        # the map checks that it fits, and gives the width it needs
        object.__setattr__(self, "address_width", kf_map(self).address_width)

    @property
    def n(self) -> int:
        return self.states

    @property
    def m(self) -> int:
        return self.measurements

    @property
    def nu(self) -> int:
        return self.inputs

    @property
    def fmt(self) -> FloatFormat:
        return FloatFormat.parse(self.format)

    def to_dict(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self)}
