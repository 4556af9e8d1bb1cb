"""The IMM core as kfgen's command line, manifest, ``make verilog`` and ``make bench`` see it."""

from __future__ import annotations

from ..describe import CoreDescriptor, Doc
from ..ukf.params import GEN_CROSSBAR_MAX, GEN_PES_MAX
from .params import D_MAX, MODELS_MAX, PES_MAX, STATES_MAX, ImmParams

__all__ = ["CORE"]


def _docs() -> dict[str, Doc]:
    from ..ukf.descriptor import engine_docs
    return {
        "models": Doc("models R: filters mixed by the IMM, each with its own F, Q, H, R", "",
                      f"an integer in 2..{MODELS_MAX}"),
        "states": Doc("states n of every model", "", f"an integer in 1..{STATES_MAX}"),
        "measurements": Doc("measurements d: the length of z (S^-1 by Schur complements)", "",
                            f"an integer in 1..{D_MAX}"),
        "pes": Doc("processing elements P (FMAs working in parallel)", "",
                   f"an integer in 1..{GEN_PES_MAX} with P x banks <= {GEN_CROSSBAR_MAX} (P <= 8 with the "
                   "default banks): the most that generates in 60 s and 2 GB"),
        "div_sqrt": Doc("the shared divider and square root: iterative (one result bit a cycle, about half "
                        "their area) or pipelined (one operation a cycle); by default iterative at P = 1, "
                        "pipelined above", "", "iterative or pipelined (any case)"),
        "banks": Doc("dual-port banks of the operand memory; by default 2P", "", f"an integer in 2..{2 * PES_MAX}"),
        **engine_docs(),
    }


def _build(params):
    from .core import Imm
    return Imm(params)


def _extra(params, core) -> dict:
    from kfgen.gen.regdoc import map_manifest
    from kfgen.hdl.linalg.schedule import chain_bound
    from kfgen.hdl.linalg.store import store_size

    sched = core.schedules["iterate"]
    layout, mc = sched.program.layout, sched.machine
    store = store_size([sched], layout.size)
    return {
        **map_manifest(core.regmap),
        "cycles": {"iterate": core.cycles("iterate")},
        "cycles_definition": "clock edges from the edge that takes the W beat writing CTRL.start = 1 to the "
                             "first edge after which STATUS.done reads 1, both counted; irq rises on the "
                             "next edge",
        "sizes": {"R": params.R, "n": params.n, "d": params.d},
        "bounds": {"fma": sched.program.fma_count, "fma_per_pe": -(-sched.program.fma_count // mc.pes),
                   "chain": chain_bound(sched.program, mc)},
        "engine": {"pes": mc.pes, "read_latency": mc.read_latency, "unit_register": mc.unit_register, "fma_latency": mc.fma_latency, "div_latency": mc.div_latency,
                   "sqrt_latency": mc.sqrt_latency, "exp_latency": mc.exp_latency,
                   "div_interval": mc.div_interval, "sqrt_interval": mc.sqrt_interval, "banks": mc.banks,
                   "memory_words": layout.size,
                   "program_store": {"instructions": store.instructions, "word_bits": store.word_bits,
                                     "bits": store.bits}},
    }


def _documents(params) -> dict[str, str]:
    from kfgen.gen.regdoc import documents

    from .regmap import imm_map
    return documents(imm_map(params), params.name)


def _waivers(params) -> str:
    from ..ukf.descriptor import _waivers as engine_waivers
    return engine_waivers(params)


def _smoke(params, manifest):
    # The minimum for a core behind AXI4: its ID register reads back as the manifest says.
    from kfgen.gen.smoke import id_register_reads
    return id_register_reads(manifest)


CORE = CoreDescriptor(
    name="imm",
    summary="interacting multiple model filter (R Kalman filters, mixing and combination) on P float PEs "
            "behind an AXI4 slave",
    params=ImmParams,
    docs=_docs,
    build=_build,
    fields_of=lambda p, port: None,
    extra=_extra,
    examples=({},),
    documents=_documents,
    waivers=_waivers,
    bench="kfgen.gen.bench_imm",
    smoke=_smoke,
)
