"""Parameters of the EKF core, validated once (pure Python, no Amaranth).

The application (``module:Class``, the UKF's application class) fixes the sizes: n states,
nw process-noise and nv measurement-noise terms, m observations and nu control inputs, named
as the UKF's command line names them (``inputs`` for nu). The register map is not yet part of
the core (no ``address_width``): this is what the programs, the machine and the schedules
need.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

from ..arith.float.format import FloatFormat
from ..arith.float.params import OMIT_NONE, check_target
from ..describe import ParamError, check_name
from ..engine.params import check_div_sqrt, check_format, check_generation, check_work

__all__ = ["EkfParams", "SIZE_MAX"]

#: Largest n, m, nw, nv and nu (the UKF's: 8-bit fields of an ID register).
SIZE_MAX = 255

_SIZES = (("states", "states", 1), ("observations", "observations", 1), ("process_noise", "process-noise terms", 1),
          ("measurement_noise", "measurement-noise terms", 1), ("inputs", "control inputs", 0))


@dataclass(frozen=True)
class EkfParams:
    """Generation parameters of the EKF core.

    Parameters
    ----------
    app : str
        The application, ``module:Class`` or ``file.py:Class`` (a
        :class:`~kfgen.sim.ukf.app.UkfApplication`): its f and h and their Jacobians run on chip.
    states, observations, process_noise, measurement_noise : int
        n, m, nw and nv, 1..255 each (the application's).
    inputs : int
        nu, the control input's length, 0..255 (the application's).
    pes : int
        Processing elements P, 1..16.
    div_sqrt : str or None
        ``iterative`` or ``pipelined`` divider and square root; ``None``: iterative at P = 1,
        pipelined above.
    banks : int or None
        Dual-port banks of the operand memory, at least 2, P x banks at most
        :data:`~kfgen.hdl.engine.params.GEN_CROSSBAR_MAX`; ``None``: 2P.
    format : str
        Float format of the buffer and the arithmetic (at most 64 bits); its canonical name.
    streams : bool
        AXI4-Stream ports beside the AXI4 slave (z and u in; x and diag P out), as the UKF's.
    irq : bool
        Whether the core has an ``irq`` output.
    target_mhz : float or None
        A clock in MHz to pipeline the engine's units for, as the UKF's; ``None``: the units' defaults.
    name : str
        Top-level module name.

    Raises
    ------
    ParamError
        Naming the first bad parameter and what it may be.
    """

    app: str
    states: int
    observations: int
    process_noise: int
    measurement_noise: int
    inputs: int = 0
    pes: int = 1
    div_sqrt: str | None = None
    banks: int | None = None
    format: str = "binary32"
    streams: bool = False
    irq: bool = True
    target_mhz: float | None = field(default=None, metadata=OMIT_NONE)
    name: str = "ekf"

    def __post_init__(self):
        object.__setattr__(self, "target_mhz", check_target(self.target_mhz))
        if not isinstance(self.app, str) or not self.app:
            raise ParamError("app", f"must be MODULE:CLASS or FILE.py:CLASS, not {self.app!r}")
        for key, what, lo in _SIZES:
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= SIZE_MAX:
                raise ParamError(key, f"the number of {what} must be an integer in {lo}..{SIZE_MAX}, not {v!r}")
        if isinstance(self.pes, bool) or not isinstance(self.pes, int) or self.pes < 1:
            raise ParamError("pes", f"must be a positive integer, not {self.pes!r}")
        object.__setattr__(self, "div_sqrt", check_div_sqrt(self.div_sqrt, self.pes))
        banks = 2 * self.pes if self.banks is None else self.banks
        if isinstance(banks, bool) or not isinstance(banks, int) or banks < 2:
            raise ParamError("banks", f"must be an integer >= 2, not {banks!r}")
        object.__setattr__(self, "banks", banks)
        check_generation(self.pes, banks, lambda p: 2 * p)
        # the covariance update P = P^- - K (H P^-) alone is n (n + 1) / 2 x m multiply-adds
        # (the programs' exact count is checked before scheduling, in .steps)
        check_work(self.n * (self.n + 1) // 2 * self.m, self.pes, "states", at_least=True)
        object.__setattr__(self, "format", check_format(self.format))
        for key in ("streams", "irq"):
            if not isinstance(getattr(self, key), bool):
                raise ParamError(key, f"must be true or false, not {getattr(self, key)!r}")
        check_name(self.name)

    @property
    def n(self) -> int:
        return self.states

    @property
    def m(self) -> int:
        return self.observations

    @property
    def nw(self) -> int:
        return self.process_noise

    @property
    def nv(self) -> int:
        return self.measurement_noise

    @property
    def nu(self) -> int:
        return self.inputs

    @property
    def sizes(self) -> tuple[int, int, int, int, int]:
        """(n, nw, nv, m, nu), as :class:`~.models.EkfModels` has them."""
        return (self.n, self.nw, self.nv, self.m, self.nu)

    @property
    def fmt(self) -> FloatFormat:
        return FloatFormat.parse(self.format)

    def to_dict(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self)}
