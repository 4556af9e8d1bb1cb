"""Cycles of the linear Kalman filter core against AMD Vitis Vision's ``xf::cv::KalmanFilter``:
``python -m kfgen.gen.bench_kf``.

Each row is an iteration's cycles as the manifest gives them (the schedule's count and the
engine's overhead, :func:`kfgen.hdl.kf.steps.schedules`), beside the program's multiply-adds
over P and the dependency-chain bound, and the microseconds at 100 MHz and at
:data:`ENGINE_FMAX_MHZ`. Nothing is generated or synthesised: the schedule is the count (the
Verilator testbench, ``tests/kf/test_kf_core.py``, asserts the RTL takes exactly the
manifest's cycles). Rows beyond what generates (m = nu = 16 at n = 16: 35,104 multiply-adds,
above :data:`kfgen.hdl.engine.params.GEN_WORK_MAX`) are the same programs scheduled on the
same machine, marked so.

Vitis' figure: 0.55 ms an iteration at 300 MHz for N_STATE = 16; this module takes it to be
the 16 x 16 x 16 configuration (N_STATE = M_MEAS = C_CTRL = 16) that Vitis Vision's resource
table lists, an assumption (its documentation gives the latency, not the breakdown).
"""

from __future__ import annotations

import argparse
import sys

from kfgen.hdl.engine.machine import machine
from kfgen.hdl.engine.machine import schedules as engine_schedules
from kfgen.hdl.engine.params import GEN_WORK_MAX, generation_work
from kfgen.hdl.kf.params import KfParams
from kfgen.hdl.kf.programs import KfSizes, build_kf
from kfgen.hdl.linalg.engine import OVERHEAD
from kfgen.hdl.linalg.schedule import chain_bound

__all__ = ["VITIS_US", "ENGINE_FMAX_MHZ", "CONFIGS", "row", "table", "main"]

#: Vitis Vision KalmanFilter, N_STATE = 16 (taken as 16 x 16 x 16), an iteration at 300 MHz.
VITIS_US = 550.0
#: The engine's lowest measured ECP5-85 Fmax (nextpnr, seed 1): the IMM core at P = 1
#: (README.md; the UKF's engine cores measure 98.6-109.3 MHz at P = 1 and 2, the default KF
#: core 108.2 MHz at P = 1, seed 1, docs/kf.md): the n = 16, P = 4 cores were not placed.
ENGINE_FMAX_MHZ = 95.8

#: (n, m, nu, P, steady gain) of the table.
CONFIGS = (
    (4, 2, 1, 1, False), (4, 2, 1, 2, False), (4, 2, 1, 4, False),
    (16, 2, 1, 1, False), (16, 2, 1, 2, False), (16, 2, 1, 4, False),
    (16, 16, 16, 4, False),
    (16, 2, 1, 4, True),
)


def row(n: int, m: int, nu: int, pes: int, steady: bool = False) -> dict:
    """One configuration's iteration: cycles (the manifest's), multiply-adds, the chain bound,
    and whether it generates."""
    progs = build_kf(KfSizes(n, m, nu, steady), "binary32")
    fma = progs.iterate.fma_count
    generates = generation_work(sum(p.fma_count for p in progs.steps.values()), pes) <= GEN_WORK_MAX
    # the machine of KfParams at this P (a small core: the machine depends on P and its defaults only)
    mc = machine(KfParams(pes=pes))
    sched = engine_schedules({"iterate": progs.iterate}, mc)["iterate"]
    return {"n": n, "m": m, "nu": nu, "pes": pes, "steady": steady, "cycles": sched.cycles + OVERHEAD,
            "fma": fma, "chain": chain_bound(sched.program, mc), "generates": generates}


def table(configs=CONFIGS) -> str:
    """The Markdown table of ``configs``."""
    lines = ["| n | m | nu | P | update | cycles | FMAs / P | chain | us at 100 MHz | us at "
             f"{ENGINE_FMAX_MHZ} MHz | Vitis ({VITIS_US:g} us) / ours at {ENGINE_FMAX_MHZ} MHz |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for cfg in configs:
        r = row(*cfg)
        fmax_us = r["cycles"] / ENGINE_FMAX_MHZ
        vs = f"{VITIS_US / fmax_us:.1f}x" if r["n"] == 16 else "-"
        lines.append(f"| {r['n']} | {r['m']} | {r['nu']} | {r['pes']} | {'steady gain' if r['steady'] else 'Joseph'} "
                     f"| {r['cycles']:,}{'' if r['generates'] else ' (not generated)'} "
                     f"| {-(-r['fma'] // r['pes']):,} | {r['chain']:,} | {r['cycles'] / 100:.1f} | {fmax_us:.1f} "
                     f"| {vs} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m kfgen.gen.bench_kf", description=__doc__.splitlines()[0])
    ap.add_argument("--small", action="store_true", help="n = 4 only (seconds, not a minute)")
    args = ap.parse_args(argv)
    print(table([c for c in CONFIGS if c[0] == 4] if args.small else CONFIGS))
    return 0


if __name__ == "__main__":
    sys.exit(main())
