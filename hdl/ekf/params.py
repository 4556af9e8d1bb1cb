"""Parameters of the EKF core, validated once (pure Python, no Amaranth).

The application (``module:Class``, the UKF's application class) fixes the sizes: n states,
nw process-noise and nv measurement-noise terms, m observations and nu control inputs, named
as the UKF's command line names them (``inputs`` for nu). The parameters load the application
themselves (:attr:`EkfParams.models`, traced and differentiated once per application): a
model that does not load, whose Q, R or P0 is not finite and positive definite, or that does
not differentiate is refused here, before any build.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from functools import lru_cache

from ..arith.float.format import FloatFormat
from ..arith.float.params import OMIT_NONE, check_target
from ..arith.float.trig_plan import trig_plan
from ..describe import ParamError
from ..engine.app import load_app
from ..engine.params import check_bus, check_div_sqrt, check_format, check_generation, check_work
from .models import EkfModels, ekf_models
from .regmap import ekf_map

__all__ = ["EkfParams", "SIZE_MAX", "app_sizes", "linearised"]

#: Largest n, m, nw, nv and nu (the UKF's: 8-bit fields of an ID register).
SIZE_MAX = 255

_SIZES = (("states", "states", 1), ("observations", "observations", 1), ("process_noise", "process-noise terms", 1),
          ("measurement_noise", "measurement-noise terms", 1), ("inputs", "control inputs", 0))


def app_sizes(app) -> dict:
    """The parameters an application fixes: its sizes, by the command line's names."""
    return {"states": int(app.n), "observations": int(app.m), "process_noise": int(app.nw),
            "measurement_noise": int(app.nv), "inputs": int(getattr(app, "nu", 0))}


@lru_cache(maxsize=16)
def linearised(spec: str) -> tuple[dict, EkfModels]:
    """The application ``spec`` loaded, checked and its f and h differentiated, once per spec:
    its sizes (:func:`app_sizes`) and models.

    Raises
    ------
    ParamError
        ``app``: an application that does not load or fails its checks (Q, R, P0 finite and
        positive definite), or does not trace or differentiate (the op, file:line).
    """
    try:
        app = load_app(spec)
    except ValueError as exc:
        raise ParamError("app", " ".join(str(exc).split())) from None
    return app_sizes(app), ekf_models(app)


@dataclass(frozen=True)
class EkfParams:
    """Generation parameters of the EKF core.

    Parameters
    ----------
    app : str
        The application, ``module:Class`` or ``file.py:Class`` (a
        :class:`~kfgen.hdl.engine.app.UkfApplication`): its f and h and their Jacobians run on
        chip. Required.
    states, observations, process_noise, measurement_noise : int or None
        n, m, nw and nv, 1..255 each: the application's (``None`` is replaced by them; another
        value is refused).
    inputs : int or None
        nu, the control input's length, 0..255 (the application's, as the sizes).
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
    address_width : int or None
        Width of the AXI address; ``None``: the smallest that holds the map
        (:func:`kfgen.hdl.ekf.regmap.ekf_map`).
    target_mhz : float or None
        A clock in MHz to pipeline the engine's units for, as the UKF's; ``None``: the units' defaults.
    name : str
        Top-level module name.

    Raises
    ------
    ParamError
        Naming the first bad parameter and what it may be.
    """

    app: str | None = None
    states: int | None = None
    observations: int | None = None
    process_noise: int | None = None
    measurement_noise: int | None = None
    inputs: int | None = None
    pes: int = 1
    div_sqrt: str | None = None
    banks: int | None = None
    format: str = "binary32"
    streams: bool = False
    irq: bool = True
    address_width: int | None = None
    target_mhz: float | None = field(default=None, metadata=OMIT_NONE)
    name: str = "ekf"

    def __post_init__(self):
        object.__setattr__(self, "target_mhz", check_target(self.target_mhz))
        if self.app is None:
            raise ParamError("app", "the EKF differentiates an application's f and h: give --app MODULE:CLASS")
        if not isinstance(self.app, str) or not self.app:
            raise ParamError("app", f"must be MODULE:CLASS or FILE.py:CLASS, not {self.app!r}")
        for key, what, lo in _SIZES:
            v = getattr(self, key)
            if v is not None and (isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= SIZE_MAX):
                raise ParamError(key, f"the number of {what} must be an integer in {lo}..{SIZE_MAX}, not {v!r}")
        sizes, models = linearised(self.app)  # loads, checks and differentiates, or refuses
        for key, _, _ in _SIZES:
            if getattr(self, key) is None:
                object.__setattr__(self, key, sizes[key])
        if self.sizes != models.sizes:
            raise ParamError("app", f"{self.app} has n, nw, nv, m, nu = {models.sizes}, the core {self.sizes}: "
                                    "the EKF takes the application's sizes")
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
        if {op[0] for lin in (models.f, models.h) for op in lin.model.ops} & {"sin", "cos", "atan2"}:
            try:
                trig_plan(self.format)
            except ValueError as exc:
                raise ParamError("format", str(exc)) from None
        if not isinstance(self.streams, bool):
            raise ParamError("streams", f"must be true or false, not {self.streams!r}")
        check_bus(self)
        # the map checks that it fits, and gives the width it needs
        object.__setattr__(self, "address_width", ekf_map(self).address_width)

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

    @property
    def models(self) -> EkfModels:
        """The application's f and h with their Jacobians (:func:`linearised`, once per
        application)."""
        return linearised(self.app)[1]

    def to_dict(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self)}
