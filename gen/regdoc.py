"""What a register and memory map (:class:`kfgen.hdl.engine.regmap.RegisterMap`) turns into: the
manifest's ``bus``, ``registers`` and ``memories``, a SystemRDL description, and from that,
through PeakRDL, a C header and a Markdown document.

Memories are SystemRDL ``external mem`` blocks (``memwidth`` 32, or 64 for elements of two
bus words, low word first): PeakRDL-markdown gives each its own section (address, size, the
description with role, layout, shape, order and format) without unrolling thousands of words, and
PeakRDL-cheader gives the register field macros (``TOP__REG__FIELD_bm`` / ``_bp`` / ``_bw`` /
``_reset``) and a ``TOP_t`` struct with the regions as arrays. PeakRDL-cheader writes no
offsets, shapes or enumerated values as macros, so the header ends with a block of them from
the same map: ``TOP__NAME_OFFSET`` for every register and region, ``TOP__REGION_ROWS`` /
``_COLS`` / ``_SIZE`` and ``TOP__REGION_ADDR(row, col)`` (byte offset of an element from the
core's base), each region's under a comment with its role, description and layout,
``TOP__ELEMENT_SIZE`` and ``TOP__REG__FIELD__VALUE`` for named field values.

Every text is deterministic: no dates, no paths (the exporters run in a temporary directory
and only the file's base name, ``TOP.h``, reaches the header guard).
"""

from __future__ import annotations

import tempfile
from pathlib import Path

from kfgen.hdl.engine.regmap import REGION_ROLES

from . import __version__

__all__ = ["map_manifest", "to_systemrdl", "compile_systemrdl", "c_header", "markdown", "documents"]

_RDL_ACCESS = {  # field access -> SystemRDL properties
    "ro": "sw = r; hw = w;",
    "rw": "sw = rw; hw = r;",
    "w1c": "sw = rw; hw = w; onwrite = woclr;",
    "w1p": "sw = w; hw = r; singlepulse = true;",
}
_ACCESS_TEXT = {
    "ro": "read-only",
    "rw": "read/write",
    "w1c": "write 1 to clear",
    "w1p": "write 1 to act, reads 0",
}


# ---------------------------------------------------------------------------- manifest

def map_manifest(regmap) -> dict:
    """The manifest's ``bus``, ``registers`` and ``memories`` entries (key names as issue 8).

    Beyond the issue's keys: a register's ``width`` in bits (ID is 64: two bus words, low
    first), a field's ``reset`` (for ID's fields the configuration it reports), a memory's
    ``words_per_element``. ``values`` maps a field's named values to their codes. A memory's
    ``description``, ``role`` (one of ``memory_roles``, which says what each means) and
    ``layout`` (what its rows and columns hold) are its declaration's.
    """
    return {
        "bus": {"protocol": "AXI4", "prefix": "s_axi", "data_width": regmap.data_width,
                "address_width": regmap.address_width, "id_width": regmap.id_width, "size": regmap.size,
                "byte_order": "little"},
        "registers": [
            {"name": r.name, "offset": r.offset, "access": r.access, "width": r.width,
             "fields": [{"name": f.name, "lsb": f.lsb, "width": f.width, "access": f.access,
                         "values": {v.name: v.value for v in f.values}, "reset": f.reset}
                        for f in r.fields]}
            for r in regmap.registers],
        "memories": [
            {"name": m.name, "offset": m.offset, "shape": [m.rows, m.cols], "order": m.order,
             "format": m.format, "access": m.access, "words_per_element": m.words,
             "description": m.desc, "role": m.role, "layout": m.layout}
            for m in regmap.memories],
        "memory_roles": dict(REGION_ROLES),
    }


# ---------------------------------------------------------------------------- SystemRDL

def _str(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _memory_desc(m) -> str:
    size = m.element_size
    what = (f"{m.rows} x {m.cols} {m.format}, {m.order}, {m.access}; element (i, j) at offset + "
            f"(i * {m.cols} + j) * {size}")
    if m.words == 2:
        what += ", two bus words, low half first"
    return f"{m.desc}. {_role_text(m)}. Layout: {m.layout}. {what}."


def _role_text(m) -> str:
    return f"Role: {m.role} ({REGION_ROLES[m.role]})"


#: The burst types the slave carries out (:mod:`kfgen.hdl.bus.axi4`); the others answer SLVERR.
BURSTS = ("FIXED", "INCR")


def _top_desc(regmap) -> str:
    return (f"AXI4 slave s_axi: {regmap.data_width}-bit data, {regmap.address_width}-bit byte addresses "
            f"({regmap.size:#x} bytes), ID width {regmap.id_width}, " + " and ".join(BURSTS) + " bursts of 1 to 256 "
            "beats of 4 bytes (a single beat is a burst of one; FIXED repeats its address); any other burst "
            "type or beat size answers SLVERR on every beat and touches nothing, as does an INCR burst that "
            "would cross a 4 KB boundary. "
            f"Registers from 0x0, the buffer from {regmap.buffer_base:#x}. "
            "An address outside every register and memory answers SLVERR and reads 0. "
            "A write to a read-only register or memory answers SLVERR and changes nothing. "
            "While STATUS.busy, buffer writes answer SLVERR and change nothing, and a buffer read waits (R "
            "stalls) until the running step leaves its memory bank a port and does not write the word, then "
            "returns the word as it is; "
            "registers stay readable and writable, but CTRL.start answers SLVERR and sets STATUS.err_busy. "
            "In registers, byte lanes whose WSTRB bit is low keep their bytes (write-1 bits act only in "
            "strobed lanes); the buffer takes whole words: all strobes write, none writes nothing, any other "
            "answers SLVERR. A two-word element is written when its high half is, with the low half written "
            "before it. "
            "Field access: " + "; ".join(f"{k} {v}" for k, v in _ACCESS_TEXT.items()) + ".")


def to_systemrdl(regmap, top: str) -> str:
    """SystemRDL 2.0 text of ``regmap`` as addrmap ``top``."""
    out = [f"// {top}: register and memory map, generated by kfgen {__version__}; do not edit.",
           f"addrmap \\{top} {{",
           f"    desc = {_str(_top_desc(regmap))};",
           "    default regwidth = 32;",
           "    default accesswidth = 32;"]
    for r in regmap.registers:
        for f in r.fields:
            if f.values:
                out.append(f"    enum {r.name}_{f.name}_e {{")
                out += [f"        {v.name} = {f.width}'d{v.value} {{ desc = {_str(v.desc)}; }};" for v in f.values]
                out.append("    };")
        out.append("    reg {")
        if r.width != 32:
            out.append(f"        regwidth = {r.width};")
        out.append(f"        desc = {_str(r.desc)};")
        for f in r.fields:
            desc = f.desc
            if f.values:
                desc += ". Values: " + ", ".join(f"{v.value} {v.name}" for v in f.values)
            encode = f" encode = {r.name}_{f.name}_e;" if f.values else ""
            out.append(f"        field {{ {_RDL_ACCESS[f.access]}{encode} desc = {_str(desc)}; }} "
                       f"{f.name}[{f.msb}:{f.lsb}] = {f.reset:#x};")
        out.append(f"    }} {r.name} @ {r.offset:#x};")
    for m in regmap.memories:
        out.append(f"    external mem {{ mementries = {m.elements}; memwidth = {m.words * 32}; "
                   f"sw = {'r' if m.access == 'ro' else 'rw'}; desc = {_str(_memory_desc(m))}; }} "
                   f"{m.name} @ {m.offset:#x};")
    out.append("};")
    return "\n".join(out) + "\n"


def compile_systemrdl(text: str, path: Path):
    """Compile and elaborate SystemRDL ``text``, written to ``path``; the top addrmap node."""
    from systemrdl import RDLCompiler  # deferred: SystemRDL/PeakRDL, 0.5 s, only for a map's documents

    path.write_text(text, encoding="utf-8")
    rdlc = RDLCompiler()
    rdlc.compile_file(str(path))
    return rdlc.elaborate().top


# ---------------------------------------------------------------------------- C and Markdown

def _macros(regmap, top: str) -> str:
    T = top.upper()
    lines = ["", "// kfgen: byte offsets from the core's base address, the buffer's shapes and the named",
             "// field values, from the same map as the definitions above.",
             f"#define {T}__SIZE {regmap.size:#x}u",
             f"#define {T}__ELEMENT_SIZE {regmap.memories[0].element_size}u"]
    for r in regmap.registers:
        lines.append(f"#define {T}__{r.name.upper()}_OFFSET {r.offset:#x}u")
        for f in r.fields:
            lines += [f"#define {T}__{r.name.upper()}__{f.name.upper()}__{v.name.upper()} {v.value}u"
                      for v in f.values]
    lines += ["", "// The buffer's regions, each with its role:"]
    lines += [f"//   {k:<7} {v}" for k, v in REGION_ROLES.items()]
    for m in regmap.memories:
        N = f"{T}__{m.name.upper()}"
        lines += ["", f"// {m.name} ({m.role}): {m.desc}.", f"// Layout: {m.layout}.",
                  f"#define {N}_OFFSET {m.offset:#x}u",
                  f"#define {N}_ROWS {m.rows}u",
                  f"#define {N}_COLS {m.cols}u",
                  f"#define {N}_SIZE {m.size:#x}u",
                  f"#define {N}_ADDR(row, col) ({N}_OFFSET + ((row) * {N}_COLS + (col)) * {T}__ELEMENT_SIZE)"]
    return "\n".join(lines) + "\n\n"


_FOOTER = "#ifdef __cplusplus\n}\n#endif"


def c_header(node, regmap, top: str, work: Path) -> str:
    """The C header (PeakRDL-cheader, then the macros it does not write) of compiled ``node``."""
    from peakrdl_cheader.c_standards import CStandard  # deferred: SystemRDL/PeakRDL, 0.5 s, only for a map's documents
    from peakrdl_cheader.exporter import CHeaderExporter

    path = work / f"{top}.h"
    CHeaderExporter().export(node, str(path), std=CStandard.gnu99)  # builds with gcc -std=c99
    text = path.read_text(encoding="utf-8")
    at = text.rfind(_FOOTER)
    if at < 0:
        raise RuntimeError("PeakRDL-cheader's header has no C++ footer to put the map's macros before")
    head = f"// {top}.h: register and memory map, generated by kfgen {__version__}; do not edit.\n"
    return head + text[:at].rstrip("\n") + "\n" + _macros(regmap, top) + text[at:]


def markdown(node, top: str, work: Path) -> str:
    """The Markdown register document (PeakRDL-markdown) of compiled ``node``."""
    from peakrdl_markdown import MarkdownExporter  # deferred: SystemRDL/PeakRDL, 0.5 s, only for a map's documents

    path = work / f"{top}.md"
    MarkdownExporter().export(node, str(path))
    return path.read_text(encoding="utf-8")


def documents(regmap, top: str) -> dict[str, str]:
    """File name -> text: ``TOP.rdl``, ``TOP.h``, ``TOP.md``."""
    rdl = to_systemrdl(regmap, top)
    with tempfile.TemporaryDirectory(prefix="kfgen-rdl-") as tmp:
        work = Path(tmp)
        node = compile_systemrdl(rdl, work / f"{top}.rdl")
        return {f"{top}.rdl": rdl, f"{top}.h": c_header(node, regmap, top, work),
                f"{top}.md": markdown(node, top, work)}
