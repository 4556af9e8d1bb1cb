"""Every core's benchmark, one table after another: ``python -m kfgen.gen.bench [CORE ...]``.

Each core's descriptor names its bench module (``CoreDescriptor.bench``), and
:data:`ACROSS_CORES` the benches of several cores side by side (``filters``: choosing a filter,
:mod:`kfgen.gen.bench_filters`); ``make bench`` runs them all, ``python -m kfgen.gen.bench fpu``
one. Their jobs run as tasks on one Dask cluster
(:mod:`kfgen.sim.cluster`): a ``LocalCluster`` sized to the machine, ``--scheduler ADDRESS``
for one a user runs, or ``--serial`` in this process. The shared synthesis and
place-and-route helpers are in :mod:`kfgen.gen.synth`.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import time

from kfgen.sim.cluster import add_arguments, shared

from .cores import discover

__all__ = ["main", "ACROSS_CORES"]

#: Benches of several cores side by side, after the cores' own: name -> module.
ACROSS_CORES = {"filters": "kfgen.gen.bench_filters"}


def main(argv=None) -> int:
    cores = {name: core.bench for name, core in discover().items() if core.bench} | ACROSS_CORES
    ap = argparse.ArgumentParser(prog="python -m kfgen.gen.bench", description=__doc__.split("\n\n")[0])
    ap.add_argument("cores", nargs="*", metavar="CORE", help=f"cores to bench (default all: {', '.join(cores)})")
    add_arguments(ap)
    args = ap.parse_args(sys.argv[1:] if argv is None else argv)
    unknown = [n for n in args.cores if n not in cores]
    if unknown:
        print(f"bench: unknown core {unknown[0]!r}; cores with a bench: {', '.join(cores)}", file=sys.stderr)
        return 2
    status = 0
    t0 = time.monotonic()
    with shared(args) as runner:
        for name in args.cores or cores:
            print(f"\n## {name}\n", flush=True)
            t1 = time.monotonic()
            status |= importlib.import_module(cores[name]).main([])
            print(f"\nbench: {name} in {time.monotonic() - t1:,.0f} s", flush=True)
        print(f"\nbench: {', '.join(args.cores or cores)} in {time.monotonic() - t0:,.0f} s on {runner.where}",
              flush=True)
    return status


if __name__ == "__main__":
    sys.exit(main())
