"""The ``kfgen`` command line: one subcommand per core, each writing Verilog, waivers and a manifest.

    kfgen castella [--tracks N] ... [--config FILE.toml] -o DIR
    kfgen --version

A core registers a :class:`Core`: its parameter dataclass (which validates itself and raises
``ParamError(param, message)``), a sentence of meaning and a unit per parameter, and how to
build the Amaranth component and describe its ports. Options are named after the dataclass
fields (``sigma_r`` -> ``--sigma-r``); defaults and ranges are read from the parameter module,
never repeated here.

Every bad input ends the same way: one line ``kfgen: error: <param>: <what is allowed>`` on
stderr and exit status 2, before any file is written.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import re
import sys
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

from kfgen.hdl.castella.params import ALPHA_FRAC, Q2_MAX, RANGES, Z_FRAC, Z_MAX, CastellaParams

from . import __version__

__all__ = ["main", "Core", "Doc", "CORES", "register", "UsageError"]

EXIT_USAGE = 2
EXIT_INTERNAL = 1


class UsageError(Exception):
    """Bad input: ``param`` names the option, key or file; ``message`` says what is allowed."""

    def __init__(self, param: str, message: str):
        super().__init__(f"{param}: {message}")
        self.param = param
        self.message = message


@dataclass(frozen=True)
class Doc:
    """What a parameter means, its unit ("" for none) and the values it takes, for ``--help``."""

    meaning: str
    unit: str
    allowed: str


@dataclass(frozen=True)
class Core:
    """A core the command line can generate."""

    name: str
    summary: str
    params: type  # frozen dataclass; its constructor validates and raises ParamError
    docs: Callable[[], Mapping[str, Doc]]  # one Doc per dataclass field
    build: Callable  # params -> wiring.Component
    fields_of: Callable  # (params, port name) -> list of field dicts, or None
    extra: Callable = lambda params, component: {}  # more manifest entries


CORES: dict[str, Core] = {}


def register(core: Core) -> Core:
    CORES[core.name] = core
    return core


def option(field: str) -> str:
    return "--" + field.replace("_", "-")


# ---------------------------------------------------------------------------- Castella

def _castella_docs() -> dict[str, Doc]:
    def rng(key):
        lo, hi = RANGES[key]
        return f"integer {lo}..{hi}" if isinstance(lo, int) else f"{lo} to {hi}"

    return {
        "tracks": Doc("independent tracks held in state memory, selected by s_axis_tid", "", rng("tracks")),
        "data_width": Doc("width of the range, velocity and covariance words", "bits", rng("data_width")),
        "gain_width": Doc("width of the Kalman gains K1 and K2", "bits", rng("gain_width")),
        "q_width": Doc("width of the q code: 2**q_width levels on the line from q1 to q2", "bits",
                       rng("q_width")),
        "period": Doc("measurement period T of each track", "s", rng("period")),
        "sigma_r": Doc("standard deviation of the range measurement noise", "m", rng("sigma_r")),
        "alpha": Doc("pole alpha_R of the single-pole filter on the normalised residual, eq. (8)", "",
                     f"open interval (0, 1), representable in {ALPHA_FRAC} fraction bits"),
        "q1": Doc("manoeuvre noise spectral density while the filtered residual is below z1", "m^2/s^3",
                  "0 < q1 < q2"),
        "q2": Doc("manoeuvre noise spectral density once the filtered residual reaches z2", "m^2/s^3",
                  f"greater than q1, at most {Q2_MAX:g}"),
        "z1": Doc("filtered normalised residual above which q rises from q1 (manoeuvre flagged)", "sigma",
                  "0 < z1 < z2"),
        "z2": Doc("filtered normalised residual at which q reaches q2", "sigma",
                  f"z1 < z2 <= {Z_MAX}, at least 2**-{Z_FRAC} above z1"),
        "name": Doc("top-level module and file name; every module in the Verilog is prefixed by it", "",
                    "a Verilog identifier: a letter or _, then letters, digits or _"),
    }


_CASTELLA_FIELD_PORTS = ("s_axis_tdata", "s_axis_tuser", "m_axis_tdata", "m_axis_tuser")


def _castella_build(params):
    from kfgen.hdl.castella.core import Castella
    return Castella(params)


register(Core(
    name="castella",
    summary="adaptive two-state (range, velocity) tracker with manoeuvre detection, many tracks",
    params=CastellaParams,
    docs=_castella_docs,
    build=_castella_build,
    fields_of=lambda p, port: p.field_list(port) if port in _CASTELLA_FIELD_PORTS else None,
    extra=lambda p, c: {"track_interval_cycles": c.track_interval},
))


# ---------------------------------------------------------------------------- IEEE-754 units

def _fpu_docs() -> dict[str, Doc]:
    from kfgen.hdl.arith.float.params import CLOCK_MHZ, OPS, ranges_text
    return {
        "op": Doc("operation: a+b, a-b, a*b, a/b, sqrt(a), a*b+c with one rounding, int32 to float, "
                  "float to int32 (round to nearest even, saturating)", "",
                  "one of " + ", ".join(OPS) + " (any case)"),
        "format": Doc("floating-point format", "",
                      "binary16, bfloat16, binary32, binary64, or eEmM with E exponent bits (3..15) "
                      "and M stored fraction bits (2..64), e.g. e6m11 (any case; an eEmM that is a "
                      "named format is recorded by its name: e8m23 is binary32)"),
        "subnormals": Doc("ieee: gradual underflow; ftz: subnormal inputs and results flushed to zero "
                          "(smaller, as vendor IP)", "", "ieee or ftz (any case)"),
        "stages": Doc("pipeline register stages = latency; the default is designed for "
                      f"{CLOCK_MHZ} MHz on an ECP5-85 in binary32 (iterative div/sqrt: the "
                      "recurrence's block sets the clock, slower the fewer cycles_per_op)", "cycles",
                      "an integer in a range that depends on op, format, subnormals and cycles_per_op; "
                      f"in binary32: {ranges_text('stages')}"),
        "cycles_per_op": Doc("div and sqrt: cycles per operation; 1 fully pipelined, K > 1 iterative "
                             "and smaller, with i_ready backpressure", "cycles",
                             "an integer in a range that depends on op and format; in binary32: "
                             f"{ranges_text('cycles_per_op')}; 1 for other ops"),
        "name": Doc("top-level module and file name", "",
                    "a Verilog identifier: a letter or _, then letters, digits or _"),
    }


def _fpu_params_cls():
    from kfgen.hdl.arith.float.params import FpuParams
    return FpuParams


register(Core(
    name="fpu",
    summary="one IEEE-754 floating-point unit (add, sub, mul, div, sqrt, fma, i2f, f2i) in any format",
    params=_fpu_params_cls(),
    docs=_fpu_docs,
    build=lambda p: p.build(),
    fields_of=lambda p, port: p.field_list(port),
))


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
            return UsageError("CORE", f"name a core: one of {', '.join(CORES)}")
        return UsageError(name, "is required" + (": the directory to write into" if name == "-o" else ""))
    m = re.match(r"argument (\S+?): (.*)", message)
    if m:
        name = m.group(1).split("/")[0]
        what = m.group(2)
        if what.startswith("expected one argument"):
            what = "needs a value"
        elif what.startswith("invalid choice"):
            what = f"{what.split('(')[0].strip()}; one of {', '.join(CORES)}"
            name = "CORE"
        return UsageError(name, what)
    m = re.match(r"ambiguous option: (\S+?)(?:=\S*)? could match (.*)", message)
    if m:
        return UsageError(m.group(1), f"unknown option (did you mean one of {m.group(2)}?)")
    return UsageError("kfgen", message)


def _defaults(params_cls) -> dict:
    return {f.name: f.default for f in dataclasses.fields(params_cls)}


def _help(doc: Doc, default) -> str:
    unit = f" [{doc.unit}]" if doc.unit else ""
    shown = "the unit's own" if default is None else default
    return f"{doc.meaning}{unit}; {doc.allowed}; default {shown}".replace("%", "%%")


def _build_parser() -> argparse.ArgumentParser:
    top = _Parser(prog="kfgen", allow_abbrev=False,
                  description="Generate synthesisable Verilog Kalman-filter cores, with Verilator lint "
                              "waivers and a JSON manifest, from Amaranth descriptions.",
                  epilog="`kfgen CORE --help` lists a core's parameters.")
    top.add_argument("--version", action="version", version=f"kfgen {__version__}")
    sub = top.add_subparsers(dest="core", metavar="CORE", required=True, parser_class=_Parser)
    for core in CORES.values():
        params_cls = core.params
        docs, defaults = core.docs(), _defaults(params_cls)
        p = sub.add_parser(
            core.name, help=core.summary, description=f"{core.name}: {core.summary}.", allow_abbrev=False,
            formatter_class=argparse.RawDescriptionHelpFormatter,
            epilog="Values come from the defaults, then --config FILE.toml (its keys are the option names\n"
                   "without the leading dashes; - and _ are interchangeable), then the command line.\n"
                   "Writes DIR/TOP.v, DIR/TOP.vlt (Verilator waivers) and DIR/TOP.json (the manifest);\n"
                   "TOP is --name.")
        g = p.add_argument_group("parameters")
        for field in defaults:
            g.add_argument(option(field), metavar="TOP" if field == "name" else field.upper(),
                           dest=field, default=None, help=_help(docs[field], defaults[field]))
        p.add_argument("--config", metavar="FILE.toml", help="read parameters from a TOML file")
        p.add_argument("-o", "--output", metavar="DIR", required=True,
                       help="directory to write into (created if missing)")
    return top


# ---------------------------------------------------------------------------- values

def _read_config(path: str, fields: Mapping) -> dict:
    try:
        import tomllib
    except ImportError:  # Python 3.10
        try:
            import tomli as tomllib
        except ImportError:
            raise UsageError("--config", "reading TOML needs Python 3.11 or the `tomli` package") from None
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


def _convert(field: str, text: str, default, doc: Doc):
    """A command-line string as the type of the field's default."""
    if isinstance(default, str):
        return text
    try:
        if default is None or isinstance(default, int):  # None: an optional count
            return int(text, 10)
        return float(text)
    except ValueError:
        kind = "an integer" if default is None or isinstance(default, int) else "a number"
        raise UsageError(option(field), f"must be {kind}, not {text!r} (allowed: {doc.allowed})") from None


def _params(core: Core, args: argparse.Namespace):
    params_cls = core.params
    defaults, docs = _defaults(params_cls), core.docs()
    values, source = dict(defaults), {}
    if args.config is not None:
        for k, v in _read_config(args.config, defaults).items():
            values[k], source[k] = v, args.config
    for field in defaults:
        text = getattr(args, field)
        if text is not None:
            values[field] = _convert(field, text, defaults[field], docs[field])
            source.pop(field, None)
    try:
        return params_cls(**values)
    except ValueError as exc:  # ParamError is a ValueError; so is anything else it rejects
        field = str(getattr(exc, "param", "parameters")).replace("-", "_")
        message = str(exc).split(": ", 1)[1] if hasattr(exc, "param") else str(exc)
        where = f" (from {source[field]})" if field in source else ""
        raise UsageError(option(field) if field in defaults else field, _one_line(message) + where) from None


def _command(core: Core, params) -> str:
    """The command line that regenerates ``params`` (for the header)."""
    parts = ["kfgen", core.name]
    for field, value in dataclasses.asdict(params).items():
        parts += [option(field), str(value)]
    return " ".join(parts + ["-o", "DIR"])


# ---------------------------------------------------------------------------- generation

def generate(core: Core, params) -> dict[str, str]:
    """File name -> text of everything ``core`` produces for ``params``."""
    from .manifest import dumps, manifest
    from .verilog import emit, header, waivers

    top = params.name
    component = core.build(params)
    head = header(core.name, top, dataclasses.asdict(params), _command(core, params))
    verilog = emit(component, top, head)
    return {
        f"{top}.v": verilog,
        f"{top}.vlt": waivers(verilog, top, head),
        f"{top}.json": dumps(manifest(core.name, top, dataclasses.asdict(params), component,
                                      lambda port: core.fields_of(params, port), core.extra(params, component))),
    }


def _prepare(out: str) -> Path:
    if not out.strip():
        raise UsageError("-o", "must name a directory")
    path = Path(out)
    try:
        path.mkdir(parents=True, exist_ok=True)
        probe = path / ".kfgen-write-test"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        raise UsageError("-o", f"cannot write to directory {out}: {exc.strerror or exc}") from None
    return path


def run(argv: list[str] | None = None) -> int:
    args = _build_parser().parse_args(argv)
    core = CORES[args.core]
    params = _params(core, args)
    out = _prepare(args.output)
    files = generate(core, params)
    for name, text in files.items():
        target = out / name
        try:
            target.write_bytes(text.encode("utf-8"))
        except OSError as exc:
            raise UsageError("-o", f"cannot write {target}: {exc.strerror or exc}") from None
        print(target)
    return 0


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
