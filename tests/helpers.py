"""What tests share beyond fixtures: the ``kfgen`` command (installed, or in process), the
work directories, and drivers for Amaranth's simulator. ``tests/`` is on ``sys.path`` (pytest
puts the root ``conftest.py``'s folder there), so a test imports them as ``from helpers import
kfgen``; :mod:`conftest` keeps only pytest's hooks and fixtures."""

import contextlib
import io
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from amaranth.sim import Simulator

ROOT = Path(__file__).resolve().parent.parent
# KFGEN_TEST_BUILD moves the work files (for runs side by side in one checkout).
BUILD = Path(os.environ.get("KFGEN_TEST_BUILD", ROOT / "build" / "tests")).resolve()
# Verilator builds shared by every test and pytest-xdist worker, keyed by sources and flags
# (kfgen.sim.verilator.build locks each while it is built).
VERILATOR_CACHE = BUILD / "verilator"


def kfgen(*args, check=True, env=None):
    """Run the installed ``kfgen`` command line; returns the CompletedProcess."""
    exe = Path(sys.executable).parent / "kfgen"
    proc = subprocess.run([str(exe), *map(str, args)], capture_output=True, text=True, env=env)
    if check and proc.returncode != 0:
        raise AssertionError(f"kfgen {' '.join(map(str, args))} failed ({proc.returncode}): {proc.stderr}")
    return proc


def kfgen_in_process(*args):
    """``kfgen ARGS`` through the command line's own ``main`` in this process (no interpreter
    and Amaranth start-up, 0.6 s a call): the CompletedProcess the installed command would
    give. For the many rejected-argument cases and the lint pool's generation; tests that
    run the installed command keep the entry point itself under test."""
    from kfgen.gen.cli import main

    with contextlib.redirect_stdout(io.StringIO()) as out, contextlib.redirect_stderr(io.StringIO()) as err:
        code = main([str(a) for a in args])
    return subprocess.CompletedProcess(["kfgen", *map(str, args)], code, out.getvalue(), err.getvalue())


# ---------------------------------------------------------------- Amaranth simulator helpers

def run_comb(m, inputs, outputs, vectors):
    """Drive ``vectors`` (tuples for ``inputs``) and collect ``outputs`` after settling."""
    got = []

    async def tb(ctx):
        for vec in vectors:
            for s, v in zip(inputs, vec):
                ctx.set(s, v)
            got.append(tuple(ctx.get(o) for o in outputs))

    sim = Simulator(m)
    sim.add_testbench(tb)
    sim.run()
    return got


def run_staged(m, inputs, out, vectors):
    """Drive ``vectors`` (tuples for ``inputs``) one a clock and collect the ``Staged`` value
    ``out``, ``out.stage`` clocks later."""
    got = []

    async def tb(ctx):
        for i in range(len(vectors) + out.stage):
            if i < len(vectors):
                for s, v in zip(inputs, vectors[i]):
                    ctx.set(s, v)
            if i >= out.stage:
                got.append(ctx.get(out.sig))
            await ctx.tick()

    sim = Simulator(m)
    sim.add_clock(1e-8)
    sim.add_testbench(tb)
    sim.run()
    return got


def simulate_fpu_cores(build_root, name, units, model):
    """Generate each ``prefix: (op, format, subnormals, operands)`` core (``operands``: word
    lists ``a`` [, ``b``]), run them side by side in one Verilator build under cocotb
    (:func:`kfgen.sim.fpu.run.run_fpu_group`) and check every word and flag against
    ``model(op, format, operands, subnormals) -> (words, flags)``."""
    from kfgen.sim.fpu.run import run_fpu_group
    root = build_root / "fpu" / name
    spec = {}
    for prefix, (op, fmt, subnormals, operands) in units.items():
        top = f"u_{name}_{prefix}"
        kfgen("fpu", "--op", op, "--format", fmt, "--subnormals", subnormals, "--name", top, "-o", root / top)
        y, flags = model(op, fmt, operands, subnormals)
        spec[prefix] = (root / top, top, operands, ([int(v) for v in y], [int(v) for v in flags]))
    results = run_fpu_group(root / "sim_build", spec, gap=0.2, seed=7, name=name, cache_dir=VERILATOR_CACHE,
                            waves=bool(os.environ.get("KFGEN_WAVES")))
    for prefix, (_, _, _, (y, flags)) in spec.items():
        assert [int(v) for v in results[prefix]["y"]] == y, prefix
        assert [int(v) for v in results[prefix]["flags"]] == flags, prefix


#: Fault campaign sequences of the engine cores (:mod:`kfgen.sim.engine.campaign`): make test runs
#: the first, make test-full the second (pytest parameters of ``sequences``).
ENGINE_CAMPAIGN = (20, 10_000)


def run_fault_campaign(model, rtl, top, module, sequences):
    """The ``fault_campaign`` of testbench ``module`` on an engine core's build: seeded random bus traffic,
    starts, soft and bus resets, each sequence followed by a clean iteration against the golden
    model (calm: no per-clock monitor, the campaign checks every response itself)."""
    from kfgen.sim.engine.run import run_tb

    run_tb(model, rtl, top, module, ["fault_campaign"], f"campaign_{sequences}",
           env={"KFGEN_TB_CALM": "1", "KFGEN_TB_SEQUENCES": str(sequences), "KFGEN_TB_SEED": str(sequences)})


#: A test module's marks (``pytestmark``) that fail each of its tests on an Amaranth
#: elaboratable it built and never elaborated: ``UnusedElaboratable`` is an error, and so is
#: the unraisable exception it becomes in ``__del__``, where Amaranth raises it, and the test
#: ends with a collection (``elaboratables_collected``, tests/common/conftest.py).
EVERY_ELABORATABLE_USED = [
    pytest.mark.filterwarnings("error::amaranth.hdl.UnusedElaboratable"),
    pytest.mark.filterwarnings("error::pytest.PytestUnraisableExceptionWarning"),
    pytest.mark.usefixtures("elaboratables_collected"),
]


def python_driver(directory, core_name, **params):
    """Core ``core_name``'s manifest with ``params`` (the component built, no Verilog emitted:
    a fraction of a second) and its generated ``TOP_driver.py`` (:mod:`kfgen.gen.pydriver`),
    written into ``directory`` and imported: (manifest, module)."""
    import importlib.util

    from kfgen.gen.cores import discover
    from kfgen.gen.manifest import manifest
    from kfgen.gen.output import recorded
    from kfgen.gen.pydriver import files

    core = discover()[core_name]
    p = core.params(**params)
    component = core.build(p)
    man = manifest(core.name, p.name, recorded(p), component, lambda port: core.fields_of(p, port),
                   core.extra(p, component))
    (path, text), = files(p.name, man).items()
    (Path(directory) / path).write_text(text)
    spec = importlib.util.spec_from_file_location(Path(path).stem, Path(directory) / path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return man, module


class GoldenRun:
    """The golden model driven by hand: region writes rounded by the simulation's own
    ``to_words``, starts run by the programs (with their prologue). What a driver's accesses
    must leave in the core's memory (``mem``)."""

    def __init__(self, programs):
        from kfgen.sim.engine.prologue import Prologue

        self.programs = programs
        self.mem = programs.layout.initial_memory()
        self.prologue = Prologue(programs)

    def write(self, name, values):
        import numpy as np

        from kfgen.sim.linalg.exec import to_words

        reg = self.programs.layout[name]
        self.mem[reg.base:reg.base + reg.size] = to_words(self.programs.fmt, np.ravel(values))
        self.prologue.wrote(name)

    def run(self, step):
        return self.prologue.run(step, self.mem)


def shipped_testbench_runner(simulator):
    """``run(directory, top, work, vectors=None, build=True)`` of the core's ``TOP_tb.v`` in
    ``simulator`` (``"icarus"``, or ``"verilator"``: its build cached in :data:`VERILATOR_CACHE`)."""
    from functools import partial

    from kfgen.sim.toolchain import run_testbench_icarus, run_testbench_verilator

    return {"icarus": run_testbench_icarus,
            "verilator": partial(run_testbench_verilator, cache=VERILATOR_CACHE)}[simulator]


def run_shipped_testbench(directory, top, simulator, work, vectors=None, build=True):
    """Run the core's self-checking ``TOP_tb.v`` (:func:`shipped_testbench_runner`) and hold it to
    PASS: exit status 0, its ``PASS: TOP: `` line and no FAIL. The testbench's output."""
    proc = shipped_testbench_runner(simulator)(directory, top, work, vectors, build=build)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0 and f"\nPASS: {top}: " in "\n" + proc.stdout and "FAIL" not in out, out[-3000:]
    return proc.stdout


def iteration_cycles(out) -> list[int]:
    """The cycles of each iteration a shipped testbench's output prints (``iteration K: C
    cycles``), checked numbered 0, 1, ... in order."""
    found = re.findall(r"^iteration (\d+): (\d+) cycles$", out, re.M)
    assert [int(k) for k, _ in found] == list(range(len(found))), found
    return [int(c) for _, c in found]


def planted_bug(vectors, out, op):
    """A copy of ``vectors`` (a ``TOP_vectors.hex``) at ``out`` with one word wrong: the
    golden model's data of its last read (``op`` ``"read"``: the estimate's last word), or the
    cycles of its first start (``"start"``, one more). The line changed, as it was."""
    from kfgen.sim.engine.script import READ, START

    code = {"read": READ, "start": START}[op]
    lines = vectors.read_text().splitlines()
    at = [k for k, line in enumerate(lines) if not line.startswith("//") and int(line.split()[0], 16) == code]
    k = at[-1] if op == "read" else at[0]
    words = lines[k].split()
    if op == "read":
        words[2] = f"{int(words[2], 16) ^ 1 << 9:08x}"
    else:
        words[3] = f"{int(words[3], 16) + 1:08x}"
    was, lines[k] = lines[k], " ".join(words)
    out.write_text("\n".join(lines) + "\n")
    return was


def c_driver(directory, core_name, **params):
    """Core ``core_name``'s manifest with ``params`` (as :func:`python_driver`) and its generated
    C driver (``TOP.h``, ``TOP_driver.h``, ``TOP_driver.c``, :mod:`kfgen.gen.cdriver`) written
    into ``directory`` and compiled with its MMIO hooks under the driver's promised flags
    (:func:`kfgen.sim.engine.run.build_driver`): (manifest, the library's path)."""
    from kfgen.gen.cores import discover
    from kfgen.sim.engine.run import build_driver

    man, _ = python_driver(directory, core_name, **params)
    core = discover()[core_name]
    p = core.params(**params)
    for name, text in core.documents(p).items():
        (Path(directory) / name).write_text(text)
    return man, build_driver(directory, p.name)
