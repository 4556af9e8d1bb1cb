"""The Castella tracker as kfgen's command line, manifest, ``make verilog`` and ``make bench`` see it."""

from __future__ import annotations

from ..describe import CoreDescriptor, Doc
from .core import Castella
from .params import ALPHA_FRAC, CONST_BITS, Q2_MAX, RANGES, Z_FRAC, Z_MAX, CastellaParams

__all__ = ["CORE"]

_FIELD_PORTS = ("s_axis_tdata", "s_axis_tuser", "m_axis_tdata", "m_axis_tuser")


def _docs() -> dict[str, Doc]:
    def rng(key):
        lo, hi = RANGES[key]
        return f"integer {lo}..{hi}" if isinstance(lo, int) else f"{lo} to {hi}"

    step = f"2**-{Z_FRAC}"
    return {
        "tracks": Doc("independent tracks held in state memory, selected by s_axis_tid", "", rng("tracks")),
        "data_width": Doc("width of the range, velocity and covariance words", "bits", rng("data_width")),
        "gain_width": Doc("width of the Kalman gains K1 and K2", "bits", rng("gain_width")),
        "q_width": Doc("width of the q code: 2**q_width levels on the line from q1 to q2", "bits",
                       rng("q_width")),
        "period": Doc("measurement period T of each track", "s",
                      f"{rng('period')}; T, 2T, T^2 and 1/T are built to {CONST_BITS} significant bits "
                      "(the manifest's built_constants)"),
        "sigma_r": Doc("standard deviation of the range measurement noise", "m",
                       f"{rng('sigma_r')}; sigma_r^2 is built in the P11 format (the manifest's built_constants)"),
        "alpha": Doc("pole alpha_R of the single-pole filter on the normalised residual, eq. (8)", "",
                     f"open interval (0, 1); built as the nearest multiple of 2**-{ALPHA_FRAC}, "
                     "which the header and manifest record"),
        "q1": Doc("manoeuvre noise spectral density while the filtered residual is below z1", "m^2/s^3",
                  "0 < q1 < q2"),
        "q2": Doc("manoeuvre noise spectral density once the filtered residual reaches z2", "m^2/s^3",
                  f"greater than q1, at most {Q2_MAX:g}"),
        "z1": Doc("filtered normalised residual above which q rises from q1 (manoeuvre flagged)", "sigma",
                  f"0 < z1 < z2; built as the nearest multiple of {step}, which the header and manifest record"),
        "z2": Doc("filtered normalised residual at which q reaches q2", "sigma",
                  f"z1 < z2 <= {Z_MAX}, at least {step} above z1; built as the nearest multiple of {step}"),
        "multipliers": Doc("how the gain and residual products are built: lut, shift-and-add trees in LUTs "
                           "(fast on ECP5, whose DSP blocks Yosys maps without their registers); dsp, products "
                           "that a Xilinx 7 series DSP48E1 takes with its registers (fewer LUTs); bit-exact and "
                           "the same latency either way", "", "lut or dsp (any case)"),
        "name": Doc("top-level module and file name; every module in the Verilog is prefixed by it", "",
                    "a Verilog identifier, not a Verilog/SystemVerilog keyword nor a port name"),
    }


CORE = CoreDescriptor(
    name="castella",
    summary="adaptive two-state (range, velocity) tracker with manoeuvre detection, many tracks",
    params=CastellaParams,
    docs=_docs,
    build=Castella,
    fields_of=lambda p, port: p.field_list(port) if port in _FIELD_PORTS else None,
    extra=lambda p, c: {"track_interval_cycles": c.track_interval,
                        "sustained_measurements_per_cycle": round(c.sustained_rate, 6),
                        "built_constants": p.built_constants},
    examples=({}, {"tracks": 8, "name": "castella8"}),
)
