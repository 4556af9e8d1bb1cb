"""How a core describes itself to the rest of kfgen, once.

Every core package holds a module ``descriptor`` with a ``CORE`` (a :class:`CoreDescriptor`):
its parameter dataclass, what each parameter means, how to build the Amaranth component,
the packed fields of its data ports, extra manifest entries, the configurations ``make
verilog`` writes and the module ``make bench`` runs. The command line, ``--help``, the
manifest writer, ``make verilog`` and ``make bench`` find the cores through
:func:`kfgen.gen.cores.discover`; adding a core adds a package and touches nothing central.

Pure Python: no Amaranth import, so the parameter modules stay light.
"""

from __future__ import annotations

import functools
import re
import weakref
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

__all__ = ["ParamError", "Doc", "CoreDescriptor", "check_name", "RESERVED_WORDS", "once_per_params"]


class ParamError(ValueError):
    """A bad parameter: ``param`` names it (a dataclass field, or a command-line option),
    ``message`` says what is allowed, and ``source`` (optional) where the bad value came from
    when the caller did not give it (``app nanosat:Nanosat``: the application fixed it). The
    one error type of every parameter check."""

    def __init__(self, param: str, message: str, source: str | None = None):
        super().__init__(f"{param}: {message}" + (f" (from {source})" if source else ""))
        self.param = param
        self.message = message
        self.source = source


@dataclass(frozen=True)
class Doc:
    """What a parameter means, its unit ("" for none) and the values it takes, for ``--help``."""

    meaning: str
    unit: str
    allowed: str


@dataclass(frozen=True)
class CoreDescriptor:
    """A core as the generator sees it.

    Parameters
    ----------
    name : str
        The ``kfgen`` subcommand.
    summary : str
        One line for ``kfgen --help``.
    params : type
        Frozen parameter dataclass; its constructor validates and raises :class:`ParamError`.
    docs : callable
        ``() -> {field: Doc}``, one per dataclass field.
    build : callable
        ``params -> wiring.Component``.
    fields_of : callable
        ``(params, port name) -> list of field dicts or None`` for the manifest.
    extra : callable
        ``(params, component) -> dict`` of more manifest entries.
    examples : tuple of dict
        Parameter sets (keyword arguments of ``params``) that ``make verilog`` writes, each
        into ``OUT/<name>``.
    bench : str or None
        Module whose ``main(argv)`` prints the core's benchmark table (``make bench``).
    documents : callable
        ``params -> {file name: text}`` of more files written beside the Verilog (the UKF's
        register map as ``TOP.rdl``, ``TOP.h``, ``TOP.md``); none by default.
    waivers : callable
        ``params -> str``, more Verilator waivers appended to ``TOP.vlt`` (a front end's own);
        none by default.
    app : callable or None
        ``spec -> {field: value}``: parameter values taken from a user's application, which
        the command line offers as ``--app SPEC`` (the UKF's ``module:Class``); raises
        ``ValueError`` with a one-line message for a bad spec. None (the default): no
        ``--app``.
    smoke : callable or None
        ``(params, manifest) -> plan`` of the self-checking smoke testbench ``TOP_tb.v`` that
        FuseSoC's ``sim`` target runs (:mod:`kfgen.gen.smoke` says what a plan holds: stream
        vectors from the golden model, or register reads). None: no testbench, no ``sim``
        target.

    A parameter whose default is ``True`` is a switch: the command line offers
    ``--no-<name>`` to turn it off.

    ``bench``, ``documents`` and ``smoke`` reach into ``gen`` and ``sim``, which
    ``hdl`` never imports: a descriptor leaves them out and :func:`kfgen.gen.cores.bind` fills
    them in (with the register map's manifest entries added to ``extra``).
    """

    name: str
    summary: str
    params: type
    docs: Callable[[], Mapping[str, Doc]]
    build: Callable
    fields_of: Callable
    extra: Callable = lambda params, component: {}
    examples: tuple = field(default=({},))
    bench: str | None = None
    documents: Callable = lambda params: {}
    waivers: Callable = lambda params: ""
    app: Callable | None = None
    smoke: Callable | None = None


_BUILT: dict[int, dict] = {}  # id(params) -> {function: what it built}, while the object lives


def once_per_params(build: Callable) -> Callable:
    """``build(params)`` built once per parameter object and reused (a core's register map,
    programs and machine): one generation builds each once, whoever asks for it (the
    parameters' own validation, the component, the manifest, the documents).

    Kept by the object's identity, not its value: a parameter object is frozen once
    validated, and validation may ask while it fills in the last derived field (the map's
    address width, which the map it builds already has). What was built is dropped with the
    object, and never pickled with it.
    """
    @functools.wraps(build)
    def built(params):
        key = id(params)
        memo = _BUILT.get(key)
        if memo is None:
            memo = _BUILT[key] = {}
            weakref.finalize(params, _BUILT.pop, key, None)
        if build not in memo:
            memo[build] = build(params)
        return memo[build]
    return built


#: Verilog-2005 (IEEE 1364-2005 Annex B) and SystemVerilog (IEEE 1800-2017 Annex B) keywords:
#: none may name a module, whichever language mode a user's tool reads the file in.
RESERVED_WORDS = frozenset("""
    accept_on alias always always_comb always_ff always_latch and assert assign assume automatic
    before begin bind bins binsof bit break buf bufif0 bufif1 byte case casex casez cell chandle
    checker class clocking cmos config const constraint context continue cover covergroup
    coverpoint cross deassign default defparam design disable dist do edge else end endcase
    endchecker endclass endclocking endconfig endfunction endgenerate endgroup endinterface
    endmodule endpackage endprimitive endprogram endproperty endspecify endsequence endtable
    endtask enum event eventually expect export extends extern final first_match for force
    foreach forever fork forkjoin function generate genvar global highz0 highz1 if iff ifnone
    ignore_bins illegal_bins implements implies import incdir include initial inout input inside
    instance int integer interconnect interface intersect join join_any join_none large let
    liblist library local localparam logic longint macromodule matches medium modport module nand
    negedge nettype new nexttime nmos nor noshowcancelled not notif0 notif1 null or output package
    packed parameter pmos posedge primitive priority program property protected pull0 pull1
    pulldown pullup pulsestyle_ondetect pulsestyle_onevent pure rand randc randcase randsequence
    rcmos real realtime ref reg reject_on release repeat restrict return rnmos rpmos rtran
    rtranif0 rtranif1 s_always s_eventually s_nexttime s_until s_until_with scalared sequence
    shortint shortreal showcancelled signed small soft solve specify specparam static string
    strong strong0 strong1 struct super supply0 supply1 sync_accept_on sync_reject_on table
    tagged task this throughout time timeprecision timeunit tran tranif0 tranif1 tri tri0 tri1
    triand trior trireg type typedef union unique unique0 unsigned until until_with untyped use
    uwire var vectored virtual void wait wait_order wand weak weak0 weak1 while wildcard wire with
    within wor xnor xor
""".split())

_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def check_name(name) -> None:
    """Raise :class:`ParamError` unless ``name`` can name a top-level Verilog module.

    Names that collide with the core's own ports or nets are found after generation
    (:func:`kfgen.gen.output.generate`), where they are known.
    """
    if not isinstance(name, str) or not _IDENTIFIER.fullmatch(name):
        raise ParamError("name", f"must be a Verilog identifier (a letter or _, then letters, digits or _), "
                                 f"not {name!r}")
    if name in RESERVED_WORDS:
        raise ParamError("name", f"{name!r} is a Verilog/SystemVerilog keyword; choose another module name")
