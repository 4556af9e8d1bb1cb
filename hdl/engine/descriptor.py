"""What every engine core's descriptor (:class:`kfgen.hdl.describe.CoreDescriptor`) shares:
the docs of the shared parameters, the Verilator waivers of the AXI front end and the
buffer, and the manifest's ``cycles`` and ``engine`` entries."""

from __future__ import annotations

from ..bus.axi4 import lint_waivers
from ..describe import Doc
from ..linalg import isa
from .machine import machine, timing
from .params import ADDRESS_WIDTH_MAX, FORMAT_WIDTH_MAX

__all__ = ["engine_docs", "engine_waivers", "engine_manifest", "engine_timing", "engine_streams", "program_units",
           "units_used", "CYCLES_DEFINITION"]

#: The manifest's ``cycles_definition``: what a step's cycle count counts.
CYCLES_DEFINITION = ("clock edges from the edge that takes the W beat writing CTRL.start = 1 to the "
                     "first edge after which STATUS.done reads 1, both counted; irq rises on the "
                     "next edge")


def engine_docs() -> dict[str, Doc]:
    """The Docs of the parameters every engine core (UKF, IMM) shares: format, irq,
    address_width, target_mhz, name."""
    return {
        "format": Doc("float format of every buffer word and of the arithmetic", "",
                      f"binary16, bfloat16, binary32, binary64 or eEmM, at most {FORMAT_WIDTH_MAX} bits "
                      "(any case)"),
        "irq": Doc("the irq output and the IRQ_ENABLE register", "",
                   "on or off (in a --config file: irq = true or false)"),
        "address_width": Doc("width of the AXI byte address (by default the smallest that holds "
                             "the map)", "bits", f"an integer in 1..{ADDRESS_WIDTH_MAX}, at least what the map needs"),
        "target_mhz": Doc("pipeline the FMA, divider, square root and exponential for this clock on an ECP5-85 "
                          "(nextpnr): each gets the fewest stages the calibrated delay model predicts to reach "
                          "it, the schedule follows, and the manifest's timing records the prediction; above 101 "
                          "MHz also the program store's fetch register (a cycle more a step); default: the "
                          "units' own stages", "MHz",
                          "a number in 10..1000"),
        "name": Doc("top-level module and file name; every module in the Verilog is prefixed by it", "",
                    "a Verilog identifier, not a Verilog/SystemVerilog keyword nor a port name"),
    }


def program_units(programs) -> set[str]:
    """The engine units that ``programs`` (an iterable of
    :class:`~kfgen.hdl.linalg.program.Program`) use: an optional unit is built only then."""
    return {op.unit for prog in programs for op in prog.ops}


def units_used(core) -> set[str]:
    """The engine units that ``core``'s programs use."""
    return program_units(s.program for s in core.schedules.values())


def engine_timing(params, core) -> dict:
    """``{"timing": ...}`` for the manifest of an engine core with a ``target_mhz``, else ``{}``."""
    if params.target_mhz is None:
        return {}
    return {"timing": timing(params, machine(params), units_used(core))}


def engine_streams(core, step: str) -> dict:
    """``{"streams": ...}`` for the manifest of an engine core with stream ports whose
    ``s_axis`` transfer is a measurement (z, then u) that runs ``step`` and whose ``m_axis``
    transfer is the estimate (x, then the diagonal of P); ``{}`` without stream ports."""
    spec = core.stream
    if spec is None:
        return {}

    width, fields = core.params.fmt.width, spec.fields()

    def listed(port):
        return [{"name": name, "lsb": lsb, "width": width} for name, lsb in fields[port]]
    return {"streams": {
        "s_axis": {"tdata_width": spec.in_width, "fields": listed("s_axis"),
                   "meaning": f"one measurement: the core writes z and u, runs {step}"},
        "m_axis": {"tdata_width": spec.out_width, "fields": listed("m_axis"),
                   "tuser": {"err_pivot": 0, "err_nan": 1},
                   "meaning": f"the estimate after that {step}: x, then the diagonal of P"},
        "latency_cycles": core.cycles(step) + spec.latency(),
        "latency_definition": "clock edges from the one that takes the s_axis transfer (counted) to the first "
                              "after which m_axis_tvalid is high",
    }}


def engine_waivers(params, units=()) -> str:
    """The AXI front end's waivers, with a format narrower than the bus word the unused
    high bits of a buffer write, and when ``units`` (the units the core's programs use,
    :func:`program_units`; none by default) hold the CopySign unit the bits it does not read."""
    text = lint_waivers(params.name)
    width = params.fmt.width
    if width < 32:  # binary16, bfloat16, narrow eEmM: one element in the low bits of a bus word
        text += (f"\n// An element narrower than the 32-bit bus word sits in its low {width} bits: a write\n"
                 f"// ignores the high bits (a read returns them as 0).\n"
                 f"lint_off -rule UNUSEDSIGNAL -file \"*{params.name}.v\" "
                 f"-match \"Bits of signal are not used: 'back_bus__w_data'?31:{width}?\"\n")
    if "copysign" in units:
        text += (f"\n// CopySign takes the magnitude bits of its first operand and the sign bit of its second.\n"
                 f"lint_off -rule UNUSEDSIGNAL -file \"*{params.name}.v\" "
                 f"-match \"Bits of signal are not used: 'engine_copysign_rd__0__data'?{width - 1}?\"\n"
                 f"lint_off -rule UNUSEDSIGNAL -file \"*{params.name}.v\" "
                 f"-match \"Bits of signal are not used: 'engine_copysign_rd__1__data'?{width - 2}:0?\"\n")
    return text


def engine_manifest(core) -> dict:
    """The manifest's ``cycles`` (step name -> cycles), ``cycles_definition`` and ``engine``
    (the machine's timing, the operand memory's words and the program store: the ROMs built,
    one per PE and shared unit, each holding every step) of ``core``, an
    :class:`~kfgen.hdl.engine.core.EngineCore`."""
    scheds = core.schedules
    first = next(iter(scheds.values()))
    layout, mc = first.program.layout, first.machine
    roms = core.program_roms
    used = units_used(core)
    optional = {}  # the latency (and interval) of each optional unit the programs use
    for name, u in isa.UNITS.items():
        if u.optional and u.latency is not None and name in used:
            optional[u.latency] = getattr(mc, u.latency)
            if u.interval is not None:
                optional[u.interval] = getattr(mc, u.interval)
    names = list(scheds)
    pro = core.prologue
    prologue = {} if pro is None else {"prologue": {
        "step": names[pro.pre], "before": names[pro.main],
        "after_writes_to": [mem.name for mem in core.regmap.memories if any(
            first <= (mem.offset - core.regmap.buffer_base) // mem.element_size < first + count
            for first, count in pro.elements)],
        "definition": f"a start of {names[pro.main]} runs {names[pro.pre]} first, by itself, when one of these "
                      f"regions has been written since {names[pro.pre]} last ended (and after reset): "
                      f"cycles.{names[pro.pre]} + cycles.{names[pro.main]} from the start's W beat"}}
    return {
        "cycles": {name: core.cycles(name) for name in scheds},
        "cycles_definition": CYCLES_DEFINITION,
        **prologue,
        "engine": {"pes": mc.pes, "read_latency": mc.read_latency, "unit_register": mc.unit_register,
                   "fma_latency": mc.fma_latency, "div_latency": mc.div_latency,
                   "sqrt_latency": mc.sqrt_latency, **optional,
                   "div_interval": mc.div_interval, "sqrt_interval": mc.sqrt_interval, "banks": mc.banks,
                   "memory_words": layout.size,
                   "program_store": {"instructions": sum(words for words, _ in roms.values()),
                                     "bits": sum(words * bits for words, bits in roms.values()),
                                     "roms": {name: {"words": words, "word_bits": bits}
                                              for name, (words, bits) in roms.items()}}},
    }
