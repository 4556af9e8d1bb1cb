"""Every core's benchmark, one table after another: ``python -m kfgen.gen.bench [CORE ...]``.

Each core's descriptor names its bench module (``CoreDescriptor.bench``); ``make bench`` runs
them all, ``python -m kfgen.gen.bench fpu`` one. The shared synthesis and place-and-route
helpers are in :mod:`kfgen.gen.synth`.
"""

from __future__ import annotations

import importlib
import sys

from .cores import discover

__all__ = ["main"]


def main(argv=None) -> int:
    names = list(sys.argv[1:] if argv is None else argv)
    cores = {name: core for name, core in discover().items() if core.bench}
    unknown = [n for n in names if n not in cores]
    if unknown:
        print(f"bench: unknown core {unknown[0]!r}; cores with a bench: {', '.join(cores)}", file=sys.stderr)
        return 2
    status = 0
    for name in names or cores:
        print(f"\n## {name}\n", flush=True)
        status |= importlib.import_module(cores[name].bench).main([])
    return status


if __name__ == "__main__":
    sys.exit(main())
