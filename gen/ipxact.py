"""The core as Vivado IP Integrator takes it: ``TOP.xml``, an IP-XACT (IEEE 1685-2009, the
``spirit:`` dialect Vivado reads and writes) component, and ``TOP_ip.tcl``, a Vivado script
that adds it to a project's IP catalog and puts it in a block design beside a Zynq PS.

Both are made from the manifest alone (its ``ports``, ``bus``, ``registers``, ``memories`` and
``parameters``), so the XML says what the manifest, ``TOP.rdl`` and ``TOP.h`` say:

- the AXI4 slave ``s_axi`` (``xilinx.com:interface:aximm:1.0``) with its memory map: one
  address block of the bus's size holding every register (fields, access, reset, named values)
  and every memory as a register array (``dim``: one 32-bit word per bus word), at the map's
  offsets;
- the AXI4-Stream ports ``s_axis``/``m_axis`` (``axis:1.0``) where the core has them, the
  interrupt ``irq`` (``interrupt:1.0``, SENSITIVITY LEVEL_HIGH), the clock ``clk``
  (``clock:1.0``, ASSOCIATED_BUSIF every bus, ASSOCIATED_RESET ``rst``) and the reset ``rst``
  (``reset:1.0``, POLARITY ACTIVE_HIGH);
- the file set (``TOP.v``; the Verilator waivers are no design source), every top-level port,
  and the core's parameters as read-only information in a ``kfgen:`` vendor extension.

PeakRDL-ipxact (the SystemRDL exporter) does not fit the register part: it discards every
``mem`` beside registers in an addrmap ("IP-XACT does not support 'mem' nodes that are nested
in hierarchy"), which is where the map's buffer lives, and sizes the block by its widest
register (64, for ID) instead of the 32-bit bus. So the whole component is written here with
:mod:`xml.etree.ElementTree`. No timestamps, no paths: the bytes depend on the manifest only.
"""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET

from . import __version__

__all__ = ["SPIRIT", "PART", "vlnv", "bus_interfaces", "component", "ip_tcl", "files"]

SPIRIT = "http://www.spiritconsortium.org/XMLSchema/SPIRIT/1685-2009"
_XSI = "http://www.w3.org/2001/XMLSchema-instance"
_XILINX = "http://www.xilinx.com"
KFGEN = "https://kfgen.org/ipxact/1"  # the namespace of kfgen's vendor extension (information only)

_NAMESPACES = {"spirit": SPIRIT, "xsi": _XSI, "xilinx": _XILINX, "kfgen": KFGEN}

#: Field access of the map -> IP-XACT 2009 access and modifiedWriteValue.
_FIELD_ACCESS = {"ro": ("read-only", None), "rw": ("read-write", None),
                 "w1c": ("read-write", "oneToClear"), "w1p": ("write-only", None)}
_ACCESS = {"ro": "read-only", "rw": "read-write"}

#: The 7-series and UltraScale families the IP is offered for in the catalog (the RTL is plain
#: Verilog; the chapter's board is a Zynq-7000, XC7Z045).
_FAMILIES = ("artix7", "kintex7", "virtex7", "zynq", "kintexu", "virtexu", "kintexuplus", "virtexuplus",
             "zynquplus")

#: The Zynq part TOP_ip.tcl creates a project for when none is open.
PART = "xc7z045ffg900-2"


def vlnv(top: str) -> str:
    """The component's vendor:library:name:version, ``kfgen.org:kfgen:TOP:<generator version>``."""
    return f"kfgen.org:kfgen:{top}:{__version__}"


def _sub(parent, tag: str, text=None, **attrs):
    """A ``spirit:`` child of ``parent`` (``attrs`` are ``spirit:`` attributes)."""
    node = ET.SubElement(parent, f"{{{SPIRIT}}}{tag}", {f"{{{SPIRIT}}}{k}": v for k, v in attrs.items()})
    if text is not None:
        node.text = str(text)
    return node


def _parameter(parent, name: str, value: str) -> None:
    p = _sub(parent, "parameter")
    _sub(p, "name", name)
    _sub(p, "value", value)


def _bus_interface(parent, name: str, bus: str, mode: str, port_map: dict[str, str], parameters=None,
                   memory_map=None) -> None:
    """A bus interface of Xilinx type ``bus`` (``interface:aximm``, ``signal:clock``...) whose
    ``mode`` is ``slave`` or ``master``; ``port_map`` is logical -> physical port name."""
    kind, what = bus.split(":")
    bi = _sub(parent, "busInterface")
    _sub(bi, "name", name)
    _sub(bi, "busType", vendor="xilinx.com", library=kind, name=what, version="1.0")
    _sub(bi, "abstractionType", vendor="xilinx.com", library=kind, name=f"{what}_rtl", version="1.0")
    m = _sub(bi, mode)
    if memory_map:
        _sub(m, "memoryMapRef", memoryMapRef=memory_map)
    maps = _sub(bi, "portMaps")
    for logical, physical in port_map.items():
        pm = _sub(maps, "portMap")
        _sub(_sub(pm, "logicalPort"), "name", logical)
        _sub(_sub(pm, "physicalPort"), "name", physical)
    if parameters:
        ps = _sub(bi, "parameters")
        for key, value in parameters.items():
            _parameter(ps, key, value)


def _prefixed(ports, prefix: str) -> dict[str, str]:
    """Logical (upper-case suffix) -> physical name of the ports named ``prefix_*``."""
    return {p["name"][len(prefix) + 1:].upper(): p["name"] for p in ports if p["name"].startswith(prefix + "_")}


def bus_interfaces(ports) -> list[tuple[str, str, str, dict[str, str]]]:
    """(name, bus type, mode, port map) of each bus interface the ``ports`` (the manifest's)
    make, buses first: ``s_axi``, then ``s_axis``, ``m_axis``, ``irq``, ``clk``, ``rst`` where present."""
    names = {p["name"] for p in ports}
    out = [(prefix, bus, mode, _prefixed(ports, prefix))
           for prefix, bus, mode in (("s_axi", "interface:aximm", "slave"), ("s_axis", "interface:axis", "slave"),
                                     ("m_axis", "interface:axis", "master"))]
    out = [b for b in out if b[3]]
    for port, bus, mode, logical in (("irq", "signal:interrupt", "master", "INTERRUPT"),
                                     ("clk", "signal:clock", "slave", "CLK"), ("rst", "signal:reset", "slave", "RST")):
        if port in names:
            out.append((port, bus, mode, {logical: port}))
    return out


def _register(block, name: str, offset: int, width: int, access: str, fields, dim: int | None = None,
              description: str | None = None) -> None:
    reg = _sub(block, "register")
    _sub(reg, "name", name)
    if description:
        _sub(reg, "description", description)
    if dim is not None:
        _sub(reg, "dim", dim)
    _sub(reg, "addressOffset", f"{offset:#x}")
    _sub(reg, "size", width)
    _sub(reg, "access", _ACCESS[access])
    reset = [f for f in fields if f.get("reset") is not None]
    if reset:
        r = _sub(reg, "reset")
        _sub(r, "value", f"{sum(f['reset'] << f['lsb'] for f in reset):#x}")
        _sub(r, "mask", f"{sum(((1 << f['width']) - 1) << f['lsb'] for f in reset):#x}")
    for f in fields:
        access, modified = _FIELD_ACCESS[f["access"]]
        field = _sub(reg, "field")
        _sub(field, "name", f["name"])
        _sub(field, "bitOffset", f["lsb"])
        _sub(field, "bitWidth", f["width"])
        # The core sets read-only and write-1-to-clear bits itself.
        _sub(field, "volatile", "true" if f["access"] in ("ro", "w1c") else "false")
        _sub(field, "access", access)
        if f.get("values"):
            values = _sub(field, "enumeratedValues")
            for value_name, code in sorted(f["values"].items(), key=lambda item: item[1]):
                v = _sub(values, "enumeratedValue")
                _sub(v, "name", value_name)
                _sub(v, "value", code)
        if modified:
            _sub(field, "modifiedWriteValue", modified)


def _memory_map(parent, manifest) -> None:
    bus = manifest["bus"]
    mm = _sub(_sub(parent, "memoryMaps"), "memoryMap")
    _sub(mm, "name", bus["prefix"])
    block = _sub(mm, "addressBlock")
    _sub(block, "name", "map")
    _sub(block, "description", "Registers from 0x0, the buffer's memories after them, as TOP.rdl and TOP.h say; "
                               "each memory is an array of bus words")
    _sub(block, "baseAddress", "0x0")
    _sub(block, "range", f"{bus['size']:#x}")
    _sub(block, "width", bus["data_width"])
    _sub(block, "usage", "register")
    for r in manifest["registers"]:
        _register(block, r["name"], r["offset"], r["width"], r["access"], r["fields"])
    word = bus["data_width"]
    for m in manifest["memories"]:
        rows, cols = m["shape"]
        _register(block, m["name"], m["offset"], word, m["access"],
                  [{"name": "word", "lsb": 0, "width": word, "access": m["access"], "values": {}}],
                  dim=rows * cols * m["words_per_element"],
                  description=f"{m['description']}; {rows} x {cols} {m['format']}, {m['order']}"
                              + (", two bus words per element, low first" if m["words_per_element"] == 2 else ""))


def _model(parent, top: str, ports) -> None:
    model = _sub(parent, "model")
    views = _sub(model, "views")
    for view, env in (("xilinx_verilogsynthesis", "synthesis"), ("xilinx_verilogbehavioralsimulation", "simulation")):
        v = _sub(views, "view")
        _sub(v, "name", view)
        _sub(v, "envIdentifier", f"verilogSource:vivado.xilinx.com:{env}")
        _sub(v, "language", "verilog")
        _sub(v, "modelName", top)
        _sub(_sub(v, "fileSetRef"), "localName", "rtl")
    out = _sub(model, "ports")
    for p in ports:
        port = _sub(out, "port")
        _sub(port, "name", p["name"])
        wire = _sub(port, "wire")
        _sub(wire, "direction", {"input": "in", "output": "out", "inout": "inout"}[p["direction"]])
        if p["width"] > 1:
            vector = _sub(wire, "vector")
            _sub(vector, "left", p["width"] - 1)
            _sub(vector, "right", 0)


def _value(value) -> str:
    return value if isinstance(value, str) else json.dumps(value)


def component(top: str, summary: str, manifest) -> str:
    """The IP-XACT 1685-2009 text of ``TOP.xml`` for the core ``manifest`` describes (one with
    an AXI4 slave: a ``bus`` entry)."""
    for prefix, uri in _NAMESPACES.items():
        ET.register_namespace(prefix, uri)
    root = ET.Element(f"{{{SPIRIT}}}component",
                      {f"{{{_XSI}}}schemaLocation": f"{SPIRIT} {SPIRIT}/index.xsd"})
    for key, value in zip(("vendor", "library", "name", "version"), vlnv(top).split(":")):
        _sub(root, key, value)
    ports = manifest["ports"]
    interfaces = bus_interfaces(ports)
    buses = _sub(root, "busInterfaces")
    buses_of_clock = ":".join(name for name, bus, _, _ in interfaces if bus.startswith("interface:"))
    extra = {"irq": {"SENSITIVITY": "LEVEL_HIGH"}, "rst": {"POLARITY": "ACTIVE_HIGH"},
             "clk": {"ASSOCIATED_BUSIF": buses_of_clock, "ASSOCIATED_RESET": "rst"}}
    for name, bus, mode, port_map in interfaces:
        _bus_interface(buses, name, bus, mode, port_map, extra.get(name),
                       manifest["bus"]["prefix"] if name == manifest["bus"]["prefix"] else None)
    _memory_map(root, manifest)
    _model(root, top, ports)
    fileset = _sub(_sub(root, "fileSets"), "fileSet")
    _sub(fileset, "name", "rtl")
    f = _sub(fileset, "file")
    _sub(f, "name", f"{top}.v")
    _sub(f, "fileType", "verilogSource")
    _sub(root, "description", f"{summary} (kfgen {__version__})")
    ext = _sub(root, "vendorExtensions")
    core = ET.SubElement(ext, f"{{{_XILINX}}}coreExtensions")
    families = ET.SubElement(core, f"{{{_XILINX}}}supportedFamilies")
    for family in _FAMILIES:
        ET.SubElement(families, f"{{{_XILINX}}}family", {f"{{{_XILINX}}}lifeCycle": "Production"}).text = family
    ET.SubElement(ET.SubElement(core, f"{{{_XILINX}}}taxonomies"), f"{{{_XILINX}}}taxonomy").text = "/UserIP"
    ET.SubElement(core, f"{{{_XILINX}}}displayName").text = f"{top} ({manifest['core']}, kfgen)"
    ET.SubElement(core, f"{{{_XILINX}}}coreRevision").text = "1"
    info = ET.SubElement(ext, f"{{{KFGEN}}}parameters", {"core": manifest["core"], "generator": __version__})
    for key, value in sorted(manifest["parameters"].items()):
        ET.SubElement(info, f"{{{KFGEN}}}parameter", {"name": key, "value": _value(value)})
    ET.indent(root, "  ")
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def ip_tcl(top: str, manifest) -> str:
    """The Vivado script ``TOP_ip.tcl``: the core's IP repository, a block design with a Zynq
    PS (processing_system7), the core by its VLNV, its AXI4 slave on M_AXI_GP0 through the
    AXI automation, its clock on FCLK_CLK0, its reset from a proc_sys_reset, its irq on IRQ_F2P."""
    names = {p["name"] for p in manifest["ports"]}
    lines = [
        f"# {top}_ip.tcl: generated by kfgen {__version__}; do not edit.",
        f"# Puts {top} ({vlnv(top)}) in a Vivado block design beside a Zynq PS. In Vivado's Tcl console,",
        f"# with a project open (or none: one is created for {PART}):",
        f"#   source DIR/{top}_ip.tcl",
        f"# It copies {top}.xml (as component.xml) and {top}.v into DIR/ip_repo/{top}, adds DIR/ip_repo",
        "# to the project's IP repositories and builds the block design.",
        "",
        "set here [file dirname [file normalize [info script]]]",
        f"set part {PART}",
        f"set design {top}_bd",
        "if {[catch {current_project}]} {",
        f"    create_project {top}_zynq [file join $here {top}_zynq] -part $part",
        "}",
        f"set repo [file join $here ip_repo {top}]",
        "file mkdir $repo",
        f"file copy -force [file join $here {top}.xml] [file join $repo component.xml]",
        f"file copy -force [file join $here {top}.v] [file join $repo {top}.v]",
        "set repos [get_property ip_repo_paths [current_project]]",
        "set_property ip_repo_paths [lsort -unique [concat $repos [list [file join $here ip_repo]]]] [current_project]",
        "update_ip_catalog",
        "",
        "create_bd_design $design",
        "create_bd_cell -type ip -vlnv xilinx.com:ip:processing_system7:5.5 ps7",
        "apply_bd_automation -rule xilinx.com:bd_rule:processing_system7 "
        "-config {make_external \"FIXED_IO, DDR\" apply_board_preset \"1\" Master \"Disable\" Slave \"Disable\"} "
        "[get_bd_cells ps7]",
    ]
    if "irq" in names:
        lines.append("set_property -dict [list CONFIG.PCW_USE_FABRIC_INTERRUPT {1} CONFIG.PCW_IRQ_F2P_INTR {1}] "
                     "[get_bd_cells ps7]")
    lines += [
        f"create_bd_cell -type ip -vlnv {vlnv(top)} {top}_0",
        "# The clock and an active-high reset first, so that the AXI automation finds them connected.",
        f"connect_bd_net [get_bd_pins ps7/FCLK_CLK0] [get_bd_pins {top}_0/clk]",
        f"create_bd_cell -type ip -vlnv xilinx.com:ip:proc_sys_reset:5.0 {top}_reset",
        f"connect_bd_net [get_bd_pins ps7/FCLK_CLK0] [get_bd_pins {top}_reset/slowest_sync_clk]",
        f"connect_bd_net [get_bd_pins ps7/FCLK_RESET0_N] [get_bd_pins {top}_reset/ext_reset_in]",
        f"connect_bd_net [get_bd_pins {top}_reset/peripheral_reset] [get_bd_pins {top}_0/rst]",
        "apply_bd_automation -rule xilinx.com:bd_rule:axi4 "
        "-config {Clk_master {/ps7/FCLK_CLK0} Clk_slave {/ps7/FCLK_CLK0} Clk_xbar {/ps7/FCLK_CLK0} "
        f"Master {{/ps7/M_AXI_GP0}} Slave {{/{top}_0/s_axi}} ddr_seg {{Auto}} intc_ip {{New AXI Interconnect}} "
        f"master_apm {{0}}}} [get_bd_intf_pins {top}_0/s_axi]",
    ]
    if "irq" in names:
        lines.append(f"connect_bd_net [get_bd_pins {top}_0/irq] [get_bd_pins ps7/IRQ_F2P]")
    if "s_axis_tdata" in names:
        lines.append("# s_axis and m_axis are left for the design to connect (a DMA, or another core).")
    lines += ["assign_bd_address", "validate_bd_design", "save_bd_design", ""]
    return "\n".join(lines)


def files(top: str, summary: str, manifest) -> dict[str, str]:
    """``TOP.xml`` and ``TOP_ip.tcl`` of a core with an AXI4 slave; none for one without."""
    if "bus" not in manifest:
        return {}
    return {f"{top}.xml": component(top, summary, manifest), f"{top}_ip.tcl": ip_tcl(top, manifest)}
