"""Parameters of the standalone ``kfgen fpu`` core: which unit, which format, how pipelined.

Pure Python apart from :meth:`FpuParams.build`, which imports the chosen unit.
"""

from __future__ import annotations

from dataclasses import dataclass

from ...describe import ParamError, check_name
from .format import FLAG_NAMES, FloatFormat

__all__ = ["FpuParams", "OPS"]

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
}
MAX_CYCLES_PER_OP = 64


@dataclass(frozen=True)
class FpuParams:
    """Generation parameters of one floating-point unit as a core.

    Parameters
    ----------
    op : str
        ``add``, ``sub``, ``mul``, ``div``, ``sqrt``, ``fma``, ``i2f`` or ``f2i``.
    format : str
        ``binary16``, ``bfloat16``, ``binary32``, ``binary64`` or ``eEmM``.
    subnormals : str
        ``ieee`` (gradual underflow) or ``ftz`` (flush subnormal inputs and results to zero).
    stages : int or None
        Register stages (the latency in cycles); ``None`` picks the unit's default, and is
        replaced by that number, so the parameters record what was built.
    cycles_per_op : int
        div and sqrt only: 1 = fully pipelined, K > 1 = iterative, one operation per K cycles.
    name : str
        Top-level module name.
    """

    op: str = "add"
    format: str = "binary32"
    subnormals: str = "ieee"
    stages: int | None = None
    cycles_per_op: int = 1
    name: str = "fpu"

    def __post_init__(self):
        if self.op not in OPS:
            raise ParamError("op", f"must be one of {', '.join(OPS)}, not {self.op!r}")
        try:
            FloatFormat.parse(self.format)
        except ValueError as exc:
            raise ParamError("format", f"must be binary16, bfloat16, binary32, binary64 or eEmM "
                                          f"(exponent 3..15 bits, fraction 2..64 bits): {exc}") from None
        if self.subnormals not in ("ieee", "ftz"):
            raise ParamError("subnormals", f"must be ieee or ftz, not {self.subnormals!r}")
        for key in ("stages", "cycles_per_op"):
            v = getattr(self, key)
            if (isinstance(v, bool) or not isinstance(v, int)) and not (key == "stages" and v is None):
                raise ParamError(key, f"must be an integer, not {v!r}")
        if self.stages is not None and self.stages < 1:
            # a core has a clock: at least its output is registered
            raise ParamError("stages", f"must be at least 1 for a generated core, not {self.stages!r}")
        if not 1 <= self.cycles_per_op <= MAX_CYCLES_PER_OP:
            raise ParamError("cycles_per_op", f"must be in 1..{MAX_CYCLES_PER_OP}, not {self.cycles_per_op!r}")
        if self.cycles_per_op != 1 and not OPS[self.op][2]:
            raise ParamError("cycles_per_op", f"applies to div and sqrt only; {self.op} takes one "
                                                 "operation per clock (leave it at 1)")
        check_name(self.name)
        try:
            unit = self.build()
        except ValueError as exc:  # the unit's own check, e.g. a stage count it cannot place
            key = "cycles_per_op" if "cycles_per_op" in str(exc) else "stages"
            raise ParamError(key, str(exc)) from None
        object.__setattr__(self, "stages", unit.stages)

    @property
    def fmt(self) -> FloatFormat:
        return FloatFormat.parse(self.format)

    def build(self):
        """The Amaranth unit for these parameters."""
        from .add import FloatAdd, FloatSub
        from .div import FloatDiv
        from .f2i import FloatToInt
        from .fma import FloatFMA
        from .i2f import IntToFloat
        from .mul import FloatMul
        from .sqrt import FloatSqrt
        kw = {"subnormals": self.subnormals, "stages": self.stages}
        cls = {"add": FloatAdd, "sub": FloatSub, "mul": FloatMul, "div": FloatDiv, "sqrt": FloatSqrt,
               "fma": FloatFMA, "i2f": IntToFloat, "f2i": FloatToInt}[self.op]
        if OPS[self.op][2]:
            kw["cycles_per_op"] = self.cycles_per_op
        unit = cls(self.fmt, **kw)
        unit._MustUse__silence = True  # validation builds one without elaborating it
        return unit

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
