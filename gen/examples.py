"""``make verilog``: every core's example configurations, ``python -m kfgen.gen.examples [OUT]``.

Each core's descriptor lists them (``CoreDescriptor.examples``); each is written, as ``kfgen
CORE ... -o OUT/<name>`` would, into ``OUT/<name>/`` (default ``out/``).
"""

from __future__ import annotations

import sys
from pathlib import Path

from .output import generate, write_files
from .cores import discover

__all__ = ["main"]


def main(argv=None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if len(args) > 1:
        print("usage: python -m kfgen.gen.examples [OUT]", file=sys.stderr)
        return 2
    out = Path(args[0] if args else "out")
    for core in discover().values():
        for example in core.examples:
            params = core.params(**example)
            for path in write_files(out / params.name, generate(core, params)):
                print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
