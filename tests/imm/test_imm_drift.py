"""The IMM core on the slides' satellite-link scenario: the golden model (bit-exact with the
RTL, :mod:`kfgen.sim.imm.tb`) against the float64 reference, and in ``make test-full`` the
RTL itself over several thousand steps: how far its probabilities and state drift from
float64, and whether its most probable model stays the same."""

import json

import numpy as np
import pytest

from kfgen.sim.imm.golden import run_golden
from kfgen.sim.imm.reference import run_reference
from kfgen.sim.imm.scenario import satlink

from helpers import VERILATOR_CACHE


def drift(trace: dict, ref, condition) -> dict:
    """How far ``trace`` (mu, x) is from the float64 run ``ref``, and how often their most
    probable models agree (and are the true condition)."""
    mu, x = trace["mu"], trace["x"]
    T = len(mu)
    same = np.argmax(mu, 1) == np.argmax(ref.mu[:T], 1)
    return {"steps": T, "mu_max_abs": float(np.max(np.abs(mu - ref.mu[:T]))),
            "mu_mean_abs": float(np.mean(np.abs(mu - ref.mu[:T]))),
            "x_max_abs_dB": float(np.max(np.abs(x - ref.x[:T])[:, [0, 3]])),
            "same_most_probable": float(np.mean(same)),
            "identification": float(np.mean(np.argmax(mu, 1) == condition[:T])),
            "identification_float64": float(np.mean(np.argmax(ref.mu[:T], 1) == condition[:T]))}


@pytest.fixture(scope="module")
def scenario():
    return satlink(3000)


@pytest.fixture(scope="module")
def reference(scenario):
    sc = scenario
    return run_reference(sc.system, sc.mu0, sc.xs0, sc.Ps0, sc.zs)


def test_golden_model_against_float64(scenario, reference):
    """120 steps of the binary32 golden model: a distribution at every step, no fault, the
    same most probable model as float64 at nearly every step, probabilities within 1e-3."""
    sc = scenario
    gold = run_golden(sc.system, sc.mu0, sc.xs0, sc.Ps0, sc.zs[:120])
    assert not gold["flags"].any()
    assert np.allclose(gold["mu"].sum(1), 1, atol=1e-5)
    d = drift(gold, reference, sc.condition)
    assert d["same_most_probable"] >= 0.98 and d["mu_max_abs"] < 1e-2, d
    assert d["x_max_abs_dB"] < 0.05, d


@pytest.mark.full
@pytest.mark.verilator
def test_rtl_drift_over_thousands_of_steps(build_root, scenario, reference):
    """3000 steps of the scenario through the RTL core (P = 4), every word checked against the
    golden model by the testbench; then its drift from float64, written to
    ``imm_drift.json`` in the build directory."""
    from kfgen.gen.cosim import imm_scenario

    trace = imm_scenario(build_root / "imm_drift", 3000, pes=4, cache_dir=VERILATOR_CACHE)
    d = drift(trace, reference, scenario.condition)
    (build_root / "imm_drift.json").write_text(json.dumps(d, indent=2) + "\n")
    print("IMM RTL (binary32) against float64 over the scenario:", json.dumps(d))
    assert d["same_most_probable"] >= 0.99, d
    assert d["mu_mean_abs"] < 1e-3, d
