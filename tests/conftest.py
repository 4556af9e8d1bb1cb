import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
# KFGEN_TEST_BUILD moves the work files (for runs side by side in one checkout).
BUILD = Path(os.environ.get("KFGEN_TEST_BUILD", ROOT / "build" / "tests")).resolve()


def pytest_addoption(parser):
    parser.addoption("--full", action="store_true", help="also run the long sweeps (make test-full)")


def pytest_collection_modifyitems(config, items):
    # Long sweeps are deselected, not skipped, from the default regression.
    if config.getoption("--full"):
        return
    keep = [it for it in items if "full" not in it.keywords]
    dropped = [it for it in items if "full" in it.keywords]
    if dropped:
        config.hook.pytest_deselected(items=dropped)
        items[:] = keep


def kfgen(*args, check=True):
    """Run the installed ``kfgen`` command line; returns the CompletedProcess."""
    exe = Path(sys.executable).parent / "kfgen"
    proc = subprocess.run([str(exe), *map(str, args)], capture_output=True, text=True)
    if check and proc.returncode != 0:
        raise AssertionError(f"kfgen {' '.join(map(str, args))} failed ({proc.returncode}): {proc.stderr}")
    return proc


@pytest.fixture(scope="session")
def build_root():
    BUILD.mkdir(parents=True, exist_ok=True)
    return BUILD
