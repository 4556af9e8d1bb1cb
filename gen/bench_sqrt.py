"""The UKF's square-root form (``kfgen ukf --form sqrt``) beside the chapter's ldl form:
``python -m kfgen.gen.bench_sqrt`` (part 6 of ``python -m kfgen.gen.bench ukf``).

1. Cycles per iteration at P = 1, 2 and 10 (the manifests' schedules), for the three-step
   core (sig_gen + predict + update) and the on-chip nanosatellite core, with the FMAs, the
   chain bound and the ratio to the ldl form.
2. Xilinx 7 resources (Yosys ``synth_xilinx``) and ECP5-85 Fmax (nextpnr, median of the
   seeds) of the on-chip nanosatellite core in both forms at P = 1 and 2.
3. The nanosatellite with the printed P0 = I over 100 seeds x 1000 iterations in binary32,
   binary16 and bfloat16, both forms (:mod:`kfgen.sim.ukf.montecarlo`).

``--target-mhz F`` builds the cores of parts 1 and 2 for that clock (``kfgen ukf --target-mhz
F``); the Monte Carlo runs the golden model, which does not depend on it.
"""

from __future__ import annotations

import argparse
import io
import sys
import time
from contextlib import redirect_stdout
from pathlib import Path

from kfgen.hdl.linalg.engine import overhead
from kfgen.hdl.linalg.schedule import chain_bound
from kfgen.hdl.ukf.descriptor import CORE
from kfgen.hdl.ukf.params import UkfParams
from kfgen.hdl.ukf.steps import machine, programs, schedules
from kfgen.sim.cluster import add_arguments, collect, failed, shared
from kfgen.sim.ukf import montecarlo
from kfgen.sim.ukf.app import load_app

from .synth import add_target_arguments, ecp5_fmax, md_table, resolve_freq, target_tag, write_cores, xilinx_task

__all__ = ["cycle_rows", "cycles_table", "main"]

FORMS = ("ldl", "sqrt")

#: The application of the on-chip cores: the chapter's nanosatellite, whose ldl core is also
#: part 5 of :mod:`.bench_ukf` (which runs this bench as its part 6, and imports this).
ON_CHIP_APP = "nanosat:Nanosat"


def cycle_rows(pes=(1, 2, 10), target_mhz: float | None = None) -> list[dict]:
    """Per P and form: the three-step core's step cycles and the on-chip core's iteration, as
    their manifests give them (``cycles``), for the cores' ``target_mhz``."""
    sizes = load_app(ON_CHIP_APP).core_parameters()
    rows = []
    for p in pes:
        for form in FORMS:
            three = UkfParams(**sizes, pes=p, form=form, target_mhz=target_mhz)
            chip = UkfParams(**sizes, pes=p, form=form, app=ON_CHIP_APP, on_chip=True, target_mhz=target_mhz)
            s3, sc = schedules(three), schedules(chip)
            progs, mc = programs(chip), machine(chip)
            it, extra = progs.iteration, overhead(mc)
            rows.append({"pes": p, "form": form,  # the manifests' cycles: the schedules' and the engine's overhead
                         "steps": {k: s.cycles + extra for k, s in s3.items()},
                         "iteration": sc["iteration"].cycles + extra, "noise": sc["noise"].cycles + extra,
                         "fmas": it.fma_count, "chain": chain_bound(it, mc)})
    return rows


def cycles_table(rows: list[dict]) -> str:
    ldl = {(r["pes"]): r for r in rows if r["form"] == "ldl"}
    head = ["P", "form", "sig_gen", "predict", "update", "three steps", "/ ldl", "on chip: iteration", "/ ldl",
            "FMAs", "chain bound", "/ max(FMAs / P, chain)", "noise (after a Q or R write)"]
    out = []
    for r in rows:
        st = r["steps"]
        three = st["sig_gen"] + st["predict"] + st["update"]
        base = ldl[r["pes"]]
        b3 = sum(base["steps"][k] for k in ("sig_gen", "predict", "update"))
        out.append([str(r["pes"]), r["form"], *(f"{st[k]:,}" for k in ("sig_gen", "predict", "update")),
                    f"{three:,}", f"{three / b3:.2f}", f"{r['iteration']:,}", f"{r['iteration'] / base['iteration']:.2f}",
                    f"{r['fmas']:,}", f"{r['chain']:,}",
                    f"{r['iteration'] / max(r['fmas'] / r['pes'], r['chain']):.2f}",
                    f"{r['noise']:,}" if "noise" in st or r["form"] == "sqrt" else f"{r['noise']:,} (on chip)"])
    return md_table(head, out)


def synth_rows(pes, out: Path, seeds, freq: float, runner, fmax: bool = True, forms=FORMS,
               target_mhz: float | None = None, done: dict | None = None) -> list[dict]:
    """Part 2's rows: each P's on-chip core in each form, synthesised and placed; the ldl rows
    of ``done`` (P -> a row of ``bench_ukf``'s part 5, the same core already synthesised and
    placed with the same seeds and target) as they are."""
    sizes = load_app(ON_CHIP_APP).core_parameters()
    rows, configs = [], []
    for p in pes:
        for form in forms:
            if form == "ldl" and p in (done or {}):
                rows.append({**done[p], "form": form, "reused": True})
                continue
            configs.append(UkfParams(**sizes, pes=p, form=form, app=ON_CHIP_APP, on_chip=True, target_mhz=target_mhz,
                                     name=f"ukf_oc_{form}_p{p}{target_tag(target_mhz)}"))
            rows.append({"pes": p, "form": form, "top": configs[-1].name})
    new = [r for r in rows if not r.get("reused")]
    for r, (work, manifest) in zip(new, write_cores(CORE, configs, out, runner)):
        r.update(work=work, iteration=manifest["cycles"]["iteration"])
    jobs = [(r, "xilinx", xilinx_task(runner, r["work"], r["top"])) for r in new[::-1]]
    if fmax:
        jobs += [(r, "ecp5", ecp5_fmax(r["work"], r["top"], freq, tuple(seeds), runner=runner)) for r in new[::-1]]
    collect(jobs, label=lambda r: f"P = {r['pes']} {r['form']}", tool="bench_sqrt")
    return rows


def synth_table(rows: list[dict]) -> str:
    head = ["P", "form", "iteration (cycles)", "Xilinx 7 LUT (as RAM)", "FF", "DSP48E1", "BRAM (36 Kb)",
            "ECP5 Fmax (MHz), median", "ECP5 LUT4", "iteration at Fmax (us)"]
    out = []
    for r in rows:
        f = r.get("fmax_mhz")
        lut = f"{r['lut']:,} ({r['lut_memory']:,})" if "lut" in r else r.get("xilinx_error", "-")
        out.append([str(r["pes"]), r["form"], f"{r['iteration']:,}", lut, f"{r.get('ff', 0):,}",
                    str(r.get("dsp", "-")), f"{r['bram36']:g}" if "bram36" in r else "-",
                    f"{f:.1f}" if f else r.get("ecp5_error", "-"),
                    f"{r.get('utilization', {}).get('TRELLIS_COMB', 0):,}",
                    f"{r['iteration'] / f:.1f}" if f else "-"])
    return md_table(head, out)


def main(argv=None, ldl: dict | None = None) -> int:
    """The command; ``ldl``: :func:`synth_rows`' ``done`` (``bench_ukf`` passes its part 5's
    nanosatellite rows, so that the full bench does not synthesise and place them twice)."""
    ap = argparse.ArgumentParser(prog="python -m kfgen.gen.bench_sqrt", description=__doc__.split("\n\n")[0])
    ap.add_argument("--synth-pes", default="1,2", help="P of the synthesised cores (default 1,2)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3], help="nextpnr seeds (default 1 2 3)")
    add_target_arguments(ap, 100.0)
    ap.add_argument("--synth-forms", default="ldl,sqrt",
                    help="forms synthesised (default ldl,sqrt; the ldl core is part 5's of bench_ukf, whose figures "
                         "python -m kfgen.gen.bench ukf takes instead of synthesising it again)")
    ap.add_argument("--no-synth", action="store_true", help="skip part 2 (synthesis, place and route)")
    ap.add_argument("--no-fmax", action="store_true", help="skip place and route")
    ap.add_argument("--no-montecarlo", action="store_true", help="skip part 3 (the 100-seed runs)")
    ap.add_argument("--mc-seeds", type=int, default=100, help="Monte Carlo seeds (default 100)")
    ap.add_argument("-o", "--out", default="build/bench_sqrt", help="work directory (default build/bench_sqrt)")
    add_arguments(ap)
    a = ap.parse_args(argv)
    resolve_freq(a)
    try:
        synth_pes = sorted({int(x) for x in a.synth_pes.split(",")})
    except ValueError:
        print(f"bench_sqrt: --synth-pes takes P values separated by commas, not {a.synth_pes!r}", file=sys.stderr)
        return 2
    out = Path(a.out).resolve()
    t0 = time.monotonic()
    report = ("The square-root form (kfgen ukf --form sqrt) beside the ldl form: cycles per iteration, "
              "nanosatellite sizes (n = 7, m = 6, nw = 7, nv = 6)"
              + (f", --target-mhz {a.target_mhz:g}" if a.target_mhz else "") + ":\n\n"
              + cycles_table(cycle_rows(target_mhz=a.target_mhz)) + "\n")
    status = 0
    with shared(a) as runner:
        if not a.no_synth:
            rows = synth_rows(synth_pes, out, a.seeds, a.freq, runner, not a.no_fmax, a.synth_forms.split(","),
                              a.target_mhz, ldl)
            reused = [str(r["pes"]) for r in rows if r.get("reused")]
            report += ("\nThe on-chip nanosatellite core in both forms (Yosys synth_xilinx; nextpnr-ecp5, median of "
                       f"seeds {' '.join(map(str, a.seeds))}):\n\n" + synth_table(rows) + "\n"
                       + (f"\n* The ldl rows at P = {', '.join(reused)} are part 5's cores (the same core, synthesised "
                          "and placed there once).\n" if reused else ""))
            status |= failed(rows)
        if not a.no_montecarlo:  # on the same runner
            buf = io.StringIO()
            with redirect_stdout(buf):
                status |= montecarlo.main(["--seeds", str(a.mc_seeds)])
            report += "\n" + buf.getvalue()
    report += f"\n(bench_sqrt: {time.monotonic() - t0:.0f} s)\n"
    print(report, end="")
    out.mkdir(parents=True, exist_ok=True)
    (out / "bench_sqrt.md").write_text(report)
    return int(bool(status))


if __name__ == "__main__":
    sys.exit(main())
