"""Finds the cores: every ``descriptor`` module under :mod:`kfgen.hdl` that defines ``CORE``.

The command line, the manifest writer, ``make verilog`` (:mod:`kfgen.gen.examples`) and
``make bench`` (:mod:`kfgen.gen.bench`) all take their list of cores from :func:`discover`,
so a new core is a new package with a ``descriptor`` module and nothing else to register.
"""

from __future__ import annotations

import importlib
import pkgutil
from functools import cache

import kfgen.hdl

from kfgen.hdl.describe import CoreDescriptor

__all__ = ["discover"]


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
        found[core.name] = core
    return dict(sorted(found.items()))
