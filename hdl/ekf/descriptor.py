"""The EKF core as kfgen's command line, manifest, ``make verilog`` and ``make bench`` see it."""

from __future__ import annotations

from ..describe import CoreDescriptor, Doc
from ..engine.app import load_app
from ..engine.descriptor import engine_docs, engine_manifest, engine_streams, engine_timing, engine_waivers, \
    program_units
from ..engine.params import GEN_CROSSBAR_MAX, GEN_PES_MAX, WORK_RULE
from ..linalg.schedule import chain_bound
from .core import Ekf
from .params import SIZE_MAX, EkfParams, app_sizes
from .regmap import CYCLES
from .steps import programs

__all__ = ["CORE"]


def _docs() -> dict[str, Doc]:
    size = f"an integer in 1..{SIZE_MAX}, the application's (another value is refused)"
    return {
        "app": Doc("the application whose f and h, and their Jacobians by forward-mode differentiation, the core "
                   "runs (the UKF's application class: the same file generates a UKF or an EKF; docs/ekf.md says "
                   "what differentiates)", "", "MODULE:CLASS or FILE.py:CLASS of a "
                   "kfgen.hdl.engine.app.UkfApplication subclass; required"),
        "states": Doc("states n: the length of x", "", f"{size}; with m and P: {WORK_RULE}"),
        "observations": Doc("observations m: the length of z", "", size),
        "process_noise": Doc("process-noise terms nw: Q is nw x nw, and f takes them with x", "", size),
        "measurement_noise": Doc("measurement-noise terms nv: R is nv x nv, and h takes them", "", size),
        "inputs": Doc("control inputs nu: the length of u, f's third argument", "",
                      f"an integer in 0..{SIZE_MAX}, the application's"),
        "pes": Doc("processing elements P (FMAs working in parallel)", "",
                   f"an integer in 1..{GEN_PES_MAX} with P x banks <= {GEN_CROSSBAR_MAX} (the most that "
                   "generates in 60 s and 2 GB); see --states for the sizes' limit"),
        "div_sqrt": Doc("the shared divider and square root: iterative (one result bit a cycle, about half "
                        "their area) or pipelined (one operation a cycle); by default iterative at P = 1, "
                        "pipelined above", "", "iterative or pipelined (any case)"),
        "banks": Doc("dual-port banks of the operand memory; by default 2P", "", "an integer >= 2"),
        "format": engine_docs()["format"],
        "streams": Doc("AXI4-Stream ports beside the AXI4 slave for a design without a processor: s_axis takes "
                       "one measurement (z, then u) a transfer and runs an iteration, m_axis gives x and the "
                       "diagonal of P", "", "a switch"),
        **{k: v for k, v in engine_docs().items() if k != "format"},
    }


def _jacobians(progs) -> dict:
    """The Jacobians' entries and multiply-adds before and after zero-dropping."""
    models = progs.params.models
    return {j.name: {"shape": [j.rows, j.cols], "nonzero": len(j.entries), "constant": j.constants,
                     "fma_dense": j.dense, "fma_sparse": j.sparse} for j in models.jacobians.values()}


def _extra(params, core) -> dict:
    sched = core.schedules["iterate"]
    mc = sched.machine
    progs = programs(params)
    return {
        **engine_manifest(core),
        **engine_timing(params, core),
        **engine_streams(core, "iterate"),
        "cycles_keys": dict(CYCLES),
        "sizes": {"n": params.n, "m": params.m, "nw": params.nw, "nv": params.nv, "nu": params.nu},
        "bounds": {"fma": sched.program.fma_count, "fma_per_pe": -(-sched.program.fma_count // mc.pes),
                   "chain": chain_bound(sched.program, mc)},
        "jacobians": _jacobians(progs),
        "jacobians_definition": "per Jacobian (F = df/dx, L = df/dw at w = 0; H = dh/dx, M = dh/dv at v = 0): "
                                "its nonzero entries (constant: known at generation, no word computed), "
                                "fma_dense the multiply-adds of forward mode without structure (every "
                                "operation's rule for every input), fma_sparse those its entries add to the "
                                "function's own once structural zeros are dropped and common terms shared",
    }


def _app(spec) -> dict:
    """The parameters the application ``spec`` fixes (its sizes)."""
    return app_sizes(load_app(spec))


def _waivers(params) -> str:
    return engine_waivers(params, program_units(programs(params).steps.values()))


CORE = CoreDescriptor(
    name="ekf",
    summary="extended Kalman filter of an application's f and h (Jacobians by differentiation at generation) "
            "on P float PEs behind an AXI4 slave",
    params=EkfParams,
    docs=_docs,
    build=Ekf,
    fields_of=lambda p, port: None,
    extra=_extra,
    examples=({"app": "tracker:Tracker"},),
    waivers=_waivers,
    app=_app,
)
