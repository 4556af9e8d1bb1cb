"""The IMM core as kfgen's command line, manifest, ``make verilog`` and ``make bench`` see it."""

from __future__ import annotations

from ..describe import CoreDescriptor, Doc
from ..engine.params import GEN_CROSSBAR_MAX, GEN_PES_MAX, WORK_RULE
from ..engine.descriptor import engine_docs, engine_manifest, engine_timing, engine_waivers, program_units
from ..linalg.schedule import chain_bound
from .core import Imm
from .params import D_MAX, MODELS_MAX, PES_MAX, STATES_MAX, ImmParams
from .regmap import CYCLES
from .steps import programs

__all__ = ["CORE"]


def _docs() -> dict[str, Doc]:
    return {
        "models": Doc("models R: filters mixed by the IMM, each with its own F, Q, H, R", "",
                      f"an integer in 2..{MODELS_MAX}"),
        "states": Doc("states n of every model", "", f"an integer in 1..{STATES_MAX}; with R, d and P: {WORK_RULE}"),
        "measurements": Doc("measurements d: the length of z (S^-1 by Schur complements)", "",
                            f"an integer in 1..{D_MAX}"),
        "pes": Doc("processing elements P (FMAs working in parallel)", "",
                   f"an integer in 1..{GEN_PES_MAX} with P x banks <= {GEN_CROSSBAR_MAX} (P <= 8 with the "
                   "default banks): the most that generates in 60 s and 2 GB; see --states for the sizes' limit"),
        "div_sqrt": Doc("the shared divider and square root: iterative (one result bit a cycle, about half "
                        "their area) or pipelined (one operation a cycle); by default iterative at P = 1, "
                        "pipelined above", "", "iterative or pipelined (any case)"),
        "banks": Doc("dual-port banks of the operand memory; by default 2P", "", f"an integer in 2..{2 * PES_MAX}"),
        **engine_docs(),
    }


def _extra(params, core) -> dict:
    sched = core.schedules["iterate"]
    mc = sched.machine
    return {
        **engine_manifest(core),
        **engine_timing(params, core),
        "cycles_keys": dict(CYCLES),
        "sizes": {"R": params.R, "n": params.n, "d": params.d},
        "bounds": {"fma": sched.program.fma_count, "fma_per_pe": -(-sched.program.fma_count // mc.pes),
                   "chain": chain_bound(sched.program, mc)},
    }


def _waivers(params) -> str:
    return engine_waivers(params, program_units(programs(params).steps.values()))


CORE = CoreDescriptor(
    name="imm",
    summary="interacting multiple model filter (R Kalman filters, mixing and combination) on P float PEs "
            "behind an AXI4 slave",
    params=ImmParams,
    docs=_docs,
    build=Imm,
    fields_of=lambda p, port: None,
    extra=_extra,
    examples=({},),
    waivers=_waivers,
)
