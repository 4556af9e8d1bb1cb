"""One IEEE-754 unit as a core (``kfgen fpu``), as the command line, manifest, ``make verilog``
and ``make bench`` see it."""

from __future__ import annotations

from ...describe import CoreDescriptor, Doc
from .params import CLOCK_MHZ, OPS, FpuParams, ranges_text, stages_range

__all__ = ["CORE"]


def _trig_latency(op: str, fmt: str = "binary32") -> int:
    return stages_range(op, fmt)[0]


def _docs() -> dict[str, Doc]:
    return {
        "op": Doc("operation: a+b, a-b, a*b, a/b, sqrt(a), a*b+c with one rounding, int32 to float, "
                  "float to int32 (round to nearest even, saturating), e**a, sin(a), cos(a), atan2(a, b) "
                  "(a is y, b is x; the last four faithfully rounded; sin, cos and atan2 iterative: "
                  "one operation per latency, with i_ready)", "",
                  "one of " + ", ".join(OPS) + " (any case)"),
        "format": Doc("floating-point format", "",
                      "binary16, bfloat16, binary32, binary64, or eEmM with E exponent bits (3..15) "
                      "and M stored fraction bits (2..64), e.g. e6m11 (any case; an eEmM that is a "
                      "named format is recorded by its name: e8m23 is binary32)"),
        "subnormals": Doc("ieee: gradual underflow; ftz: subnormal inputs and results flushed to zero "
                          "(smaller, as vendor IP)", "", "ieee or ftz (any case)"),
        "stages": Doc("pipeline register stages = latency; the default is designed for "
                      f"{CLOCK_MHZ} MHz on an ECP5-85 in binary32 (iterative div/sqrt: the "
                      "recurrence's block sets the clock, slower the fewer cycles_per_op)", "cycles",
                      "an integer in a range that depends on op, format, subnormals and cycles_per_op; "
                      f"in binary32: {ranges_text('stages')}; sin, cos and atan2 take only their "
                      "latency (binary32: sin/cos " + str(_trig_latency('sin')) + ", atan2 "
                      + str(_trig_latency('atan2')) + ")"),
        "cycles_per_op": Doc("div and sqrt: cycles per operation; 1 fully pipelined, K > 1 iterative "
                             "and smaller, with i_ready backpressure", "cycles",
                             "an integer in a range that depends on op and format; in binary32: "
                             f"{ranges_text('cycles_per_op')}; 1 for other ops"),
        "target_mhz": Doc("pipeline for this clock on an ECP5-85 (nextpnr): the fewest stages the "
                          "calibrated delay model predicts to reach it (the manifest's timing records "
                          "the prediction); default: --stages' own default", "MHz",
                          "a number in 10..1000; not for sin, cos and atan2"),
        "name": Doc("top-level module and file name", "",
                    "a Verilog identifier, not a Verilog/SystemVerilog keyword nor a port name"),
    }


CORE = CoreDescriptor(
    name="fpu",
    summary="one IEEE-754 floating-point unit (add, sub, mul, div, sqrt, fma, i2f, f2i, exp, sin, cos, atan2) in any format",
    params=FpuParams,
    docs=_docs,
    build=lambda p: p.build(),
    fields_of=lambda p, port: p.field_list(port),
    extra=lambda p, component: {"timing": p.timing} if p.target_mhz is not None else {},
    examples=tuple({"op": op, "name": f"fpu_{op}"} for op in OPS),
)
