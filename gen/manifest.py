"""The manifest (``TOP.json``): how a user or a testbench drives a generated core.

It is written beside the Verilog and read by the testbenches (``kfgen.sim.verilator`` and each core's runner), so
ports, widths and field formats are stated once. Key order is sorted and the port list is
in the Verilog port order, so the same parameters give the same bytes.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping

from amaranth.hdl import Value
from amaranth.lib import wiring

from . import __version__

__all__ = ["ports", "manifest", "dumps"]

#: A core's description of a port's packed fields, or ``None`` for a port without fields.
FieldsOf = Callable[[str], "list[dict] | None"]


def ports(component: wiring.Component, fields_of: FieldsOf) -> list[dict]:
    """Every Verilog port of ``component``: ``clk``, ``rst``, then its signature's members.

    Raises ``ValueError`` when the fields ``fields_of`` gives for a port do not fit its width,
    which means the parameter object and the core disagree.
    """
    out = [{"name": "clk", "direction": "input", "width": 1},
           {"name": "rst", "direction": "input", "width": 1}]
    for path, member, value in component.signature.flatten(component):
        name = "__".join(map(str, path))
        port = {"name": name, "direction": "input" if member.flow == wiring.In else "output",
                "width": len(Value.cast(value))}
        fields = fields_of(name)
        if fields:
            used = 0
            for f in fields:
                if f["lsb"] < used or f["lsb"] + f["width"] > port["width"]:
                    raise ValueError(f"field {f['name']!r} of {name} (lsb {f['lsb']}, width {f['width']}) "
                                     f"does not fit the {port['width']}-bit port after bit {used}")
                used = f["lsb"] + f["width"]
            if used != port["width"]:
                raise ValueError(f"the fields of {name} cover {used} bits, the port has {port['width']}")
            port["fields"] = [dict(f) for f in fields]
        out.append(port)
    return out


def manifest(core: str, top: str, parameters: Mapping[str, object], component: wiring.Component,
             fields_of: FieldsOf, extra: Mapping[str, object] = ()) -> dict:
    """The manifest of one generated core.

    ``component`` supplies the ports, ``latency`` and ``initiation_interval``; ``extra`` adds
    core-specific entries (``track_interval_cycles`` for Castella).
    """
    data = {
        "core": core,
        "top": top,
        "generator": {"name": "kfgen", "version": __version__},
        "parameters": dict(parameters),
        "latency_cycles": component.latency,
        "initiation_interval": component.initiation_interval,
        "ports": ports(component, fields_of),
    }
    data.update(extra)
    return data


def dumps(data: dict) -> str:
    """Stable JSON text: sorted keys, two-space indent, a final newline."""
    return json.dumps(data, sort_keys=True, indent=2, ensure_ascii=False, allow_nan=False) + "\n"
