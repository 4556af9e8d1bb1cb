# amaranth: UnusedElaboratable=no
# (A unit :meth:`FpuParams.build` makes for a caller that only reads its attributes is never
# elaborated: Amaranth's public linter option, for what this file creates only.)
"""Parameters of the standalone ``kfgen fpu`` core: which unit, which format, how pipelined.

The ranges of the counts are read from the units themselves (:func:`stages_range`,
:func:`cycles_per_op_range`), so validation, ``kfgen fpu --help`` and the README (which quotes
:func:`ranges_text` and :data:`CLOCK_MHZ`) cannot drift from what the units build.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ...describe import ParamError, check_name
from .add import FloatAdd, FloatSub
from .div import FloatDiv
from .exp import FloatExp
from .f2i import FloatToInt
from .fma import FloatFMA
from .format import FLAG_NAMES, FloatFormat
from .i2f import IntToFloat
from .mul import FloatMul
from .sqrt import FloatSqrt
from .timing import CLOCK_MHZ, MEASURED_MHZ, TARGET_RANGE, predicted_mhz, stages_for_target
from .trig import FloatAtan2, FloatCos, FloatSin

__all__ = ["FpuParams", "OPS", "CLOCK_MHZ", "cycles_per_op_range", "stages_range",
           "ranges_text", "check_target", "unit_timing", "core_timing", "OMIT_NONE"]

#: A parameter that a generated core's header, manifest and command line leave out while it
#: is ``None`` (so that adding it changed no core generated without it).
OMIT_NONE = {"omit_none": True}


def check_target(value) -> float | None:
    """``--target-mhz``: ``None``, or a number in :data:`TARGET_RANGE` (returned as a float)."""
    if value is None:
        return None
    lo, hi = TARGET_RANGE
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not lo <= value <= hi:
        raise ParamError("target_mhz", f"must be a clock in MHz, a number in {lo:g}..{hi:g}, not {value!r}")
    return float(value)


def unit_timing(op: str, fmt, subnormals: str = "ieee", cycles_per_op: int = 1,
                target_mhz: float | None = None, stages: int | None = None) -> tuple[int | None, float | None]:
    """``(stages, predicted Fmax in MHz)`` of a unit by the calibrated delay model
    (:mod:`.timing`): with ``target_mhz``, the fewest stages that reach it (or the most
    stages); otherwise for ``stages`` (``None``: the default). The prediction is ``None`` for
    an iterative sin, cos or atan2, whose measured clock :data:`~.timing.MEASURED_MHZ` gives."""
    cls = _unit_class(op)
    delays = cls.stage_delays(fmt, **_unit_args(op, subnormals, None, cycles_per_op))
    if delays is None:
        return stages, None
    if target_mhz is not None:
        return stages_for_target(op, delays, target_mhz)
    if stages is None:
        stages = cls.plan(fmt, **_unit_args(op, subnormals, None, cycles_per_op)).stages
    return stages, predicted_mhz(op, delays[stages])


def core_timing(target_mhz: float, fmt, units: dict, ceiling: float | None = None,
                model: str = "ECP5-85, nextpnr (kfgen.hdl.arith.float.timing)") -> dict:
    """The manifest's ``timing`` of a core built of units: ``units`` maps a name to ``(op,
    cycles_per_op, stages)``; each unit's stages and predicted Fmax, and the core's prediction,
    its slowest unit's (at most ``ceiling``, the clock of the core's own paths)."""
    shown = {}
    for name, (op, cpo, stages) in units.items():
        shown[name] = {"stages": stages,
                       "predicted_fmax_mhz": round(unit_timing(op, fmt, "ieee", cpo, stages=stages)[1], 1)}
    predicted = min([u["predicted_fmax_mhz"] for u in shown.values()] + ([ceiling] if ceiling else []))
    return {"target_mhz": target_mhz, "predicted_fmax_mhz": predicted, "met": predicted >= target_mhz,
            "units": shown, "model": model}


#: op -> (operand ports, result is an integer, has cycles_per_op)
OPS = {
    "add": (("i_a", "i_b"), False, False),
    "sub": (("i_a", "i_b"), False, False),
    "mul": (("i_a", "i_b"), False, False),
    "div": (("i_a", "i_b"), False, True),
    "sqrt": (("i_a",), False, True),
    "fma": (("i_a", "i_b", "i_c"), False, False),
    "i2f": (("i_a",), False, False),
    "f2i": (("i_a",), True, False),
    "exp": (("i_a",), False, False),
    "sin": (("i_a",), False, False),
    "cos": (("i_a",), False, False),
    "atan2": (("i_a", "i_b"), False, False),
}


def _unit_class(op: str):
    return {"add": FloatAdd, "sub": FloatSub, "mul": FloatMul, "div": FloatDiv, "sqrt": FloatSqrt,
            "fma": FloatFMA, "i2f": IntToFloat, "f2i": FloatToInt, "exp": FloatExp,
            "sin": FloatSin, "cos": FloatCos, "atan2": FloatAtan2}[op]


def _unit_args(op: str, subnormals: str, stages: int | None, cycles_per_op: int) -> dict:
    """The unit constructor's keyword arguments (``cycles_per_op`` for div and sqrt only)."""
    return {"subnormals": subnormals, "stages": stages, **({"cycles_per_op": cycles_per_op} if OPS[op][2] else {})}


def cycles_per_op_range(op: str, fmt) -> tuple[int, int]:
    """``(lo, hi)``, the cycles per operation a core of ``op`` in ``fmt`` accepts: for div and
    sqrt 1 to the recurrence's steps (one step a cycle), for the others 1."""
    if not OPS[op][2]:
        return 1, 1
    return 1, _unit_class(op).iterations(FloatFormat.parse(fmt))


def stages_range(op: str, fmt, subnormals: str = "ieee", cycles_per_op: int = 1) -> tuple[int, int]:
    """``(lo, hi)``, the register stages a core of ``op`` in ``fmt`` accepts: those the unit
    can place, except none (a core has a clock: at least its output is registered)."""
    plans = _unit_class(op).plan(fmt, **_unit_args(op, subnormals, None, cycles_per_op)).plans
    return max(1, min(plans)), max(plans)


def ranges_text(param: str, fmt="binary32") -> str:
    """``"add 1..8, sub 1..8, ..."``: the range of ``param`` (``"stages"``, pipelined and ieee,
    or ``"cycles_per_op"``) for each op in ``fmt`` that has more than one value, as the help
    and the README quote it."""
    ranges = {op: stages_range(op, fmt) if param == "stages" else cycles_per_op_range(op, fmt)
              for op in OPS}
    return ", ".join(f"{op} {lo}..{hi}" for op, (lo, hi) in ranges.items() if hi > lo)


def _canonical(value):
    """Case and surrounding spaces do not matter in a name."""
    return value.strip().lower() if isinstance(value, str) else value


def _in_range(value, lo: int, hi: int) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and lo <= value <= hi


@dataclass(frozen=True)
class FpuParams:
    """Generation parameters of one floating-point unit as a core.

    Names are read whatever their case (``--op MUL --format E8M23``) and recorded in their
    canonical spelling: lowercase, and a format by its standard name when it has one (``e8m23``
    is ``binary32``, ``e5m10`` ``binary16``, ``e11m52`` ``binary64``, ``e8m7`` ``bfloat16``),
    so every spelling of one core gives the same files.

    Parameters
    ----------
    op : str
        ``add``, ``sub``, ``mul``, ``div``, ``sqrt``, ``fma``, ``i2f``, ``f2i``, ``exp``, ``sin``,
        ``cos`` or ``atan2`` (``atan2(a, b)``: ``a`` is ``y``, ``b`` is ``x``).
    format : str
        ``binary16``, ``bfloat16``, ``binary32``, ``binary64`` or ``eEmM``.
    subnormals : str
        ``ieee`` (gradual underflow) or ``ftz`` (flush subnormal inputs and results to zero).
    stages : int or None
        Register stages (the latency in cycles), in :func:`stages_range`; ``None`` picks the
        unit's default, designed for :data:`CLOCK_MHZ` MHz on an ECP5-85 in binary32, and is
        replaced by that number, so the parameters record what was built.
    cycles_per_op : int
        In :func:`cycles_per_op_range`: for div and sqrt, 1 = fully pipelined, K > 1 =
        iterative, one operation per K cycles; 1 for the others.
    target_mhz : float or None
        A clock in MHz (ECP5-85, nextpnr) to pipeline for: ``stages`` becomes the fewest the
        calibrated delay model (:mod:`.timing`) predicts to reach it, or the most stages
        when none does; the manifest records the target and the prediction. ``None`` (the
        default) keeps ``stages``' own default. Given both, ``stages`` must be the count the
        target picks (the recorded parameters regenerate the same core).
    name : str
        Top-level module name.

    Raises
    ------
    ParamError
        On a bad value; a count out of its range says ``must be an integer in LO..HI for
        <op> <format>``.
    """

    op: str = "add"
    format: str = "binary32"
    subnormals: str = "ieee"
    stages: int | None = None
    cycles_per_op: int = 1
    target_mhz: float | None = field(default=None, metadata=OMIT_NONE)
    name: str = "fpu"

    def __post_init__(self):
        op, subnormals = _canonical(self.op), _canonical(self.subnormals)
        if op not in OPS:
            raise ParamError("op", f"must be one of {', '.join(OPS)}, not {self.op!r}")
        try:
            fmt = FloatFormat.parse(self.format).name
        except ValueError as exc:
            raise ParamError("format", f"must be binary16, bfloat16, binary32, binary64 or eEmM "
                                          f"(exponent 3..15 bits, fraction 2..64 bits): {exc}") from None
        if subnormals not in ("ieee", "ftz"):
            raise ParamError("subnormals", f"must be ieee or ftz, not {self.subnormals!r}")
        for key, value in (("op", op), ("format", fmt), ("subnormals", subnormals)):
            object.__setattr__(self, key, value)

        lo, hi = cycles_per_op_range(op, fmt)
        if not _in_range(self.cycles_per_op, lo, hi):
            hint = "" if OPS[op][2] else ": only div and sqrt are iterative"
            raise ParamError("cycles_per_op", f"must be an integer in {lo}..{hi} for {op} {fmt}, "
                                                 f"not {self.cycles_per_op!r}{hint}")
        try:
            lo, hi = stages_range(op, fmt, subnormals, self.cycles_per_op)
        except ValueError as exc:  # a format the unit cannot take (sin, cos, atan2)
            raise ParamError("format", str(exc)) from None
        if self.stages is not None and not _in_range(self.stages, lo, hi):
            what = f"{op} {fmt}" + (", ftz" if subnormals == "ftz" else "") \
                + (f", cycles_per_op {self.cycles_per_op}" if self.cycles_per_op > 1 else "")
            raise ParamError("stages", f"must be an integer in {lo}..{hi} for {what}, not {self.stages!r}")
        target = check_target(self.target_mhz)
        object.__setattr__(self, "target_mhz", target)
        if target is not None and op in MEASURED_MHZ:
            raise ParamError("target_mhz", f"{op} has one pipeline, whose step control sets its clock "
                                           f"(measured {MEASURED_MHZ[op]:g} MHz in binary32): it takes no target")
        if target is not None:
            picked, _ = unit_timing(op, fmt, subnormals, self.cycles_per_op, target)
            if self.stages is not None and self.stages != picked:
                raise ParamError("stages", f"{self.stages} is not the {picked} stages target_mhz {target:g} picks; "
                                           "give one of the two")
            object.__setattr__(self, "stages", picked)
        check_name(self.name)
        args = _unit_args(op, subnormals, self.stages, self.cycles_per_op)
        object.__setattr__(self, "stages", _unit_class(op).plan(fmt, **args).stages)

    @property
    def fmt(self) -> FloatFormat:
        return FloatFormat.parse(self.format)

    @property
    def timing(self) -> dict:
        """The manifest's ``timing``: the target and the model's prediction (only with a target)."""
        _, mhz = unit_timing(self.op, self.format, self.subnormals, self.cycles_per_op, stages=self.stages)
        return {"target_mhz": self.target_mhz, "predicted_fmax_mhz": round(mhz, 1),
                "met": mhz >= self.target_mhz, "model": "ECP5-85, nextpnr (kfgen.hdl.arith.float.timing)"}

    def build(self):
        """The Amaranth unit for these parameters."""
        args = _unit_args(self.op, self.subnormals, self.stages, self.cycles_per_op)
        return _unit_class(self.op)(self.format, **args)

    def field_list(self, port: str):
        """Packed fields of a data port (manifest): floats carry ``format`` instead of ``frac_bits``."""
        fmt = self.fmt
        operands, int_result, _ = OPS[self.op]
        float_field = {"signed": True, "format": fmt.name, "unit": "",
                       "layout": f"sign[{fmt.width - 1}] exponent[{fmt.width - 2}:{fmt.frac_bits}] "
                                 f"fraction[{fmt.frac_bits - 1}:0], bias {fmt.bias}"}
        int_field = {"signed": True, "frac_bits": 0, "unit": ""}
        if port == "o_flags":
            return [{"name": n, "lsb": i, "width": 1, "signed": False, "frac_bits": 0, "unit": ""}
                    for i, n in enumerate(FLAG_NAMES)]
        if port == "o_y":
            return [{"name": "y", "lsb": 0, "width": 32, **int_field} if int_result
                    else {"name": "y", "lsb": 0, "width": fmt.width, **float_field}]
        if port in operands:
            name = port[2:]
            if self.op == "i2f":
                return [{"name": name, "lsb": 0, "width": 32, **int_field}]
            return [{"name": name, "lsb": 0, "width": fmt.width, **float_field}]
        return None
