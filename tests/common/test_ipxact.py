"""``TOP.xml`` (IP-XACT 1685-2009) and ``TOP_ip.tcl`` (Vivado) of the cores with an AXI4 slave
(:mod:`kfgen.gen.ipxact`).

No PyPI package carries the Accellera 1685-2009 schema files (ipyxact ships YAML descriptions
of the elements it reads, PeakRDL-ipxact none), so each file is validated structurally here:
the component's elements in the schema's order, the VLNV, every manifest port once with its
direction and width, every port map naming a real port, the memory map's registers and
memories at TOP.rdl's offsets and sizes, the clock, reset and interrupt parameters Vivado
reads; and ipyxact, an independent reader of the 2009 dialect, reads it back. Vivado is not
available here: ``TOP_ip.tcl`` runs under tclsh with stub procedures for the Vivado commands,
which record the calls.
"""

import json
import shutil
import subprocess
import xml.etree.ElementTree as ET

import pytest
from ipyxact.ipyxact import Component
from systemrdl.node import MemNode, RegNode

from kfgen.gen import __version__
from kfgen.gen.ipxact import SPIRIT, component, files, vlnv
from kfgen.gen.regdoc import compile_systemrdl

from helpers import kfgen_in_process

pytestmark = pytest.mark.xdist_group("ipxact")  # one worker generates the three cores once

S = f"{{{SPIRIT}}}"
NS = {"spirit": SPIRIT}

#: (core, arguments, top): the cores with an AXI4 slave (small sizes: the XML does not depend on
#: them beyond the map), the KF with its stream ports.
CORES = [
    ("ukf", ["--states", "2", "--observations", "1", "--process-noise", "1", "--measurement-noise", "1"], "ukf"),
    ("imm", ["--models", "3", "--states", "2", "--measurements", "2", "--pes", "2"], "imm"),
    ("kf", ["--states", "4", "--measurements", "2", "--inputs", "1", "--pes", "2", "--streams"], "kf"),
]

#: The 1685-2009 component's children, in the order its schema's sequence requires.
COMPONENT_ORDER = ["vendor", "library", "name", "version", "busInterfaces", "channels", "remapStates",
                   "addressSpaces", "memoryMaps", "model", "componentGenerators", "choices", "fileSets",
                   "whiteboxElements", "cpus", "otherClockDrivers", "description", "parameters", "vendorExtensions"]
REGISTER_ORDER = ["name", "displayName", "description", "dim", "addressOffset", "typeIdentifier", "size", "volatile",
                  "access", "reset", "field"]
FIELD_ORDER = ["name", "displayName", "description", "bitOffset", "typeIdentifier", "bitWidth", "volatile", "access",
               "enumeratedValues", "modifiedWriteValue"]


@pytest.fixture(scope="module", params=CORES, ids=[c[0] for c in CORES])
def generated(request, tmp_path_factory):
    core, args, top = request.param
    out = tmp_path_factory.mktemp(core)
    proc = kfgen_in_process(core, *args, "-o", out)
    assert proc.returncode == 0, proc.stderr
    return top, out, json.loads((out / f"{top}.json").read_text())


def _tags(node) -> list[str]:
    return [child.tag.removeprefix(S) for child in node if child.tag.startswith(S)]


def _in_order(node, order) -> None:
    tags = _tags(node)
    assert all(t in order for t in tags), tags
    assert tags == sorted(tags, key=order.index), f"out of the schema's order: {tags}"


def _params(bus) -> dict[str, str]:
    return {p.find("spirit:name", NS).text: p.find("spirit:value", NS).text
            for p in bus.findall("spirit:parameters/spirit:parameter", NS)}


def test_only_for_an_axi4_slave(tmp_path):
    """A core without an AXI4 slave (Castella: streams only) writes neither file."""
    assert files("trk", "", {"ports": [{"name": "clk", "direction": "input", "width": 1}]}) == {}
    assert kfgen_in_process("castella", "--tracks", "2", "--name", "trk", "-o", tmp_path).returncode == 0
    assert not list(tmp_path.glob("trk*.xml")) and not list(tmp_path.glob("*_ip.tcl"))


def test_component(generated):
    top, out, manifest = generated
    text = (out / f"{top}.xml").read_text()
    root = ET.fromstring(text)
    assert root.tag == f"{S}component"
    _in_order(root, COMPONENT_ORDER)
    assert [root.find(f"spirit:{k}", NS).text for k in ("vendor", "library", "name", "version")] == \
        vlnv(top).split(":") == ["kfgen.org", "kfgen", top, __version__]
    # Deterministic, and no path of this machine.
    assert component(top, root.find("spirit:description", NS).text.removesuffix(f" (kfgen {__version__})"),
                     manifest) == text
    assert str(out) not in text

    # Every manifest port once, with its direction and width.
    ports = {}
    for port in root.findall("spirit:model/spirit:ports/spirit:port", NS):
        name = port.find("spirit:name", NS).text
        assert name not in ports, f"port {name} twice"
        left = port.find("spirit:wire/spirit:vector/spirit:left", NS)
        ports[name] = (port.find("spirit:wire/spirit:direction", NS).text, 1 if left is None else int(left.text) + 1)
    assert ports == {p["name"]: ({"input": "in", "output": "out"}[p["direction"]], p["width"])
                     for p in manifest["ports"]}

    # Bus interfaces: real ports, each mapped once; types and the parameters Vivado reads.
    buses = {b.find("spirit:name", NS).text: b for b in root.findall("spirit:busInterfaces/spirit:busInterface", NS)}
    mapped = []
    for name, bus in buses.items():
        physical = [p.text for p in bus.findall("spirit:portMaps/spirit:portMap/spirit:physicalPort/spirit:name", NS)]
        assert physical and set(physical) <= set(ports), name
        mapped += physical
    assert len(mapped) == len(set(mapped)) == len(ports), "every port in exactly one bus interface"
    kinds = {n: b.find("spirit:busType", NS).get(f"{S}name") for n, b in buses.items()}
    streams = [n for n in ("s_axis", "m_axis") if f"{n}_tdata" in ports]
    assert kinds == {"s_axi": "aximm", **{n: "axis" for n in streams}, "irq": "interrupt", "clk": "clock",
                     "rst": "reset"}
    assert (manifest["core"] == "kf") == bool(streams)
    axi = buses["s_axi"]
    assert axi.find("spirit:abstractionType", NS).get(f"{S}name") == "aximm_rtl"
    assert axi.find("spirit:slave/spirit:memoryMapRef", NS).get(f"{S}memoryMapRef") == "s_axi"
    logical = {p.find("spirit:logicalPort/spirit:name", NS).text: p.find("spirit:physicalPort/spirit:name", NS).text
               for p in axi.findall("spirit:portMaps/spirit:portMap", NS)}
    assert logical == {n.removeprefix("s_axi_").upper(): n for n in ports if n.startswith("s_axi_")}
    assert {"AWADDR", "WDATA", "BRESP", "ARADDR", "RDATA", "RLAST"} <= set(logical)
    assert _params(buses["clk"]) == {"ASSOCIATED_BUSIF": ":".join(["s_axi", *streams]), "ASSOCIATED_RESET": "rst"}
    assert _params(buses["rst"]) == {"POLARITY": "ACTIVE_HIGH"}
    assert _params(buses["irq"]) == {"SENSITIVITY": "LEVEL_HIGH"}

    # Files: the Verilog only (the waivers are no design source).
    assert [f.text for f in root.findall("spirit:fileSets/spirit:fileSet/spirit:file/spirit:name", NS)] == [f"{top}.v"]
    views = root.findall("spirit:model/spirit:views/spirit:view", NS)
    assert {v.find("spirit:modelName", NS).text for v in views} == {top}

    # The parameters, as information.
    info = root.find("spirit:vendorExtensions/{https://kfgen.org/ipxact/1}parameters", NS)
    assert {p.get("name") for p in info} == set(manifest["parameters"])


def test_memory_map_matches_rdl(generated, tmp_path):
    """The address block holds what TOP.rdl holds: each register and memory at its offset and
    size (a memory as an array of bus words), the block the bus's size."""
    top, out, manifest = generated
    root = ET.fromstring((out / f"{top}.xml").read_text())
    (mm,) = root.findall("spirit:memoryMaps/spirit:memoryMap", NS)
    (block,) = mm.findall("spirit:addressBlock", NS)
    assert int(block.find("spirit:range", NS).text, 0) == manifest["bus"]["size"]
    assert int(block.find("spirit:width", NS).text) == manifest["bus"]["data_width"] == 32
    got = {}
    for reg in block.findall("spirit:register", NS):
        _in_order(reg, REGISTER_ORDER)
        for field in reg.findall("spirit:field", NS):
            _in_order(field, FIELD_ORDER)
        dim = reg.find("spirit:dim", NS)
        words = 1 if dim is None else int(dim.text)
        got[reg.find("spirit:name", NS).text] = (int(reg.find("spirit:addressOffset", NS).text, 0),
                                                 words * int(reg.find("spirit:size", NS).text) // 8)
    node = compile_systemrdl((out / f"{top}.rdl").read_text(), tmp_path / "map.rdl")
    want = {}
    for child in node.children():
        if isinstance(child, RegNode):
            want[child.inst_name] = (child.address_offset, child.size)
        elif isinstance(child, MemNode):
            want[child.inst_name] = (child.address_offset, child.size)
    assert got == want
    # Field access and resets as the manifest says (CTRL.start acts on a 1 and reads 0; STATUS's
    # error bits clear on a 1).
    fields = {}
    for reg in block.findall("spirit:register", NS):
        for f in reg.findall("spirit:field", NS):
            modified = f.find("spirit:modifiedWriteValue", NS)
            fields[f'{reg.find("spirit:name", NS).text}.{f.find("spirit:name", NS).text}'] = (
                f.find("spirit:access", NS).text, None if modified is None else modified.text)
    assert fields["CTRL.start"] == ("write-only", None)
    assert ("read-write", "oneToClear") in fields.values()
    assert fields["ID.core"] == ("read-only", None)


def test_ipyxact_reads_it_back(generated):
    """ipyxact, a reader of the 2009 dialect independent of the writer, finds the same VLNV,
    ports, bus interfaces, memory map and files."""
    top, out, manifest = generated
    c = Component()
    c.load(str(out / f"{top}.xml"))
    assert (c.vendor, c.library, c.name, c.version) == tuple(vlnv(top).split(":"))
    assert [p.name for p in c.model.ports.port] == [p["name"] for p in manifest["ports"]]
    assert {b.name for b in c.busInterfaces.busInterface} >= {"s_axi", "clk", "rst", "irq"}
    block = c.memoryMaps.memoryMap[0].addressBlock[0]
    assert block.range == manifest["bus"]["size"]
    offsets = {r.name: r.addressOffset for r in block.register}
    assert offsets == {x["name"]: x["offset"] for x in manifest["registers"] + manifest["memories"]}
    assert [f.name for f in c.fileSets.fileSet[0].file] == [f"{top}.v"]


#: Stub Vivado commands: each records its call (one line, its words) in the list ``calls``.
STUBS = r"""
set calls {}
set project_open 0
proc record {args} { global calls; lappend calls $args }
proc current_project {args} {
    global project_open
    if {!$project_open} { error "no open project" }
    return proj
}
proc create_project {args} { global project_open; set project_open 1; record create_project {*}$args }
proc get_property {args} { record get_property {*}$args; return {} }
foreach cmd {set_property update_ip_catalog create_bd_design create_bd_cell apply_bd_automation connect_bd_net
             assign_bd_address validate_bd_design save_bd_design} {
    proc $cmd {args} "record $cmd {*}\$args"
}
foreach cmd {get_bd_cells get_bd_pins get_bd_intf_pins} { proc $cmd {args} { return $args } }
source [lindex $argv 0]
foreach call $calls { puts $call }
"""


@pytest.mark.skipif(shutil.which("tclsh") is None, reason="needs tclsh")
def test_ip_tcl_under_stubs(generated, tmp_path):
    """``TOP_ip.tcl`` under tclsh with the Vivado commands stubbed: it parses, runs, copies the
    component into its repository, and calls the commands in the order a block design needs."""
    top, out, manifest = generated
    stubs = tmp_path / "stubs.tcl"
    stubs.write_text(STUBS)
    proc = subprocess.run(["tclsh", str(stubs), str(out / f"{top}_ip.tcl")], capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 0, proc.stderr
    calls = [line.split()[0] for line in proc.stdout.splitlines()]
    assert calls[0] == "create_project" and "xc7z045ffg900-2" in proc.stdout.splitlines()[0]
    repo = out / "ip_repo" / top
    assert (repo / "component.xml").read_bytes() == (out / f"{top}.xml").read_bytes()
    assert (repo / f"{top}.v").read_bytes() == (out / f"{top}.v").read_bytes()
    lines = proc.stdout.splitlines()

    def at(fragment):
        return next(i for i, line in enumerate(lines) if fragment in line)

    assert f"set_property ip_repo_paths {out / 'ip_repo'}" in lines[at("set_property ip_repo_paths")]
    order = [at("update_ip_catalog"), at("create_bd_design"), at("processing_system7:5.5 ps7"),
             at("bd_rule:processing_system7"), at(f"-vlnv {vlnv(top)} {top}_0"), at(f"{top}_0/clk"),
             at(f"{top}_0/rst"), at("bd_rule:axi4"), at(f"{top}_0/irq"), at("validate_bd_design"),
             at("save_bd_design")]
    assert order == sorted(order)
    assert "ps7/IRQ_F2P" in lines[at(f"{top}_0/irq")]
    assert "CONFIG.PCW_USE_FABRIC_INTERRUPT" in lines[at("PCW_USE_FABRIC_INTERRUPT")]
    assert f"Slave {{/{top}_0/s_axi}}" in lines[at("bd_rule:axi4")]
    assert calls[-1] == "save_bd_design"
