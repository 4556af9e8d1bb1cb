"""pytest's hooks and fixtures for the whole tree; the helpers tests import (the ``kfgen``
command, the build directories, Amaranth simulator drivers) live in :mod:`helpers`."""

import os

import pytest

from helpers import BUILD


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


@pytest.fixture(scope="session")
def build_root():
    """This process's work directory: under pytest-xdist each worker has its own, so two
    workers never generate into one directory."""
    root = BUILD / os.environ.get("PYTEST_XDIST_WORKER", "")
    root.mkdir(parents=True, exist_ok=True)
    return root
