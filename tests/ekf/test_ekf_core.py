"""The EKF core end to end: ``kfgen ekf --app`` output (files, manifest, lint, bad values), then
ONE small Verilator build (the tracker at P = 2, with stream ports) driven through AXI4 by
cocotbext-axi (:mod:`kfgen.sim.ekf.tb`) and shared by every cocotb case: the tracker's
scenario with every word against the golden model and the cycles against the manifest, the
bus and fault cases, err_pivot, the stream ports and the fault campaign."""

import json
import re

import pytest

from kfgen.hdl.ekf.params import EkfParams
from kfgen.hdl.ekf.steps import schedules
from kfgen.hdl.linalg.engine import OVERHEAD
from kfgen.hdl.linalg.schedule import chain_bound
from kfgen.sim.ekf.smoke import ITERATIONS
from kfgen.sim.engine.run import build_core, run_tb
from kfgen.sim.toolchain import lint

from helpers import (ENGINE_CAMPAIGN, VERILATOR_CACHE, iteration_cycles, kfgen, kfgen_in_process, run_fault_campaign,
                     run_shipped_testbench)

TB = "kfgen.sim.ekf.tb"
TOP = "ekf_small"
SMALL = ["--app", "tracker:Tracker", "--pes", "2", "--streams"]

#: A model that does not differentiate (np.maximum), and one whose R is not positive definite.
BAD_APPS = '''
import numpy as np
from kfgen.hdl.engine.app import UkfApplication


class Clip(UkfApplication):
    n, nw, nv, m = 2, 2, 1, 1
    dt = 0.1
    x0 = np.array([0.5, -0.2])
    P0 = np.eye(2)
    Q = np.eye(2) * 1e-3
    R = np.eye(1) * 1e-2

    def f(self, x, w, u, dt):
        return np.array([x[0] + dt * x[1], np.maximum(x[1], 0.0)]) + w

    def h(self, x, v):
        return np.array([x[0]]) + v


class Indefinite(Clip):
    R = -np.eye(1)
'''


@pytest.fixture(scope="module")
def rtl(build_root):
    out = build_root / "ekf_core"
    kfgen("ekf", *SMALL, "--name", TOP, "-o", out)
    return out


@pytest.mark.xdist_group("ekf_core")
def test_files_and_manifest(rtl):
    names = sorted(p.name for p in rtl.glob(f"{TOP}*"))
    assert names == sorted([f"{TOP}.{ext}" for ext in ("v", "vlt", "json", "rdl", "h", "md", "core", "xdc", "sdc",
                                                       "xml")] + [f"{TOP}_ip.tcl", f"{TOP}_tb.v", f"{TOP}_vectors.hex",
                                                                   f"{TOP}_driver.py", f"{TOP}_driver.h", f"{TOP}_driver.c"])
    man = json.loads((rtl / f"{TOP}.json").read_text())
    params = EkfParams(**man["parameters"])
    assert params.sizes == (4, 2, 2, 2, 0) and params.pes == 2 and params.app == "tracker:Tracker"
    sched = schedules(params)["iterate"]
    assert man["cycles"] == {"iterate": sched.cycles + OVERHEAD}
    assert man["bounds"]["chain"] == chain_bound(sched.program, sched.machine) <= sched.cycles
    assert [m["name"] for m in man["memories"]] == ["x", "P", "Q", "R", "z"]
    assert {f["name"] for f in man["registers"][1]["fields"]} == {"start", "reset"}
    jac = man["jacobians"]
    assert jac["F"] == {"shape": [4, 4], "nonzero": 6, "constant": 6, "fma_dense": 40, "fma_sparse": 0}
    assert jac["H"]["nonzero"] == 4 and jac["H"]["fma_sparse"] < jac["H"]["fma_dense"]
    assert man["streams"]["latency_cycles"] == man["cycles"]["iterate"] + 2 + 8 + 4
    assert "#define" in (rtl / f"{TOP}.h").read_text()
    rc, messages = lint(rtl / f"{TOP}.v")
    assert rc == 0 and not messages, "\n".join(messages)


@pytest.mark.xdist_group("ekf_core")
@pytest.mark.full  # (make test runs the testbench on the small UKF cores: kfgen.gen.smoke is one for all)
@pytest.mark.parametrize("simulator", ["icarus", pytest.param("verilator", marks=pytest.mark.verilator)])
def test_shipped_testbench(rtl, tmp_path, simulator):
    """The shipped TOP_tb.v replays TOP_vectors.hex on the core (the tracker's scenario): PASS,
    and each iteration's cycles printed as the manifest's (the testbench checks every start's)."""
    out = run_shipped_testbench(rtl, TOP, simulator, tmp_path)
    cycles = json.loads((rtl / f"{TOP}.json").read_text())["cycles"]["iterate"]
    assert iteration_cycles(out) == [cycles] * ITERATIONS


@pytest.mark.parametrize("args,says", [
    (["--pes", "0"], "--pes: "),
    (["--banks", "1"], "--banks: "),
    (["--div-sqrt", "fast"], "--div-sqrt: "),
    (["--format", "binary128"], "--format: "),
    (["--address-width", "5"], "--address-width: "),
    (["--states", "5"], "--app: tracker:Tracker has n, nw, nv, m, nu = (4, 2, 2, 2, 0)"),
])
def test_bad_values_exit_2(tmp_path, args, says):
    proc = kfgen_in_process("ekf", "--app", "tracker:Tracker", *args, "-o", tmp_path / "x")
    assert proc.returncode == 2 and proc.stderr.startswith(f"kfgen: error: {says}")
    assert proc.stderr.count("\n") == 1 and not (tmp_path / "x").exists()


@pytest.mark.parametrize("cls,says", [
    ("Clip", r"--app: Clip.f does not differentiate \(.*bad_apps.py:\d+\): max \(np.maximum"),
    ("Indefinite", r"--app: Indefinite.R must be positive definite"),
    (None, r"--app: the EKF differentiates an application's f and h: give --app"),
])
def test_bad_application_refused_before_any_build(tmp_path, cls, says):
    (tmp_path / "bad_apps.py").write_text(BAD_APPS)
    app = [] if cls is None else ["--app", f"{tmp_path / 'bad_apps.py'}:{cls}"]
    proc = kfgen_in_process("ekf", *app, "-o", tmp_path / "x")
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert re.match(f"kfgen: error: {says}", proc.stderr), proc.stderr
    assert not (tmp_path / "x").exists()


@pytest.fixture(scope="module")
def sim(rtl):
    return build_core(rtl, TOP, VERILATOR_CACHE)


@pytest.mark.verilator
@pytest.mark.xdist_group("ekf_core")
def test_cocotb(rtl, sim):
    """The tracker's scenario over the bus, the bus and fault cases with err_pivot, the
    stream ports and the generated C driver, on the one build (n = 4, m = 2, P = 2, binary32)."""
    run_tb(sim, rtl, TOP, TB, ["iterations", "errors", "stream_iterations", "c_driver"], "all")


@pytest.mark.verilator
@pytest.mark.full
@pytest.mark.xdist_group("ekf_core")
def test_python_driver(rtl, sim):
    """The generated Python driver on the one build (kfgen.sim.ekf.tb.python_driver)."""
    run_tb(sim, rtl, TOP, TB, ["python_driver"], "python_driver")


@pytest.mark.verilator
@pytest.mark.xdist_group("ekf_core")
@pytest.mark.parametrize("sequences", [ENGINE_CAMPAIGN[0], pytest.param(ENGINE_CAMPAIGN[1], marks=pytest.mark.full)])
def test_fault_campaign(rtl, sim, sequences):
    run_fault_campaign(sim, rtl, TOP, TB, sequences)
