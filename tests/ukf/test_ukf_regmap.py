"""The UKF's parameters and its register and memory map: validation, placement, decoding, the
manifest entries, and the SystemRDL, C header and Markdown made from the map."""

import dataclasses
import json
import shutil
import subprocess

import pytest

from kfgen.gen.regdoc import documents, map_manifest
from kfgen.hdl.arith.float.format import FloatFormat
from kfgen.hdl.describe import ParamError
from kfgen.hdl.engine.regmap import REGION_ROLES, Field, Memory, Register
from kfgen.hdl.ukf.params import UkfParams
from kfgen.hdl.ukf.programs import build_ukf
from kfgen.hdl.ukf.regmap import ukf_map

CONFIGS = {
    "default": {},
    "binary64": {"format": "binary64"},
    "binary16": {"format": "binary16", "w0": 0.5},
    "small": {"states": 2, "observations": 1, "process_noise": 1, "measurement_noise": 1, "pes": 3},
    "noirq": {"states": 3, "observations": 2, "process_noise": 2, "measurement_noise": 1, "irq": False, "address_width": 16},
}
REGIONS = ("x", "P", "Q", "R", "sigma_points", "sigma_points_f", "sigma_points_h", "z")


@pytest.fixture(scope="module", params=CONFIGS)
def config(request):
    params = UkfParams(**CONFIGS[request.param])
    return params, ukf_map(params)


# ------------------------------------------------------------------------------ parameters

@pytest.mark.parametrize("kwargs,param,says", [
    ({"states": 0}, "states", "1..255"),
    ({"observations": -1}, "observations", "1..255"),
    ({"process_noise": 256}, "process_noise", "1..255"),
    ({"measurement_noise": 1.0}, "measurement_noise", "integer"),
    ({"states": True}, "states", "integer"),
    ({"pes": 0}, "pes", "1..M = 20"),
    ({"pes": 21}, "pes", "1..M = 20"),
    ({"states": 2, "observations": 1, "process_noise": 1, "measurement_noise": 1, "pes": 5}, "pes", "1..M = 4"),
    ({"format": "binary128"}, "format", "unknown format"),
    ({"format": "e15m64"}, "format", "at most 64 bits"),
    ({"w0": 1.0}, "w0", "0 <= W0 < 1"),
    ({"w0": -0.1}, "w0", "0 <= W0 < 1"),
    ({"w0": float("nan")}, "w0", "0 <= W0 < 1"),
    ({"irq": "no"}, "irq", "true or false"),
    ({"address_width": 12}, "address_width", "needs 13 address bits"),
    ({"format": "binary64", "address_width": 13}, "address_width", "needs 14 address bits"),
    ({"address_width": 33}, "address_width", "1..32"),
    ({"name": "module"}, "name", "keyword"),
])
def test_bad_parameter_names_itself_in_one_line(kwargs, param, says):
    with pytest.raises(ParamError) as info:
        UkfParams(**kwargs)
    assert info.value.param == param
    assert says in info.value.message
    assert "\n" not in str(info.value)


def test_defaults_are_the_nanosatellite_filter():
    p = UkfParams()
    assert (p.n, p.m, p.nw, p.nv, p.M, p.N, p.pes) == (7, 6, 7, 6, 20, 22, 1)
    assert (p.format, p.w0, p.irq, p.address_width) == (FloatFormat(8, 23), 0.0, True, 13)
    # a format's name is replaced by the one FloatFormat (recorded by its canonical name), the width as built
    assert UkfParams(format="E8M23").format == p.format and p.fmt is p.format and p.format.name == "binary32"
    assert UkfParams(address_width=20).address_width == 20


# ------------------------------------------------------------------------------ the map

def test_blocks_do_not_overlap_and_fit(config):
    params, regmap = config
    blocks = sorted(regmap.registers + regmap.memories, key=lambda b: b.offset)
    for a, b in zip(blocks, blocks[1:]):
        assert a.end <= b.offset, (a.name, b.name)
    assert blocks[-1].end <= regmap.size == 1 << regmap.address_width
    # registers below the buffer; the buffer from a power of two, regions back to back
    base = regmap.buffer_base
    assert base & (base - 1) == 0 and regmap.size >= 2 * base
    assert ukf_map(dataclasses.replace(params, address_width=None)).size == 2 * base
    assert all(r.end <= base for r in regmap.registers)
    assert [m.name for m in regmap.memories] == list(REGIONS)
    offset = base
    for m in regmap.memories:
        assert m.offset == offset and m.offset % m.element_size == 0
        offset = m.end
    assert offset - base > base // 2  # the smallest power of two
    assert params.address_width == regmap.address_width


def test_every_address_decodes_to_its_word(config):
    _, regmap = config
    expect = {}
    for kind, blocks in (("register", regmap.registers), ("memory", regmap.memories)):
        for b in blocks:
            for i in range(b.size // 4):
                assert b.offset + 4 * i not in expect
                expect[b.offset + 4 * i] = (kind, b.name, i)
    holes = 0
    for addr in range(regmap.size):
        got = regmap.decode(addr)
        want = expect.get(addr & ~3)
        assert got == want, hex(addr)
        holes += want is None
    assert holes > 0
    assert regmap.decode(-1) is None and regmap.decode(regmap.size) is None


def test_elements_and_bus_words(config):
    params, regmap = config
    words = 1 if params.fmt.width <= 32 else 2
    for m in regmap.memories:
        assert (m.format, m.words, m.element_size) == (params.format.name, words, 4 * words)
        for row in range(m.rows):
            for col in range(m.cols):
                for w in range(words):
                    addr = m.address(row, col, w)
                    kind, name, index = regmap.decode(addr)
                    assert (kind, name, m.locate(index)) == ("memory", m.name, (row, col, w))
    with pytest.raises(IndexError):
        regmap["P"].address(params.n, 0)


def test_map_agrees_with_the_engine_layout(config):
    params, regmap = config
    engine = build_ukf(params).layout
    bus = [r for r in engine.regions.values() if r.kind == "bus"]
    assert [r.name for r in bus] == list(REGIONS)
    for r in bus:
        m = regmap[r.name]
        assert (m.rows, m.cols) == (r.rows, r.cols)
        assert m.offset == regmap.buffer_base + r.base * m.element_size


def test_registers_and_fields_as_the_issue_names_them(config):
    params, regmap = config
    names = [r.name for r in regmap.registers]
    assert names == ["ID", "CTRL", "STATUS"] + (["IRQ_ENABLE"] if params.irq else [])
    ctrl, status = regmap["CTRL"], regmap["STATUS"]
    assert [(v.name, v.value) for v in ctrl.field("step").values] == [("sig_gen", 0), ("predict", 1), ("update", 2)]
    assert ctrl.field("start").access == ctrl.field("reset").access == "w1p"
    assert {f.name: f.access for f in status.fields} == {
        "busy": "ro", "done": "w1c", "err_pivot": "w1c", "err_nan": "w1c", "err_busy": "w1c"}
    if params.irq:  # irq = STATUS & IRQ_ENABLE: the same bits
        assert {(f.name, f.lsb) for f in regmap["IRQ_ENABLE"].fields} == \
            {(f.name, f.lsb) for f in status.fields if f.name != "busy"}
    ident = regmap["ID"]
    assert ident.access == "ro" and ident.width == 64
    fmt = params.fmt
    assert {f.name: f.reset for f in ident.fields} == {
        "core": 0x55, "version": 1, "exp_bits": fmt.exp_bits, "frac_bits": fmt.frac_bits,
        "pes": params.pes, "n": params.n, "nw": params.nw, "nv": params.nv, "m": params.m}
    assert {m.name: m.access for m in regmap.memories} == {
        name: "ro" if name == "sigma_points" else "rw" for name in REGIONS}


def test_default_map():
    regmap = ukf_map(UkfParams())
    assert [(r.name, r.offset) for r in regmap.registers] == [
        ("ID", 0x0), ("CTRL", 0x8), ("STATUS", 0xC), ("IRQ_ENABLE", 0x10)]
    assert [(m.name, m.offset, m.shape) for m in regmap.memories] == [
        ("x", 0x1000, (7, 1)), ("P", 0x101C, (7, 7)), ("Q", 0x10E0, (7, 7)), ("R", 0x11A4, (6, 6)),
        ("sigma_points", 0x1234, (22, 20)), ("sigma_points_f", 0x1914, (22, 7)),
        ("sigma_points_h", 0x1B7C, (22, 6)), ("z", 0x1D8C, (6, 1))]
    assert (regmap.address_width, regmap.size, regmap.memories[-1].end) == (13, 0x2000, 0x1DA4)
    wide = ukf_map(UkfParams(format="binary64"))
    assert (wide.address_width, wide.buffer_base, wide.memories[-1].end - wide.buffer_base) == (14, 0x2000, 873 * 8)
    assert wide["P"].address(3, 2, 1) == 0x2000 + 7 * 8 + (3 * 7 + 2) * 8 + 4
    small = ukf_map(UkfParams(states=2, observations=1, process_noise=1, measurement_noise=1))
    assert (small.address_width, small.buffer_base, small.memories[-1].end - small.buffer_base) == (9, 0x100, 51 * 4)


def test_declarations_that_cannot_be_decoded_are_refused():
    with pytest.raises(ValueError, match="overlaps"):
        Register("A", 0, 32, "", (Field("a", 0, 4, "rw", ""), Field("b", 3, 1, "rw", "")))
    with pytest.raises(ValueError, match="straddles"):
        Register("A", 0, 64, "", (Field("a", 28, 8, "ro", ""),))
    with pytest.raises(ValueError, match="aligned"):
        Register("A", 4, 64, "", ())
    with pytest.raises(ValueError, match="does not fit"):
        Field("a", 0, 2, "rw", "", reset=4)
    with pytest.raises(ValueError, match="access"):
        Memory("m", 0, (1, 1), "binary32", 1, "w1c", "")
    with pytest.raises(ValueError, match="role"):
        Memory("m", 0, (1, 1), "binary32", 1, "rw", "", role="scratch")


# ------------------------------------------------------------------------------ products

def test_manifest_entries(config):
    params, regmap = config
    data = json.loads(json.dumps(map_manifest(regmap)))
    assert set(data) == {"bus", "registers", "memories", "memory_roles"}
    assert data["memory_roles"] == REGION_ROLES and set(REGION_ROLES) == {"input", "state", "output"}
    bus = data["bus"]
    assert (bus["protocol"], bus["data_width"], bus["address_width"], bus["id_width"]) == \
        ("AXI4", 32, params.address_width, 4)
    for r in data["registers"]:
        assert {"name", "offset", "access", "fields"} <= set(r)
        for f in r["fields"]:
            assert {"name", "lsb", "width", "access", "values"} <= set(f)
    ctrl = next(r for r in data["registers"] if r["name"] == "CTRL")
    assert next(f for f in ctrl["fields"] if f["name"] == "step")["values"] == \
        {"sig_gen": 0, "predict": 1, "update": 2}
    for m, mem in zip(data["memories"], regmap.memories):
        assert {"name", "offset", "shape", "order", "format", "access"} <= set(m)
        assert (m["name"], m["offset"], m["shape"], m["order"], m["format"], m["access"]) == \
            (mem.name, mem.offset, [mem.rows, mem.cols], "row-major", params.format.name, mem.access)
        assert (m["description"], m["role"], m["layout"]) == (mem.desc, mem.role, mem.layout)


@pytest.fixture(scope="module")
def docs(config):
    params, regmap = config
    return params, regmap, documents(regmap, params.name)


def test_systemrdl_compiles_to_the_map(docs, tmp_path):
    from kfgen.gen.regdoc import compile_systemrdl
    params, regmap, files = docs
    node = compile_systemrdl(files[f"{params.name}.rdl"], tmp_path / "map.rdl")
    got = [(c.inst_name, c.absolute_address, c.size) for c in node.children()]
    assert got == [(b.name, b.offset, b.size) for b in regmap.registers + regmap.memories]
    for r in regmap.registers:
        rdl = {f.inst_name: (f.lsb, f.width, f.get_property("reset")) for f in node.get_child_by_name(r.name).fields()}
        assert rdl == {f.name: (f.lsb, f.width, f.reset) for f in r.fields}


@pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc is not installed")
def test_c_header_compiles_and_agrees(docs, tmp_path):
    params, regmap, files = docs
    T, top = params.name.upper(), params.name
    (tmp_path / f"{top}.h").write_text(files[f"{top}.h"])
    row, col = min(3, params.n - 1), min(2, params.n - 1)  # P row 3 col 2 where P has one
    checks = [f"{T}__P_ADDR({row}, {col}) == {regmap['P'].address(row, col):#x}u",
              f"{T}__STATUS__DONE_bm == {regmap['STATUS'].field('done').mask:#x}",
              f"{T}__CTRL__STEP__UPDATE == 2u",
              f"{T}__ELEMENT_SIZE == {regmap['x'].element_size}u",
              f"sizeof({top}_t) == {regmap.memories[-1].end:#x}"]
    for b in regmap.registers + regmap.memories:
        N = f"{T}__{b.name.upper()}"
        checks += [f"{N}_OFFSET == {b.offset:#x}u", f"offsetof({top}_t, {b.name}) == {N}_OFFSET"]
    for m in regmap.memories:
        N = f"{T}__{m.name.upper()}"
        checks += [f"{N}_ROWS == {m.rows}u", f"{N}_COLS == {m.cols}u", f"{N}_SIZE == {m.size:#x}u",
                   f"sizeof((({top}_t *)0)->{m.name}.mem[0]) == {m.element_size}"]
    src = tmp_path / "use.c"
    src.write_text(f'#include <stddef.h>\n#include "{top}.h"\n'
                   + "".join(f'_Static_assert({c}, "{c}");\n' for c in checks))
    proc = subprocess.run(["gcc", "-fsyntax-only", "-std=gnu11", "-Wall", "-Wextra", "-Werror", str(src)],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr


def test_markdown_mentions_every_register_field_and_memory(docs):
    params, regmap, files = docs
    md = files[f"{params.name}.md"]
    for r in regmap.registers:
        assert f"### {r.name} register" in md
        for f in r.fields:
            assert f"#### {f.name} field" in md
    for m in regmap.memories:
        assert f"## {m.name} memory" in md and f"{m.rows} x {m.cols} {m.format}, row-major, {m.access}" in md


def test_documents_are_deterministic(docs):
    params, regmap, files = docs
    again = documents(ukf_map(UkfParams(**params.to_dict())), params.name)
    assert again == files
    for text in files.values():
        assert "kfgen-rdl-" not in text and "/tmp" not in text


def test_top_name_that_is_a_systemrdl_keyword():
    params = UkfParams(states=2, observations=1, process_noise=1, measurement_noise=1, name="field")
    files = documents(ukf_map(params), "field")
    assert "#define FIELD__P_OFFSET 0x108u" in files["field.h"] and "} field_t;" in files["field.h"]
