"""The UKF IP core as kfgen's command line, manifest, ``make verilog`` and ``make bench`` see it."""

from __future__ import annotations

from ..describe import CoreDescriptor, Doc
from ..engine.params import GEN_CROSSBAR_MAX, GEN_PES_MAX, WORK_RULE
from ..engine.app import load_app
from ..engine.descriptor import (engine_docs, engine_manifest, engine_streams, engine_timing, engine_waivers,
                                 program_units)
from .core import Ukf
from .params import FLOOR_REASON, SIZE_MAX, UkfParams
from .regmap import steps
from .steps import programs

__all__ = ["CORE"]


def _docs() -> dict[str, Doc]:
    size = f"an integer in 1..{SIZE_MAX}"
    return {
        "states": Doc("states n: the length of x", "", f"{size}; with m, nw, nv and P: {WORK_RULE}"),
        "observations": Doc("observations m: the length of z", "", size),
        "process_noise": Doc("process-noise terms nw: Q is nw x nw, and f takes them with x", "", size),
        "measurement_noise": Doc("measurement-noise terms nv: R is nv x nv, and h takes them", "", size),
        "pes": Doc("processing elements P (FMAs working in parallel)", "", "an integer in 1..M, M = n + nw + nv, "
                   f"at most {GEN_PES_MAX} with P x banks <= {GEN_CROSSBAR_MAX} (the most that "
                   "generates in 60 s and 2 GB); see --states for the sizes' limit"),
        "div_sqrt": Doc("the shared divider and square root: iterative (one result bit a cycle, about half "
                        "their area; sig_gen takes longer) or pipelined (one operation a cycle); by default "
                        "iterative at P = 1, pipelined above", "", "iterative or pipelined (any case)"),
        "banks": Doc("dual-port banks of the operand memory: more banks, fewer port conflicts and a larger "
                     "crossbar; by default 2P up to P = 2, P from 3 to 8, 8 above", "", "an integer in 2..2M"),
        "format": Doc(engine_docs()["format"].meaning, "", f"{engine_docs()['format'].allowed}; {FLOOR_REASON}"),
        "w0": Doc("weight W0 of the centre sigma point (eq. 5)", "", "a number with 0 <= W0 < 1"),
        "form": Doc("the covariance's form: ldl, the chapter's (P in the buffer, factored by LDL^T every sig_gen), "
                    "or sqrt, the square-root form (a Cholesky factor S of P = S S^T in region sqrtP, updated by "
                    "Householder triangularisation: stays positive definite where ldl's P cancels to indefinite; "
                    "docs/ukf.md)", "", "ldl (the default) or sqrt, any case"),
        "app": Doc("the application the core is sized for (its n, m, nw, nv and W0) and, on an on_chip core, the one "
                   "whose f and h are compiled into it", "", "MODULE:CLASS or FILE.py:CLASS of a "
                   "kfgen.hdl.engine.app.UkfApplication subclass (kfgen.sim.ukf.app re-exports it)"),
        "on_chip": Doc("compile the application's f and h into the engine: one start (CTRL.step = iteration) "
                       "runs the whole iteration, reading z and u (docs/applications.md says what traces)", "",
                       "a switch; needs --app"),
        "streams": Doc("AXI4-Stream ports beside the AXI4 slave for a design without a processor: s_axis takes "
                       "one measurement (z, then u) a transfer, m_axis gives x and the diagonal of P", "",
                       "a switch; needs --on-chip"),
        **{k: v for k, v in engine_docs().items() if k != "format"},
    }


def _extra(params, core) -> dict:
    return {
        **engine_manifest(core),
        **engine_timing(params, core),
        **engine_streams(core, "iteration"),
        "cycles_keys": {v.name: f"one {v.name} step (CTRL.start with CTRL.step = {v.value}): {v.desc}"
                        for v in steps(params)},
        "sizes": {"n": params.n, "m": params.m, "nw": params.nw, "nv": params.nv, "M": params.M,
                  "N": params.N},
    }


def _app(spec) -> dict:
    """The parameters the application ``spec`` fixes (its sizes and W0)."""
    return load_app(spec).core_parameters()


def _waivers(params) -> str:
    return engine_waivers(params, program_units(programs(params).steps.values()))


CORE = CoreDescriptor(
    name="ukf",
    summary="unscented Kalman filter (augmented, spherical simplex) on P float PEs behind an AXI4 slave",
    params=UkfParams,
    docs=_docs,
    build=Ukf,
    fields_of=lambda p, port: None,
    extra=_extra,
    examples=({},),
    waivers=_waivers,
    app=_app,
)
