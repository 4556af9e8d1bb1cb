"""The linear Kalman filter core as kfgen's command line, manifest, ``make verilog`` and
``make bench`` see it."""

from __future__ import annotations

from ..describe import CoreDescriptor, Doc
from ..engine.descriptor import engine_docs, engine_manifest, engine_timing, engine_waivers, program_units
from ..engine.params import GEN_CROSSBAR_MAX, GEN_PES_MAX, WORK_RULE
from ..linalg.schedule import chain_bound
from .core import Kf
from .params import INPUTS_MAX, MEASUREMENTS_MAX, PES_MAX, STATES_MAX, KfParams
from .regmap import CYCLES
from .steps import programs

__all__ = ["CORE"]


def _docs() -> dict[str, Doc]:
    engine = engine_docs()
    return {
        "states": Doc("states n: the length of x", "", f"an integer in 1..{STATES_MAX}; with m, nu and P: {WORK_RULE}"),
        "measurements": Doc("measurements m: the length of z (S = H P H^T + R factored by LDL^T)", "",
                            f"an integer in 1..{MEASUREMENTS_MAX}"),
        "inputs": Doc("control inputs nu: the length of u (x^- = F x + B u); 0: no B and u", "",
                      f"an integer in 0..{INPUTS_MAX}"),
        "pes": Doc("processing elements P (FMAs working in parallel)", "",
                   f"an integer in 1..{GEN_PES_MAX} with P x banks <= {GEN_CROSSBAR_MAX} (P <= 8 with the "
                   "default banks): the most that generates in 60 s and 2 GB; see --states for the sizes' limit"),
        "div_sqrt": Doc("the shared divider and square root: iterative (one result bit a cycle, about half "
                        "their area) or pipelined (one operation a cycle); by default iterative at P = 1, "
                        "pipelined above", "", "iterative or pipelined (any case)"),
        "banks": Doc("dual-port banks of the operand memory; by default 2P", "", f"an integer in 2..{2 * PES_MAX}"),
        "format": engine["format"],
        "irq": engine["irq"],
        "streams": Doc("AXI4-Stream ports beside the AXI4 slave for a design without a processor: s_axis takes "
                       "one measurement (z, then u) a transfer and runs an iteration, m_axis gives x and the "
                       "diagonal of P (x only with --steady-gain)", "", "a switch"),
        "steady_gain": Doc("a fixed gain K in the buffer, written by software (e.g. the steady-state gain of the "
                           "discrete algebraic Riccati equation, kfgen.sim.kf.reference.steady_gain), instead of "
                           "P, Q and R: an iteration is n (n + nu + m) multiply-adds (docs/kf.md)", "", "a switch"),
        **{k: engine[k] for k in ("address_width", "target_mhz", "name")},
    }


def _streams(core) -> dict:
    spec = core.stream
    if spec is None:
        return {}
    width, fields = core.params.fmt.width, spec.fields()

    def listed(port):
        return [{"name": name, "lsb": lsb, "width": width} for name, lsb in fields[port]]
    return {"streams": {
        "s_axis": {"tdata_width": spec.in_width, "fields": listed("s_axis"),
                   "meaning": "one measurement: the core writes z and u, runs iterate"},
        "m_axis": {"tdata_width": spec.out_width, "fields": listed("m_axis"),
                   "tuser": {"err_pivot": 0, "err_nan": 1},
                   "meaning": "the estimate after that iteration: x, then the diagonal of P"},
        "latency_cycles": core.cycles("iterate") + spec.latency(),
        "latency_definition": "clock edges from the one that takes the s_axis transfer (counted) to the first "
                              "after which m_axis_tvalid is high",
    }}


def _extra(params, core) -> dict:
    sched = core.schedules["iterate"]
    mc = sched.machine
    return {
        **engine_manifest(core),
        **engine_timing(params, core),
        **_streams(core),
        "cycles_keys": {k: v for k, v in CYCLES.items() if k in core.schedules},
        "sizes": {"n": params.n, "m": params.m, "nu": params.nu},
        "bounds": {"fma": sched.program.fma_count, "fma_per_pe": -(-sched.program.fma_count // mc.pes),
                   "chain": chain_bound(sched.program, mc)},
    }


def _waivers(params) -> str:
    return engine_waivers(params, program_units(programs(params).steps.values()))


CORE = CoreDescriptor(
    name="kf",
    summary="linear Kalman filter (F, B, H, Q, R in the buffer; Joseph's update, or a steady gain) on P float "
            "PEs behind an AXI4 slave",
    params=KfParams,
    docs=_docs,
    build=Kf,
    fields_of=lambda p, port: None,
    extra=_extra,
    examples=({}, {"states": 2, "measurements": 1, "inputs": 1, "steady_gain": True, "streams": True,
                 "name": "kf_steady"}),
    waivers=_waivers,
)
