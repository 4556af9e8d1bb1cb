"""Parameters of the Schur-complement inversion unit (``kfgen schur``), validated once.

The latencies are the slides' trade-study columns (multiplier latency, addition latency,
divider cycles per operation, divider latency), and each is a floating-point unit's own count:
``stages`` of :class:`~kfgen.hdl.arith.float.mul.FloatMul`, of
:class:`~kfgen.hdl.arith.float.add.FloatAdd` and ``FloatSub``, and ``cycles_per_op`` and
``stages`` of :class:`~kfgen.hdl.arith.float.div.FloatDiv`. Their ranges are the units' own
(:func:`~kfgen.hdl.arith.float.params.stages_range`,
:func:`~kfgen.hdl.arith.float.params.cycles_per_op_range`), quoted by every error.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ..arith.float.format import FloatFormat
from ..arith.float.params import (OMIT_NONE, FpuParams, check_target, core_timing, cycles_per_op_range, stages_range,
                                  unit_timing)
from ..describe import ParamError, check_name
from .program import SIZE_MAX

__all__ = ["SchurParams", "SIZE_MAX"]


def _in_range(value, lo: int, hi: int) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and lo <= value <= hi


@dataclass(frozen=True)
class SchurParams:
    """Generation parameters of the Schur-complement unit.

    Parameters
    ----------
    size : int
        ``d``: the matrices are ``d x d``, 1..:data:`SIZE_MAX` (2 by default).
    format : str
        Float format of every word: ``binary16``, ``bfloat16``, ``binary32``, ``binary64`` or
        ``eEmM``; replaced by its canonical name.
    mul_latency : int or None
        The multipliers' stages, in ``stages_range("mul", format)``.
    add_latency : int or None
        The adders' and subtracters' stages, in ``stages_range("add", format)``.
    div_cycles_per_op : int
        The dividers' cycles per operation, in ``cycles_per_op_range("div", format)``: 1 fully
        pipelined (one matrix a clock), K > 1 iterative (one matrix every K clocks).
    div_latency : int or None
        The dividers' stages, in ``stages_range("div", format, "ieee", div_cycles_per_op)``.
    name : str
        Top-level module name.

    target_mhz : float or None
        A clock in MHz (ECP5-85, nextpnr): each latency left ``None`` becomes the fewest stages
        the calibrated delay model predicts to reach it (:func:`~kfgen.hdl.arith.float.params.unit_timing`);
        the manifest's ``timing`` records the predictions. ``None``: the units' defaults.

    A latency left ``None`` is the unit's default (designed for 100 MHz on an ECP5-85 in
    binary32), or the target's choice, and replaced by that number, so the parameters record
    what was built.

    Raises
    ------
    ParamError
        Naming the first bad parameter; a count out of its range says ``must be an integer in
        LO..HI for <op> <format>``.
    """

    size: int = 2
    format: str = "binary32"
    mul_latency: int | None = None
    add_latency: int | None = None
    div_cycles_per_op: int = 1
    div_latency: int | None = None
    target_mhz: float | None = field(default=None, metadata=OMIT_NONE)
    name: str = "schur"

    def __post_init__(self):
        if not _in_range(self.size, 1, SIZE_MAX):
            raise ParamError("size", f"must be an integer in 1..{SIZE_MAX} (d x d matrices), not {self.size!r}")
        try:
            fmt = FloatFormat.parse(self.format).name
        except ValueError as exc:
            raise ParamError("format", f"must be binary16, bfloat16, binary32, binary64 or eEmM "
                                       f"(exponent 3..15 bits, fraction 2..64 bits): {exc}") from None
        object.__setattr__(self, "format", fmt)
        lo, hi = cycles_per_op_range("div", fmt)
        if not _in_range(self.div_cycles_per_op, lo, hi):
            raise ParamError("div_cycles_per_op", f"must be an integer in {lo}..{hi} for div {fmt}, "
                                                  f"not {self.div_cycles_per_op!r}")
        k = self.div_cycles_per_op
        target = check_target(self.target_mhz)
        object.__setattr__(self, "target_mhz", target)
        for key, op, cpo in (("mul_latency", "mul", 1), ("add_latency", "add", 1), ("div_latency", "div", k)):
            value = getattr(self, key)
            lo, hi = stages_range(op, fmt, "ieee", cpo)
            if value is not None and not _in_range(value, lo, hi):
                what = f"{op} {fmt}" + (f", cycles_per_op {cpo}" if cpo > 1 else "")
                raise ParamError(key, f"must be an integer in {lo}..{hi} for {what}, not {value!r}")
            if value is None and target is not None:  # a latency given stays; the rest follow the target
                value = unit_timing(op, fmt, "ieee", cpo, target)[0]
            built = FpuParams(op=op, format=fmt, stages=value, cycles_per_op=cpo).stages
            object.__setattr__(self, key, built)
        check_name(self.name)

    @property
    def timing(self) -> dict:
        """The manifest's ``timing`` (only with a target): the target, each unit's stages and
        predicted Fmax by the calibrated model (:mod:`kfgen.hdl.arith.float.timing`), and the
        core's prediction, its slowest unit's."""
        units = {op: (op, cpo, self.latencies[op]) for op, cpo in (("mul", 1), ("add", 1),
                                                                    ("div", self.div_cycles_per_op))}
        return core_timing(self.target_mhz, self.format, units,
                           model="ECP5-85, nextpnr (kfgen.hdl.arith.float.timing); the control is not modelled")

    @property
    def fmt(self) -> FloatFormat:
        return FloatFormat.parse(self.format)

    @property
    def d(self) -> int:
        return self.size

    @property
    def latencies(self) -> dict[str, int]:
        """Stages of each kind of unit, as :func:`~kfgen.hdl.schur.program.schedule` takes them."""
        return {"mul": self.mul_latency, "add": self.add_latency, "sub": self.add_latency,
                "div": self.div_latency}
