"""The Schur-complement inversion unit as kfgen's command line, manifest, ``make verilog`` and
``make bench`` see it."""

from __future__ import annotations

from ..arith.float.format import FLAG_NAMES, FloatFormat
from ..arith.float.params import CLOCK_MHZ, ranges_text, stages_range
from ..describe import CoreDescriptor, Doc
from .core import Schur, matrix_layout, result_layout, status_layout
from .params import SIZE_MAX, SchurParams

__all__ = ["CORE"]


def _docs() -> dict[str, Doc]:
    return {
        "size": Doc("d: the matrices are d x d, symmetric positive definite; d > 2 by recursive 2 x 2 "
                    "blocks (odd d split as floor(d/2) and the rest)", "", f"an integer in 1..{SIZE_MAX}"),
        "format": Doc("floating-point format of every word", "",
                      "binary16, bfloat16, binary32, binary64, or eEmM with E exponent bits (3..15) and M "
                      "stored fraction bits (2..64) (any case)"),
        "mul_latency": Doc("multiplier latency: the stages of every FloatMul; the default is designed for "
                           f"{CLOCK_MHZ} MHz on an ECP5-85 in binary32", "cycles",
                           f"an integer in the unit's range for the format; in binary32: "
                           f"{_range('stages', 'mul')}"),
        "add_latency": Doc("addition latency: the stages of every FloatAdd and FloatSub", "cycles",
                           f"an integer in the unit's range for the format; in binary32: "
                           f"{_range('stages', 'add')}"),
        "div_cycles_per_op": Doc("divider cycles per operation: 1 pipelined (one matrix a clock), K > 1 "
                                 "iterative and smaller (one matrix every K clocks)", "cycles",
                                 f"an integer in the unit's range for the format; in binary32: "
                                 f"{_range('cycles_per_op', 'div')}"),
        "div_latency": Doc("divider latency: the stages of every FloatDiv", "cycles",
                           "an integer in a range that depends on the format and div_cycles_per_op; in "
                           f"binary32: {_div_latency_text()}"),
        "target_mhz": Doc("pipeline the units whose latency is not given for this clock on an ECP5-85 "
                          "(nextpnr): the fewest stages the calibrated delay model predicts to reach it "
                          "(the manifest's timing records the prediction); default: the units' own stages",
                          "MHz", "a number in 10..1000"),
        "name": Doc("top-level module and file name; every module in the Verilog is prefixed by it", "",
                    "a Verilog identifier, not a Verilog/SystemVerilog keyword nor a port name"),
    }


def _range(param: str, op: str) -> str:
    """``1..8``: the binary32 range of ``param`` for ``op``, from :func:`ranges_text`."""
    for part in ranges_text(param).split(", "):
        name, _, span = part.partition(" ")
        if name == op:
            return span
    raise KeyError(op)


def _div_latency_text() -> str:
    """``1..34 pipelined, K+1..K+8 iterative``, from :func:`stages_range` in binary32."""
    lo, hi = stages_range("div", "binary32")
    k = 2
    ilo, ihi = stages_range("div", "binary32", "ieee", k)
    return f"{lo}..{hi} pipelined, K+{ilo - k}..K+{ihi - k} iterative"


def _float_field(fmt: FloatFormat, name: str, lsb: int) -> dict:
    return {"name": name, "lsb": lsb, "width": fmt.width, "signed": True, "format": fmt.name, "unit": "",
            "layout": f"sign[{fmt.width - 1}] exponent[{fmt.width - 2}:{fmt.frac_bits}] "
                      f"fraction[{fmt.frac_bits - 1}:0], bias {fmt.bias}"}


def _fields(params: SchurParams, port: str):
    """Packed fields of the data ports, from the payload layouts (:mod:`.core`)."""
    fmt = params.fmt
    if port in ("s_axis_tdata", "m_axis_tdata"):
        layout = (matrix_layout if port == "s_axis_tdata" else result_layout)(fmt, params.d)
        return [_float_field(fmt, name, field.offset) for name, field in layout]
    if port == "m_axis_tuser":
        bit = {"signed": False, "frac_bits": 0, "unit": ""}
        out = []
        for name, field in status_layout():
            if name == "flags":
                out += [{"name": f, "lsb": field.offset + i, "width": 1, **bit} for i, f in enumerate(FLAG_NAMES)]
            else:
                out.append({"name": name, "lsb": field.offset, "width": 1, **bit})
        return out
    return None


def _extra(params: SchurParams, core) -> dict:
    prog = core.program
    return {
        "datapath_latency_cycles": core.datapath_latency,
        "fifo_depth": core.fifo_depth,
        "units": {op: prog.count(op) for op in ("mul", "add", "sub", "div")},
        "unit_latencies": {"mul": params.mul_latency, "add": params.add_latency, "sub": params.add_latency,
                           "div": params.div_latency, "div_cycles_per_op": params.div_cycles_per_op},
        **({"timing": params.timing} if params.target_mhz is not None else {}),
    }


CORE = CoreDescriptor(
    name="schur",
    summary="inverse and determinant of symmetric positive-definite d x d matrices by the Schur complement, "
            "streaming",
    params=SchurParams,
    docs=_docs,
    build=Schur,
    fields_of=_fields,
    extra=_extra,
    examples=({},),
)
