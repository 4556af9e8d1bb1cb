"""Generation time and peak memory of the engine cores against P: ``python -m kfgen.gen.bench_gen``.

Each row runs ``kfgen CORE --pes P -o DIR`` as a subprocess and reports its wall time and its
peak resident memory, children (Yosys) included: ``wait4``'s maximum RSS of the child, which
Linux folds its own reaped children into. The CLI refuses, at validation, what would not fit
in :data:`LIMIT_SECONDS` and :data:`LIMIT_MB` (:func:`kfgen.hdl.engine.params.check_generation`);
this table is the measurement those limits rest on. ``make bench`` prints it after the UKF's
and the IMM's own tables.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

__all__ = ["LIMIT_SECONDS", "LIMIT_MB", "ROWS", "measure", "table", "main"]

#: The acceptance rule every configuration the CLI accepts keeps on a two-core machine.
LIMIT_SECONDS = 60
LIMIT_MB = 2048

#: (core, extra arguments, P values): the defaults' sizes, P up to the largest accepted.
ROWS = {
    "ukf": ([], (1, 2, 4, 8, 16)),
    "imm": ([], (1, 2, 4, 8)),
}


def measure(argv: list[str], out: str) -> dict:
    """Run ``kfgen ARGV -o OUT``; its exit code, wall seconds and peak RSS in MB (children included)."""
    cmd = [sys.executable, "-c", "import sys; from kfgen.gen.cli import main; sys.exit(main())", *argv, "-o", out]
    t0 = time.monotonic()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    seconds = time.monotonic() - t0
    err = proc.stderr.read().decode(errors="replace").strip().splitlines()
    proc.stderr.close()
    proc.returncode = os.waitstatus_to_exitcode(status)
    return {"code": proc.returncode, "seconds": seconds, "mb": usage.ru_maxrss / 1024,
            "error": err[-1] if proc.returncode and err else ""}


def table(rows: dict = ROWS) -> tuple[str, bool]:
    """The markdown table and whether every row generated within the limits."""
    lines = [f"Generation of the engine cores against P (`kfgen CORE --pes P`, wall time and peak RSS with "
             f"Yosys; limit {LIMIT_SECONDS} s and {LIMIT_MB} MB):", "",
             "| core | P | seconds | peak MB | within the limits |", "|---|---|---|---|---|"]
    ok = True
    with tempfile.TemporaryDirectory(prefix="bench_gen_") as tmp:
        for core, (extra, pes) in rows.items():
            for p in pes:
                r = measure([core, *extra, "--pes", str(p)], os.path.join(tmp, f"{core}_p{p}"))
                fits = r["code"] == 0 and r["seconds"] < LIMIT_SECONDS and r["mb"] < LIMIT_MB
                ok &= fits
                note = "yes" if fits else f"no (exit {r['code']}{': ' + r['error'] if r['error'] else ''})"
                lines.append(f"| {core} | {p} | {r['seconds']:.1f} | {r['mb']:.0f} | {note} |")
                print(f"bench_gen: {core} P = {p} done", file=sys.stderr, flush=True)
    return "\n".join(lines) + "\n", ok


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m kfgen.gen.bench_gen", description=__doc__.splitlines()[0])
    ap.add_argument("cores", nargs="*", help=f"cores to measure: {', '.join(ROWS)} (default: all)")
    args = ap.parse_args(argv)
    for c in args.cores:
        if c not in ROWS:
            ap.error(f"unknown core {c!r}; cores: {', '.join(ROWS)}")
    report, ok = table({c: ROWS[c] for c in (args.cores or ROWS)})
    print(report, end="")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
