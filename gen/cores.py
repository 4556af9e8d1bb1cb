"""Finds the cores: every ``descriptor`` module under :mod:`kfgen.hdl` that defines ``CORE``,
and binds to each what lives above ``hdl`` (which imports neither ``gen`` nor ``sim``): its
bench module, its smoke-test plan, the documents and manifest entries made from its register
map.

The command line, the manifest writer, ``make verilog`` (:mod:`kfgen.gen.examples`) and
``make bench`` (:mod:`kfgen.gen.bench`) all take their list of cores from :func:`discover`,
so a new core is a new package with a ``descriptor`` module, and its line in :data:`_HOOKS`
when it has a bench, a smoke test or a register map.
"""

from __future__ import annotations

import dataclasses
import importlib
import pkgutil
from functools import cache

import kfgen.hdl

from kfgen.hdl.describe import CoreDescriptor
from kfgen.hdl.ekf.regmap import ekf_map
from kfgen.hdl.imm.regmap import imm_map
from kfgen.hdl.kf.regmap import kf_map
from kfgen.hdl.ukf.core import stream_spec
from kfgen.hdl.ukf.regmap import ukf_map
from kfgen.hdl.ukf.steps import programs

from .cdriver import ekf_driver, id_fields, imm_driver, kf_driver, ukf_driver
from .regdoc import documents, map_manifest

__all__ = ["discover", "bind"]


@cache
def discover() -> dict[str, CoreDescriptor]:
    """Core name -> descriptor, sorted by name."""
    found = {}
    for info in pkgutil.walk_packages(kfgen.hdl.__path__, "kfgen.hdl."):
        if info.name.rsplit(".", 1)[-1] != "descriptor":
            continue
        core = getattr(importlib.import_module(info.name), "CORE", None)
        if not isinstance(core, CoreDescriptor):
            continue
        if core.name in found:
            raise RuntimeError(f"two cores are named {core.name!r}: {info.name} and another descriptor")
        found[core.name] = bind(core)
    return dict(sorted(found.items()))


def _smoke(module):
    def plan(params, manifest):
        return importlib.import_module(module).smoke_plan(params, manifest)
    return plan


def _with_map(extra):
    """``extra`` with the register map's manifest entries (the component's ``regmap``)."""
    def with_map(params, component):
        return {**map_manifest(component.regmap), **extra(params, component)}
    return with_map


def _map_documents(regmap, more=lambda params: {}):
    """``TOP.rdl``, ``TOP.h``, ``TOP.md`` of the map ``regmap(params)``, and ``more``."""
    def with_more(params):
        return {**documents(regmap(params), params.name), **more(params)}
    return with_more


def _ukf_driver(params):
    return ukf_driver(params.name, params.format.name)


def _imm_driver(params):
    return imm_driver(params.name, params.format.name, id_fields(imm_map(params)))


def _kf_driver(params):
    return kf_driver(params.name, params.fmt.name, id_fields(kf_map(params)), params.steady_gain)


def _ekf_driver(params):
    return ekf_driver(params.name, params.fmt.name, id_fields(ekf_map(params)))


def _ukf_documents(params):
    """The UKF's map documents and C driver; with stream ports, their fields in ``TOP.md``
    and as ``TOP_S_AXIS_*``/``TOP_M_AXIS_*`` macros in the driver's header."""
    docs = _map_documents(ukf_map, _ukf_driver)(params)
    if not params.streams:
        return docs
    spec = stream_spec(params, programs(params))
    top, width = params.name, params.fmt.width
    md = ["", "## Stream ports", "",
          "One `s_axis` transfer is one measurement: the core writes it into `z` (and `u`), runs `iteration` "
          "and puts the estimate on `m_axis` (`m_axis_tuser`: bit 0 err_pivot, bit 1 err_nan). Each field is "
          f"one element of {params.format}, in {spec.field_bits} bits (the rest zero).", "",
          "| port | field | bits |", "|---|---|---|"]
    macros = ["", "/* Stream ports (--streams): each field's lowest bit in tdata; every field is "
              f"{width} bits wide in a {spec.field_bits}-bit slot. */",
              f"#define {top.upper()}_S_AXIS_TDATA_WIDTH {spec.in_width}u",
              f"#define {top.upper()}_M_AXIS_TDATA_WIDTH {spec.out_width}u"]
    for port, fields in spec.fields().items():
        for name, lo in fields:
            md.append(f"| `{port}_tdata` | {name} | {lo + width - 1}:{lo} |")
            ident = name.upper().replace("[", "").replace("]", "").replace(",", "_")
            macros.append(f"#define {top.upper()}_{port.upper()}_{ident}_LSB {lo}u")
    docs[f"{top}.md"] = docs[f"{top}.md"].rstrip("\n") + "\n" + "\n".join(md) + "\n"
    header = f"{top}_driver.h"
    if header in docs:
        text = docs[header]
        at = text.rindex("#ifdef __cplusplus")
        docs[header] = text[:at] + "\n".join(macros).lstrip("\n") + "\n\n" + text[at:]
    return docs


#: Per core: descriptor fields bound here, or (for ``extra``) a wrapper of the descriptor's own.
_HOOKS = {
    "castella": {"bench": "kfgen.gen.bench_castella", "smoke": _smoke("kfgen.sim.castella.smoke")},
    "fpu": {"bench": "kfgen.gen.bench_fpu", "smoke": _smoke("kfgen.sim.fpu.smoke")},
    "schur": {"bench": "kfgen.gen.bench_schur", "smoke": _smoke("kfgen.sim.schur.smoke")},
    "ukf": {"bench": "kfgen.gen.bench_ukf", "smoke": _smoke("kfgen.sim.ukf.smoke"),
            "documents": _ukf_documents, "extra": _with_map},
    "imm": {"bench": "kfgen.gen.bench_imm", "smoke": _smoke("kfgen.sim.imm.smoke"),
            "documents": _map_documents(imm_map, _imm_driver), "extra": _with_map},
    "kf": {"bench": "kfgen.gen.bench_kf", "smoke": _smoke("kfgen.sim.kf.smoke"), "documents": _map_documents(kf_map, _kf_driver),
           "extra": _with_map},
    "ekf": {"bench": "kfgen.gen.bench_ekf", "smoke": _smoke("kfgen.sim.ekf.smoke"), "documents": _map_documents(ekf_map, _ekf_driver),
            "extra": _with_map},
}

_BOUND: dict[str, CoreDescriptor] = {}  # core name -> its bound descriptor


def bind(core: CoreDescriptor) -> CoreDescriptor:
    """``core`` (a descriptor as ``hdl`` declares it) with its hooks of :data:`_HOOKS`; a bound
    descriptor is returned as it is."""
    if _BOUND.get(core.name) is core:
        return core
    hooks = dict(_HOOKS.get(core.name, {}))
    if "extra" in hooks:
        hooks["extra"] = hooks["extra"](core.extra)
    bound = dataclasses.replace(core, **hooks)
    _BOUND[core.name] = bound
    return bound
