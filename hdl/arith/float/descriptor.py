"""One IEEE-754 unit as a core (``kfgen fpu``), as the command line, manifest, ``make verilog``
and ``make bench`` see it."""

from __future__ import annotations

from ...describe import CoreDescriptor, Doc
from .params import MAX_CYCLES_PER_OP, OPS, FpuParams

__all__ = ["CORE"]


def _docs() -> dict[str, Doc]:
    return {
        "op": Doc("operation: a+b, a-b, a*b, a/b, sqrt(a), a*b+c with one rounding, int32 to float, "
                  "float to int32 (round to nearest even, saturating)", "", "one of " + ", ".join(OPS)),
        "format": Doc("floating-point format", "",
                      "binary16, bfloat16, binary32, binary64, or eEmM with E exponent bits (3..15) "
                      "and M stored fraction bits (2..64), e.g. e6m11"),
        "subnormals": Doc("ieee: gradual underflow; ftz: subnormal inputs and results flushed to zero "
                          "(smaller, as vendor IP)", "", "ieee or ftz"),
        "stages": Doc("pipeline register stages = latency", "cycles",
                      "a count the unit can place (its error names the range); the unit's default "
                      "meets 100 MHz on ECP5 for binary32 (iterative div/sqrt: slower the fewer cycles_per_op)"),
        "cycles_per_op": Doc("div and sqrt: cycles per operation; 1 fully pipelined, K > 1 iterative "
                             "and smaller, with i_ready backpressure", "cycles",
                             f"integer 1..{MAX_CYCLES_PER_OP}; 1 for other ops"),
        "name": Doc("top-level module and file name", "",
                    "a Verilog identifier, not a Verilog/SystemVerilog keyword nor a port name"),
    }


CORE = CoreDescriptor(
    name="fpu",
    summary="one IEEE-754 floating-point unit (add, sub, mul, div, sqrt, fma, i2f, f2i) in any format",
    params=FpuParams,
    docs=_docs,
    build=lambda p: p.build(),
    fields_of=lambda p, port: p.field_list(port),
    examples=tuple({"op": op, "name": f"fpu_{op}"} for op in OPS),
    bench="kfgen.gen.bench_fpu",
)
