import contextlib
import io
import os
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


def pytest_addoption(parser):
    parser.addoption("--full", action="store_true", help="also run the long sweeps (make test-full)")


def pytest_collection_modifyitems(config, items):
    # Verilator tests (minutes each) first: started last, one would leave the other
    # pytest-xdist worker idle at the end. The sort is stable, so every worker agrees.
    # Tests that share a module-scoped fixture (a generated core, a synthesis) or a Verilator
    # build carry one xdist_group, so that one worker makes it (tests/test_xdist_groups.py).
    items.sort(key=lambda it: "verilator" not in it.keywords)
    # Long sweeps are deselected, not skipped, from the default regression.
    if config.getoption("--full"):
        return
    keep = [it for it in items if "full" not in it.keywords]
    dropped = [it for it in items if "full" in it.keywords]
    if dropped:
        config.hook.pytest_deselected(items=dropped)
        items[:] = keep


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


@pytest.fixture(scope="session")
def build_root():
    """This process's work directory: under pytest-xdist each worker has its own, so two
    workers never generate into one directory."""
    root = BUILD / os.environ.get("PYTEST_XDIST_WORKER", "")
    root.mkdir(parents=True, exist_ok=True)
    return root


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
