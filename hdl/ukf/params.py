"""Parameters of the UKF core, validated once (pure Python, no Amaranth).

Sizes follow the issue's command line ``--states n --observations m --process-noise nw
--measurement-noise nv``: x^a = [x; w; v] has M = n + nw + nv entries (eqs. 3-4). The defaults
are the chapter's nanosatellite filter, "7, 6, 7, 6, M = 20" read in that option order:
n = 7 states, m = 6 observations, nw = 7 process-noise terms (one per state), nv = 6
measurement-noise terms (one per observation, so R is m x m); the chapter's eq. (41) reads
the same way. Any reading of the four numbers gives M = 20.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

from ..arith.float.format import FloatFormat
from ..arith.float.params import OMIT_NONE, check_target
from ..arith.float.trig_plan import trig_plan
from ..describe import ParamError
from ..engine.params import BINARY32, check_bus, check_div_sqrt, check_format, check_generation, check_work
from .forms import FORMS, covariance_region
from .models import compile_models
from .regmap import ukf_map

__all__ = ["UkfParams", "SIZE_MAX", "FORMAT_FLOOR", "FLOOR_REASON", "FORMS", "covariance_region", "default_banks"]

#: Largest n, m, nw, nv: the ID register holds each in 8 bits.
SIZE_MAX = 255

#: The narrowest format the filter works in: at least 5 exponent bits and 4 fraction bits.
#: Measured with the golden model (tests/common/test_format_floor.py): the mildest application
#: (docs/examples/pendulum.py, Q = 1e-4 I) tracks at e5m4 within 1.25 times float64's error,
#: and faults (err_pivot, first sig_gen) at e4m10 (Q's entries below 4 exponent bits' normal
#: range) and at e5m3 and e8m3 (LDL^T's pivots round to zero). The shipped applications need
#: more (the tracker e6m10, the nanosatellite e6m17).
FORMAT_FLOOR = (5, 4)
FLOOR_REASON = (f"at least {FORMAT_FLOOR[0]} exponent and {FORMAT_FLOOR[1]} fraction bits: below them the "
                "first sig_gen's LDL^T pivots underflow or round to zero (err_pivot) for every application "
                "measured (the golden model, tests/common/test_format_floor.py; docs/ukf.md)")

_SIZES = (("states", "states"), ("observations", "observations"),
          ("process_noise", "process-noise terms"), ("measurement_noise", "measurement-noise terms"))


def default_banks(pes: int) -> int:
    """The UKF's default bank count: 2P up to P = 2, P from 3 to 8, 8 above."""
    return 2 * pes if pes <= 2 else min(pes, 8)


@dataclass(frozen=True)
class UkfParams:
    """Generation parameters of the UKF core.

    Parameters
    ----------
    states, observations, process_noise, measurement_noise : int
        n, m, nw and nv: states, observations, process-noise and measurement-noise terms,
        1..255 each (named as the command line's options; :attr:`n`, :attr:`m`, :attr:`nw`
        and :attr:`nv` read them by the chapter's letters).
    pes : int
        Processing elements P (FMA units working in parallel), 1..M.
    div_sqrt : str or None
        The shared divider and square root: ``iterative`` (one result bit a cycle, a new
        operation every 26 and 25 cycles in binary32: about half their area, and enough for
        the pivots' reciprocals and sqrt(D)) or ``pipelined`` (one operation a cycle: a
        shorter sig_gen). Replaced by its lowercase name; ``None`` by ``iterative`` at P = 1,
        where they are a third of the core, and ``pipelined`` above, where sig_gen's length
        matters more than their area.
    banks : int or None
        Dual-port memory banks of the engine's operand memory, 2..2M: more banks mean fewer
        port conflicts (fewer cycles) and a larger crossbar (its area grows with banks times
        lanes). ``None``: 2P up to P = 2, P from 3 to 8, 8 above (at P = 10, 8 banks take 3 %
        more cycles than 10 and leave the core 8,500 LUTs smaller).
    format : FloatFormat or str
        Float format of every buffer word: a :class:`FloatFormat` or its name, ``binary16``,
        ``bfloat16``, ``binary32``, ``binary64`` or ``eEmM``, at most 64 bits wide. Replaced by
        the :class:`FloatFormat` (manifests and headers record its name).
    w0 : float
        Weight W_0 of the centre sigma point, 0 <= W0 < 1 (eq. 5).
    form : "ldl" or "sqrt"
        The covariance's form (:data:`FORMS`): ``ldl`` keeps P and factors it every sig_gen;
        ``sqrt`` keeps a lower-triangular factor S of P = S S^T (region ``sqrtP``) and
        updates it by Householder triangularisation, never forming P.
    app : str or None
        The application (``module:Class`` or ``file.py:Class``) the core is sized for; with
        ``on_chip`` its f and h are compiled into the core (:mod:`kfgen.hdl.ukf.models`).
    on_chip : bool
        Whether the core runs the whole iteration, f and h included: one step, ``iteration``
        (CTRL.step = 3), reading ``z`` and ``u`` and leaving the estimate in ``x`` and ``P``.
        Needs ``app``. Off (the default), the core has the chapter's three steps and software
        applies f and h between them.
    streams : bool
        With ``on_chip``: AXI4-Stream ports beside the AXI4 slave, so that a design without a
        processor feeds measurements and takes estimates (``s_axis``: z then u, one
        measurement a transfer; ``m_axis``: x then the diagonal of P, ``tuser`` the step's
        err_pivot and err_nan).
    irq : bool
        Whether the core has an ``irq`` output (and an IRQ_ENABLE register).
    address_width : int or None
        Width of the AXI address; ``None`` is replaced by the smallest that holds the map
        (:func:`kfgen.hdl.ukf.regmap.ukf_map`). A wider one leaves the rest of the aperture
        unmapped (SLVERR).
    target_mhz : float or None
        A clock in MHz (ECP5-85, nextpnr) to pipeline the engine's units for: the FMA's,
        divider's, square root's and exponential's stages become the fewest the calibrated
        delay model predicts to reach it (:func:`kfgen.hdl.engine.machine.timing`; the
        schedule follows their latencies). Above
        :data:`~kfgen.hdl.engine.machine.ENGINE_MHZ` it also adds the program store's fetch
        register (a cycle more a step), and the prediction is at most
        :func:`~kfgen.hdl.engine.machine.engine_mhz`. ``None`` (the default): the units'
        defaults.
    name : str
        Top-level module name.

    Raises
    ------
    ParamError
        Naming the first bad parameter and what it may be.
    """

    states: int = 7
    observations: int = 6
    process_noise: int = 7
    measurement_noise: int = 6
    pes: int = 1
    div_sqrt: str | None = None
    banks: int | None = None
    format: FloatFormat | str = BINARY32
    w0: float = 0.0
    form: str = "ldl"
    app: str | None = None
    on_chip: bool = False
    streams: bool = False
    irq: bool = True
    address_width: int | None = None
    target_mhz: float | None = field(default=None, metadata=OMIT_NONE)
    name: str = "ukf"

    def __post_init__(self):
        object.__setattr__(self, "target_mhz", check_target(self.target_mhz))
        for key, what in _SIZES:
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= SIZE_MAX:
                raise ParamError(key, f"the number of {what} must be an integer in 1..{SIZE_MAX}, not {value!r}")
        M = self.M
        if isinstance(self.pes, bool) or not isinstance(self.pes, int) or not 1 <= self.pes <= M:
            raise ParamError("pes", f"must be an integer in 1..M = {M} (M = n + nw + nv), not {self.pes!r}")
        object.__setattr__(self, "div_sqrt", check_div_sqrt(self.div_sqrt, self.pes))
        banks = self.banks
        if banks is None:
            banks = default_banks(self.pes)
        elif isinstance(banks, bool) or not isinstance(banks, int) or not 2 <= banks <= 2 * M:
            raise ParamError("banks", f"must be an integer in 2..2M = {2 * M}, not {banks!r}")
        object.__setattr__(self, "banks", banks)
        check_generation(self.pes, banks, default_banks)
        # sig_gen factors the M x M augmented covariance and update the m x m innovation
        # covariance: at least M^3/6 and m^3/6 multiply-adds (the exact count is checked
        # against the programs before scheduling, in .steps)
        check_work(max(M ** 3, self.m ** 3) // 6, self.pes, "states", at_least=True)
        object.__setattr__(self, "format", check_format(self.format))
        if isinstance(self.w0, bool) or not isinstance(self.w0, (int, float)) or not math.isfinite(self.w0) \
                or not 0 <= self.w0 < 1:
            raise ParamError("w0", f"must be a number with 0 <= W0 < 1, not {self.w0!r}")
        if not isinstance(self.form, str) or self.form.lower() not in FORMS:
            raise ParamError("form", f"must be {' or '.join(FORMS)}, not {self.form!r}")
        object.__setattr__(self, "form", self.form.lower())
        if not isinstance(self.on_chip, bool):
            raise ParamError("on_chip", f"must be true or false, not {self.on_chip!r}")
        if self.app is not None and (not isinstance(self.app, str) or not self.app):
            raise ParamError("app", f"must be MODULE:CLASS or FILE.py:CLASS, not {self.app!r}")
        if not isinstance(self.streams, bool):
            raise ParamError("streams", f"must be true or false, not {self.streams!r}")
        if self.streams and not self.on_chip:
            raise ParamError("streams", "feeds the on-chip iteration: give --on-chip (and --app) with it")
        if self.on_chip:
            if self.app is None:
                raise ParamError("on_chip", "compiles an application's f and h into the core: give --app MODULE:CLASS")
            models = self.models  # loads and traces the application, or refuses it
            used = {op[0] for model in (models.f, models.h) for op in model.ops}
            if used & {"sin", "cos", "atan2"}:
                try:
                    trig_plan(self.format)
                except ValueError as exc:
                    raise ParamError("format", str(exc)) from None
            check_work(max(M ** 3, self.m ** 3) // 6 + self.N * models.fma_count, self.pes, "states",
                       at_least=True)
        fmt = self.format
        if fmt.exp_bits < FORMAT_FLOOR[0] or fmt.frac_bits < FORMAT_FLOOR[1]:
            raise ParamError("format", f"{fmt.name} is too narrow for the filter to work; it needs {FLOOR_REASON}")
        check_bus(self)
        # the map checks that it fits, and gives the width it needs
        object.__setattr__(self, "address_width", ukf_map(self).address_width)

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
    def M(self) -> int:
        """Length of the augmented state (eq. 3)."""
        return self.n + self.nw + self.nv

    @property
    def N(self) -> int:
        """Number of sigma points of the spherical simplex set (M + 2)."""
        return self.M + 2

    @property
    def models(self):
        """The application's traced f and h (:class:`~kfgen.hdl.ukf.models.UkfModels`), for
        an ``on_chip`` core; ``None`` otherwise."""
        if not self.on_chip:
            return None
        return compile_models(self.app, (self.n, self.nw, self.nv, self.m))

    @property
    def nu(self) -> int:
        """Length of the control input u (0 without one, and for a core without ``on_chip``)."""
        return self.models.nu if self.on_chip else 0

    @property
    def fmt(self) -> FloatFormat:
        """:attr:`format` itself (the name the engine's modules read it by)."""
        return self.format

    def to_dict(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self)}
