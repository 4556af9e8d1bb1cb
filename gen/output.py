"""What a core's generation produces, and the one writer that puts it on disk.

:func:`generate` turns a core's parameters into its files (file name -> text) and
:func:`write_files` writes them all or nothing. The command line (:mod:`kfgen.gen.cli`), the
Python API (:mod:`kfgen.gen.api`), ``make verilog`` (:mod:`kfgen.gen.examples`) and the benches
(:mod:`kfgen.gen.synth`) sit above this module and import it; it imports none of them.
"""

from __future__ import annotations

import dataclasses
import os
import shlex
import shutil
import tempfile
from collections.abc import Mapping
from pathlib import Path

from amaranth.hdl import Fragment

from kfgen.hdl.arith.float.format import FloatFormat
from kfgen.hdl.engine.app import recorded_spec
from kfgen.hdl.describe import CoreDescriptor, ParamError

from .cores import bind
from .fusesoc import FlowOptions, constraints, core_file
from .ipxact import files as ipxact_files
from .manifest import dumps, manifest
from .pydriver import files as pydriver_files
from .smoke import testbench, vectors, vectors_name
from .verilog import declared_names, emit, header, waivers

__all__ = ["generate", "write_files", "command", "check_name_fits", "check_output", "port_names",
           "NAME_MAX"]

#: The longest ``--name``: every file is TOP plus a suffix of at most 10 characters
#: (``TOP_driver.py``), and file systems cap a file name at 255 bytes; 64 keeps the names
#: readable and leaves room for the writer's temporary names.
NAME_MAX = 64


def option(field: str) -> str:
    return "--" + field.replace("_", "-")


def check_name_fits(name) -> None:
    """Raise ``ParamError("name", ...)`` for a top name longer than :data:`NAME_MAX`."""
    if isinstance(name, str) and len(name) > NAME_MAX:
        raise ParamError("name", f"must be at most {NAME_MAX} characters (it names every file written, "
                                 f"TOP.v to TOP_driver.py), not {len(name)}")


def port_names(component) -> set[str]:
    """The top module's port names: ``clk``, ``rst`` and the signature's members."""
    return {"clk", "rst", *("__".join(map(str, path)) for path, _, _ in component.signature.flatten(component))}


def recorded(params) -> dict:
    """The parameters a core's header and manifest record: every field, less those marked
    ``omit_none`` (:data:`kfgen.hdl.arith.float.params.OMIT_NONE`) while they are ``None``; a
    float format by its name."""
    return {f.name: _recorded(f.name, value) for f in dataclasses.fields(params)
            if (value := getattr(params, f.name)) is not None or not f.metadata.get("omit_none")}


def _recorded(name: str, value):
    """A parameter's value as generated files write it: a float format by its name, an
    application's file by its name alone (:func:`kfgen.hdl.engine.app.recorded_spec`)."""
    if isinstance(value, FloatFormat):
        return value.name
    if name == "app" and isinstance(value, str):
        return recorded_spec(value)
    return value


def command(core: CoreDescriptor, params, flow: FlowOptions | None = None, out: str = "DIR") -> str:
    """The ``kfgen`` command line that regenerates ``params`` (and ``flow``) byte for byte:
    every parameter and flow option that differs from its default, quoted for a POSIX shell."""
    parts = ["kfgen", core.name]
    for f in dataclasses.fields(params):
        value = getattr(params, f.name)
        if value == f.default:
            continue
        if f.default is True:  # a switch: --no-<name>
            parts.append("--no-" + option(f.name)[2:])
        elif f.default is False:  # a switch: --<name>
            parts.append(option(f.name))
        else:
            parts += [option(f.name), str(_recorded(f.name, value))]
    if flow is not None:
        for f in dataclasses.fields(flow):
            value = getattr(flow, f.name)
            if value != f.default:
                parts += [option(f.name), f"{value:g}" if isinstance(value, float) else str(value)]
    return " ".join(shlex.quote(p) for p in parts + ["-o", out])


def generate(core: CoreDescriptor, params, flow: FlowOptions | None = None) -> dict[str, str]:
    """File name -> text of everything ``core`` produces for ``params``: the Verilog, its
    waivers, the manifest, the core's documents, the IP-XACT component ``TOP.xml`` and its Vivado
    script ``TOP_ip.tcl`` (:mod:`kfgen.gen.ipxact`, for a core with an AXI4 slave) and its Python
    driver ``TOP_driver.py`` (:mod:`kfgen.gen.pydriver`, likewise), the self-checking
    testbench ``TOP_tb.v`` (where the core has one; :mod:`kfgen.gen.smoke`) and its vectors
    ``TOP_vectors.hex`` (an engine core's), the constraints ``TOP.xdc`` and ``TOP.sdc`` and the FuseSoC core ``TOP.core``
    (:mod:`kfgen.gen.fusesoc`; ``flow``, a :class:`~kfgen.gen.fusesoc.FlowOptions`, sets the
    clock and parts, default 100 MHz).

    Raises ``ParamError("name", ...)`` for a top name longer than :data:`NAME_MAX`, or one
    that is also the name of one of the core's ports (before the netlist is emitted) or nets
    (after: Verilator calls that VARHIDDEN, and some tools refuse it).
    """
    core = bind(core)  # the descriptor as hdl declares it gets its gen and sim hooks
    top = params.name
    check_name_fits(top)
    component = core.build(params)
    if top in port_names(component):
        # Elaborated (milliseconds to a second, against the seconds of emission) so that
        # Amaranth does not warn of a component created and never used.
        Fragment.get(component, None)
        raise ParamError("name", f"{top!r} is also a port name of the {core.name} core; choose another module name")
    parameters = recorded(params)
    head = header(core.name, top, parameters, command(core, params))
    verilog = emit(component, top, head)
    if top in declared_names(verilog):
        raise ParamError("name", f"{top!r} is also a port or net name inside the {core.name} core; "
                                 "choose another module name")
    more = core.waivers(params)
    described = manifest(core.name, top, parameters, component,
                         lambda port: core.fields_of(params, port), core.extra(params, component))
    files = {
        f"{top}.v": verilog,
        f"{top}.vlt": waivers(verilog, top, head) + (f"\n{more}" if more else ""),
        f"{top}.json": dumps(described),
        **core.documents(params),
        **ipxact_files(top, core.summary, described),
        **pydriver_files(top, described),
    }
    if core.smoke is not None:
        plan = core.smoke(params, described)
        files[f"{top}_tb.v"] = testbench(top, described, plan, head)
        if plan["kind"] == "axi_script":
            files[vectors_name(top)] = vectors(top, plan, head)
    flow = flow or FlowOptions()
    files.update(constraints(top, flow))
    # The Verilog does not depend on the flow options, so only TOP.core's command names them.
    files[f"{top}.core"] = core_file(top, core.summary, list(files), flow,
                                     header(core.name, top, parameters, command(core, params, flow)))
    return files


def check_output(out) -> Path:
    """``out`` as a directory :func:`write_files` can write into, checked before any generation:
    not empty, not a file, and the directory (or its nearest existing parent) writable.
    Raises ``ParamError("-o", ...)``."""
    if out is None or not str(out).strip():
        raise ParamError("-o", "must name a directory")
    path = Path(out)
    if path.exists() and not path.is_dir():
        raise ParamError("-o", f"{out} exists and is not a directory")
    existing = next(d for d in (path, *path.parents, Path(".")) if d.exists())
    if not existing.is_dir():
        raise ParamError("-o", f"cannot make directory {out}: {existing} is not a directory")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise ParamError("-o", f"cannot write to directory {out}: {existing} is not writable")
    return path


def write_files(out: str | Path, files: Mapping[str, str]) -> list[Path]:
    """Write ``files`` into directory ``out`` (created if missing), all or nothing; the paths.

    Every file is written first into a temporary directory beside ``out``; a new ``out`` is
    that directory renamed, an existing one gets each file moved into place, the file it
    replaces kept aside until all are in. On any failure ``out`` is left as it was (and the
    directories this call made are removed). Raises ``ParamError("-o", ...)`` naming the
    file or directory that could not be written.
    """
    path = check_output(out)
    made = [d for d in (path, *path.parents) if not d.exists()]
    stage = None
    moved: list[tuple[Path, Path | None]] = []  # (target, its old version kept aside, or None)
    culprit = path
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        stage = Path(tempfile.mkdtemp(prefix=f".{path.name[:40]}.kfgen-", dir=path.parent))
        new, old = stage / "new", stage / "old"
        new.mkdir()
        old.mkdir()
        for name, text in files.items():
            culprit = path / name
            (new / name).write_bytes(text.encode("utf-8"))
        if not path.exists():
            culprit = path
            os.rename(new, path)
            moved = [(path / name, None) for name in files]
        else:
            for name in files:
                culprit = target = path / name
                if target.is_dir():
                    raise IsADirectoryError(21, "Is a directory")
                kept = None
                if target.exists():
                    kept = old / name
                    os.replace(target, kept)
                moved.append((target, kept))
                os.replace(new / name, target)
    except OSError as exc:
        for target, kept in reversed(moved):
            try:
                if kept is not None:
                    os.replace(kept, target)
                else:
                    target.unlink(missing_ok=True)
            except OSError:
                pass
        if stage is not None:
            shutil.rmtree(stage, ignore_errors=True)
        for d in made:  # innermost first
            try:
                if d.exists():
                    d.rmdir()
            except OSError:
                break
        what = f"directory {out}" if culprit == path else str(culprit)
        raise ParamError("-o", f"cannot write {what}: {exc.strerror or exc}") from None
    shutil.rmtree(stage, ignore_errors=True)
    return [path / name for name in files]
