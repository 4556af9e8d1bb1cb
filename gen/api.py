"""kfgen from Python: generate a core without a shell, or take its Amaranth component.

    >>> from kfgen.gen.api import generate_core
    >>> core = generate_core("castella", tracks=8, name="trk")
    >>> core.verilog[:60]              # the Verilog text of module trk
    >>> core.manifest["latency_cycles"]
    >>> sorted(core.files)             # every file `kfgen castella ... -o DIR` writes, by name
    >>> core.write("out/trk")          # and those files written (all or nothing)

Parameters are the keyword arguments of the core's parameter dataclass (the command line's
options with ``_`` for ``-``: ``sigma_r=50.0``; with ``app``, the application's sizes first),
or an instance of it; a bad value raises :class:`~kfgen.hdl.describe.ParamError` (a
``ValueError``) naming the parameter and what is allowed. The command line is a layer over
this module: it turns its options (or a TOML file) into these keyword arguments, and
generates through :func:`generate_core`; both sit on :mod:`kfgen.gen.output`, which makes the
files and writes them.

:func:`component` gives the Amaranth ``wiring.Component`` itself, for a design of one's own
that instantiates it (``m.submodules.trk = component("castella", tracks=8)``).
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from kfgen.hdl.engine.app import resolved_spec
from kfgen.hdl.describe import CoreDescriptor, ParamError

from .cores import discover
from .fusesoc import FlowOptions
from .output import generate, write_files

__all__ = ["GeneratedCore", "generate_core", "params_for", "component", "cores", "FlowOptions", "ParamError"]


def cores() -> dict[str, str]:
    """Name -> one-line summary of every core kfgen generates."""
    return {name: core.summary for name, core in discover().items()}


def _core(name: str) -> CoreDescriptor:
    found = discover().get(name)
    if found is None:
        raise ParamError("core", f"must be one of {', '.join(discover())}, not {name!r}")
    return found


def _params(core: CoreDescriptor, params, parameters: Mapping):
    if params is None:
        fields = list(core.params.__dataclass_fields__)
        for key in parameters:
            if key not in fields:
                raise ParamError(key, f"is not a parameter of the {core.name} core; they are {', '.join(fields)}")
        return _sized(core, parameters)
    if parameters or not isinstance(params, core.params):
        raise TypeError(f"give the {core.name} core's parameters as keywords or as one {core.params.__name__}, "
                        "not both")
    return params


def _sized(core: CoreDescriptor, values: Mapping):
    """``core``'s parameters from ``values``, over those the application ``values["app"]`` fixes
    (its sizes and W0, for a core that takes one: ``CoreDescriptor.app``).

    Raises
    ------
    ParamError
        ``app`` for an application that does not load; a parameter the application fixed and
        the core refuses, with ``source`` naming the application.
    """
    spec = values.get("app")
    fixed = {}
    if isinstance(spec, str):  # loads from any directory; recorded by the file's name alone
        spec = resolved_spec(spec)
        values = {**values, "app": spec}
    if spec is not None and core.app is not None:
        try:
            fixed = core.app(spec)
        except ValueError as exc:  # the loader's one-line message
            raise ParamError("app", " ".join(str(exc).split())) from None
    try:
        return core.params(**{**fixed, **values})
    except ParamError as exc:
        if exc.param in fixed and exc.param not in values:
            raise ParamError(exc.param, exc.message, f"app {spec}") from None
        raise


@dataclass(frozen=True)
class GeneratedCore:
    """What :func:`generate_core` made: the files by name, and views of the main ones."""

    core: str
    params: object
    files: Mapping[str, str]

    @property
    def top(self) -> str:
        return self.params.name

    @property
    def verilog(self) -> str:
        """The text of ``TOP.v``."""
        return self.files[f"{self.top}.v"]

    @property
    def manifest(self) -> dict:
        """``TOP.json`` as a dict: ports, fields, latency, parameters."""
        return json.loads(self.files[f"{self.top}.json"])

    def write(self, directory) -> list[Path]:
        """Write every file into ``directory`` (created if missing), all or nothing; the paths."""
        return write_files(directory, self.files)


def generate_core(core: str, params=None, /, *, flow: FlowOptions | None = None, **parameters) -> GeneratedCore:
    """Generate ``core`` (``"castella"``, ``"fpu"``, ``"ukf"``, ...) as ``kfgen CORE`` does.

    Parameters
    ----------
    core : str
        A name from :func:`cores`.
    params : the core's parameter dataclass, optional
        Instead of keyword ``parameters``.
    flow : FlowOptions, optional
        Clock and parts of the vendor-flow files (``TOP.core``, ``TOP.xdc``, ``TOP.sdc``).
    **parameters
        The core's parameters; the rest keep their defaults. With ``app`` (the UKF's
        ``module:Class``), the parameters the application fixes (its sizes and W0) are taken
        from it first, as ``kfgen ukf --app`` does: these override them.

    Raises
    ------
    ParamError
        An unknown core or a bad parameter (``.param`` names it, ``.message`` says what is allowed).
    """
    desc = _core(core)
    chosen = _params(desc, params, parameters)
    return GeneratedCore(desc.name, chosen, generate(desc, chosen, flow))


def params_for(core: str, /, **values):
    """The parameter object :func:`generate_core` builds from ``values`` (with ``app``, the
    application's sizes first): to check parameters before a generation, or to reuse them.

    Raises
    ------
    ParamError
        As :func:`generate_core`.
    """
    desc = _core(core)
    return _params(desc, None, values)


def component(core: str, params=None, /, **parameters):
    """The Amaranth ``wiring.Component`` of ``core`` with these parameters (not elaborated)."""
    desc = _core(core)
    return desc.build(_params(desc, params, parameters))
