"""The UKF IP core as kfgen's command line, manifest, ``make verilog`` and ``make bench`` see it."""

from __future__ import annotations

from ..describe import CoreDescriptor, Doc
from .params import ADDRESS_WIDTH_MAX, FORMAT_WIDTH_MAX, GEN_CROSSBAR_MAX, GEN_PES_MAX, SIZE_MAX, UkfParams

__all__ = ["CORE", "engine_docs"]


def _docs() -> dict[str, Doc]:
    size = f"an integer in 1..{SIZE_MAX}"
    return {
        "states": Doc("states n: the length of x", "", size),
        "observations": Doc("observations m: the length of z", "", size),
        "process_noise": Doc("process-noise terms nw: Q is nw x nw, and f takes them with x", "", size),
        "measurement_noise": Doc("measurement-noise terms nv: R is nv x nv, and h takes them", "", size),
        "pes": Doc("processing elements P (FMAs working in parallel)", "", "an integer in 1..M, M = n + nw + nv, "
                f"at most {GEN_PES_MAX} with P x banks <= {GEN_CROSSBAR_MAX} (the most that "
                "generates in 60 s and 2 GB)"),
        "div_sqrt": Doc("the shared divider and square root: iterative (one result bit a cycle, about half "
                        "their area; sig_gen takes longer) or pipelined (one operation a cycle); by default "
                        "iterative at P = 1, pipelined above", "", "iterative or pipelined (any case)"),
        "banks": Doc("dual-port banks of the operand memory: more banks, fewer port conflicts and a larger "
                     "crossbar; by default 2P up to P = 2, P from 3 to 8, 8 above", "", "an integer in 2..2M"),
        "format": engine_docs()["format"],
        "w0": Doc("weight W0 of the centre sigma point (eq. 5)", "", "a number with 0 <= W0 < 1"),
        **{k: v for k, v in engine_docs().items() if k != "format"},
    }


def engine_docs() -> dict[str, Doc]:
    """The Docs of the parameters every engine core (UKF, IMM) shares: format, irq,
    address_width, name."""
    return {
        "format": Doc("float format of every buffer word and of the arithmetic", "",
                      f"binary16, bfloat16, binary32, binary64 or eEmM, at most {FORMAT_WIDTH_MAX} bits "
                      "(any case)"),
        "irq": Doc("the irq output and the IRQ_ENABLE register", "",
                   "on or off (in a --config file: irq = true or false)"),
        "address_width": Doc("width of the AXI byte address (the unit's own: the smallest that holds "
                             "the map)", "bits", f"an integer in 1..{ADDRESS_WIDTH_MAX}, at least what the map needs"),
        "name": Doc("top-level module and file name; every module in the Verilog is prefixed by it", "",
                    "a Verilog identifier, not a Verilog/SystemVerilog keyword nor a port name"),
    }


def _build(params):
    from .core import Ukf
    return Ukf(params)


def _extra(params, core) -> dict:
    from kfgen.gen.regdoc import map_manifest
    from kfgen.hdl.linalg.store import store_size

    scheds = core.schedules
    layout = next(iter(scheds.values())).program.layout
    store = store_size(list(scheds.values()), layout.size)
    mc = next(iter(scheds.values())).machine
    return {
        **map_manifest(core.regmap),
        "cycles": {name: core.cycles(name) for name in scheds},
        "cycles_definition": "clock edges from the edge that takes the W beat writing CTRL.start = 1 to the "
                             "first edge after which STATUS.done reads 1, both counted; irq rises on the "
                             "next edge",
        "sizes": {"n": params.n, "m": params.m, "nw": params.nw, "nv": params.nv, "M": params.M,
                  "N": params.N},
        "engine": {"pes": mc.pes, "read_latency": mc.read_latency, "unit_register": mc.unit_register, "fma_latency": mc.fma_latency, "div_latency": mc.div_latency,
                   "sqrt_latency": mc.sqrt_latency, "div_interval": mc.div_interval,
                   "sqrt_interval": mc.sqrt_interval, "banks": mc.banks, "memory_words": layout.size,
                   "program_store": {"instructions": store.instructions, "word_bits": store.word_bits,
                                     "bits": store.bits}},
    }


def _documents(params) -> dict[str, str]:
    from kfgen.gen.cdriver import ukf_driver
    from kfgen.gen.regdoc import documents

    from .regmap import ukf_map
    return {**documents(ukf_map(params), params.name), **ukf_driver(params.name, params.format)}


def _waivers(params) -> str:
    from ..bus.axi4 import lint_waivers
    text = lint_waivers(params.name)
    width = params.fmt.width
    if width < 32:  # binary16, bfloat16, narrow eEmM: one element in the low bits of a bus word
        text += (f"\n// An element narrower than the 32-bit bus word sits in its low {width} bits: a write\n"
                 f"// ignores the high bits (a read returns them as 0).\n"
                 f"lint_off -rule UNUSEDSIGNAL -file \"*{params.name}.v\" "
                 f"-match \"Bits of signal are not used: 'back_bus__w_data'?31:{width}?\"\n")
    return text


def _from_app(spec: str) -> dict:
    # The application is the user's Python (kfgen.sim.ukf.app), loaded only when asked for.
    from kfgen.sim.ukf.app import load_app
    return load_app(spec).core_parameters()


def _smoke(params, manifest):
    # The minimum for a core behind AXI4: its ID register reads back as the manifest says.
    from kfgen.gen.smoke import id_register_reads
    return id_register_reads(manifest)


CORE = CoreDescriptor(
    name="ukf",
    summary="unscented Kalman filter (augmented, spherical simplex) on P float PEs behind an AXI4 slave",
    params=UkfParams,
    docs=_docs,
    build=_build,
    fields_of=lambda p, port: None,
    extra=_extra,
    examples=({},),
    documents=_documents,
    waivers=_waivers,
    app=_from_app,
    bench="kfgen.gen.bench_ukf",
    smoke=_smoke,
)
