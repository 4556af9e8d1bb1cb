"""Generated Schur-complement units in Verilator under cocotb, bit for bit against the golden
model (:func:`kfgen.sim.schur.model.golden`), several configurations in one build.

Each core gets the status cases (zero, negative and -0 pivots, a singular and an indefinite
Schur complement, NaNs and infinities in every position) and then a shuffle of
positive-definite matrices, symmetric matrices of random sign and random words; the first
matrices stream with no idle cycle and no backpressure (exact latency and initiation interval),
the rest with random input gaps and heavy backpressure on ``m_axis``, which fills the FIFO
and holds ``s_axis_tready`` low.
"""

import json
import os

import numpy as np
import pytest

from kfgen.gen.cli import main
from kfgen.hdl.schur.params import SchurParams
from kfgen.sim.schur.model import stimulus
from kfgen.sim.schur.run import run_schur_group
from kfgen.sim.toolchain import lint

from helpers import VERILATOR_CACHE

pytestmark = pytest.mark.verilator

# name: (command-line options, matrices in the default run)
CONFIGS = {
    # the default core: binary32, every unit pipelined, one matrix a clock
    "schur": ([], 200),
    # the slides' third row: multiplier 3, adder 7, a divider of 26 cycles an operation, latency 27
    "schur_row3": (["--mul-latency", 3, "--add-latency", 7, "--div-cycles-per-op", 26, "--div-latency", 27], 60),
    # the slides' first row (its divider latency 14 is 15 here, the least a 14-cycle divider has)
    "schur_row1": (["--mul-latency", 1, "--add-latency", 1, "--div-cycles-per-op", 14, "--div-latency", 15], 200),
    "schur_d4": (["--size", 4, "--format", "binary16"], 300),
    "schur_b64": (["--format", "binary64"], 300),
    "schur_d3": (["--size", 3, "--format", "e6m11", "--div-cycles-per-op", 4], 200),
}
GROUPS = {
    "schur_default": ("schur",),
    "schur_more": ("schur_row3", "schur_row1", "schur_d4", "schur_b64", "schur_d3"),
}


def _generate(build_root, top):
    """``kfgen schur OPTIONS --name TOP -o DIR``, in this process (the command line's own
    tests run it as a command)."""
    out = build_root / "schur" / top
    assert main(["schur", *map(str, CONFIGS[top][0]), "--name", top, "-o", str(out)]) == 0
    return out, json.loads((out / f"{top}.json").read_text())


def _run(build_root, group, scale=1, seed=1):
    """Generate, lint and simulate the cores of ``group``; every result is checked in the
    testbench. Returns ``{top: (manifest, record)}``."""
    cores, manifests = {}, {}
    for k, top in enumerate(GROUPS[group]):
        out, man = _generate(build_root, top)
        rc, messages = lint(out / f"{top}.v")
        assert rc == 0 and not messages, "\n".join(messages)
        p = SchurParams(**man["parameters"])
        matrices = stimulus(p.fmt, p.d, CONFIGS[top][1] * scale, np.random.default_rng(seed * 100 + k))
        cores[top], manifests[top] = (out, top, matrices), man
    results = run_schur_group(build_root / "schur" / f"{group}_run{seed}", cores, calm=40, gap=0.2, stall=0.8,
                              seed=seed, name=group, cache_dir=VERILATOR_CACHE,
                              waves=bool(os.environ.get("KFGEN_WAVES")))
    return {top: (manifests[top], results[top]) for top in cores}


def _check_rates(man, rec):
    """What the testbench did not already check: the stream waited on both sides, and never
    took matrices closer than the initiation interval."""
    assert rec["m_axis_waits"] > 0, "m_axis never waited: no backpressure was exercised"
    ii = man["initiation_interval"]
    assert np.min(np.diff(rec["in_cycle"])) == ii
    if ii == 1:
        assert rec["s_axis_waits"] > 0, "the FIFO never filled: s_axis_tready never fell"


@pytest.mark.xdist_group("schur_default")
def test_schur_default(build_root):
    """The default core: binary32, pipelined, one matrix a clock. (An iterative divider's
    initiation interval is checked in every run in Amaranth's simulator, test_schur_core, and
    in Verilator by the configurations below, in make test-full.)"""
    for top, (man, rec) in _run(build_root, "schur_default").items():
        _check_rates(man, rec)


@pytest.mark.full
@pytest.mark.xdist_group("schur_default")
def test_schur_default_long(build_root):
    _run(build_root, "schur_default", scale=20, seed=2)


@pytest.mark.full
@pytest.mark.xdist_group("schur_more")
def test_schur_more_configurations(build_root):
    """The slides' third and first rows (iterative dividers of 26 and 14 cycles), d = 4 in
    binary16, binary64, and d = 3 in e6m11 with a 4-cycle divider, in one build."""
    for top, (man, rec) in _run(build_root, "schur_more", scale=3).items():
        _check_rates(man, rec)


#: Fault campaign sequences: make test runs the first, make test-full the second.
CAMPAIGN = [pytest.param(20, id="20"), pytest.param(10_000, id="10000", marks=pytest.mark.full)]


@pytest.mark.xdist_group("schur_default")
@pytest.mark.parametrize("sequences", CAMPAIGN)
def test_schur_fault_campaign(build_root, sequences):
    """The default unit: random traffic cut by resets at random cycles, each sequence followed
    by a clean run of 8 matrices (4 calm: exact latency and interval) against the golden model
    (:func:`kfgen.sim.schur.tb.fault_campaign`)."""
    out, man = _generate(build_root, "schur")
    p = SchurParams(**man["parameters"])
    matrices = stimulus(p.fmt, p.d, 8, np.random.default_rng(sequences))
    run_schur_group(build_root / "schur" / f"campaign_{sequences}", {"schur": (out, "schur", matrices)},
                    calm=4, gap=0.2, stall=0.5, seed=sequences, name="schur_default", cache_dir=VERILATOR_CACHE,
                    test="fault_campaign", env={"KFGEN_TB_SEQUENCES": str(sequences)})
