"""The linear Kalman filter core end to end: ``kfgen kf`` output (files, manifest, lint), then
one Verilator build (n = 4, m = 2, nu = 1, P = 2, with stream ports) driven through AXI4 by
cocotbext-axi (:mod:`kfgen.sim.kf.tb`): iterations with every word against the golden model
and the cycles against the manifest, the bus and fault cases, the stream ports; the
steady-gain core and larger ones in ``make test-full``."""

import json

import pytest

from kfgen.hdl.kf.params import KfParams
from kfgen.hdl.kf.steps import schedules
from kfgen.hdl.linalg.engine import OVERHEAD
from kfgen.hdl.linalg.schedule import chain_bound
from kfgen.sim.engine.run import build_core, run_tb
from kfgen.sim.kf.smoke import ITERATIONS
from kfgen.sim.kf.tb import TB_MODULE as TB
from kfgen.sim.toolchain import lint

from helpers import ENGINE_CAMPAIGN, VERILATOR_CACHE, iteration_cycles, kfgen, run_fault_campaign, run_shipped_testbench

SMALL = ["--states", "4", "--measurements", "2", "--inputs", "1", "--pes", "2", "--streams"]


@pytest.fixture(scope="module")
def rtl(build_root):
    out = build_root / "kf_core"
    kfgen("kf", *SMALL, "--name", "kf_small", "-o", out)
    return out


@pytest.mark.xdist_group("kf_core")
def test_files_and_manifest(rtl):
    names = {p.name for p in rtl.glob("kf_small.*")}
    assert {f"kf_small.{ext}" for ext in ("v", "vlt", "json", "rdl", "h", "md", "core", "xml")} <= names
    assert {"kf_small_driver.py", "kf_small_driver.h", "kf_small_driver.c"} <= {p.name for p in rtl.iterdir()}
    man = json.loads((rtl / "kf_small.json").read_text())
    params = KfParams(**man["parameters"])
    assert (params.n, params.m, params.nu, params.pes, params.streams) == (4, 2, 1, 2, True)
    sched = schedules(params)["iterate"]
    assert man["cycles"] == {"iterate": sched.cycles + OVERHEAD}
    assert man["bounds"]["chain"] == chain_bound(sched.program, sched.machine) <= sched.cycles
    assert man["bounds"]["fma"] == sched.program.fma_count
    assert man["bounds"]["fma_per_pe"] == -(-sched.program.fma_count // 2)
    assert {r["name"] for r in man["registers"]} == {"ID", "CTRL", "STATUS", "IRQ_ENABLE"}
    assert [m["name"] for m in man["memories"]] == ["x", "P", "F", "B", "Q", "H", "R", "z", "u"]
    assert {m["access"] for m in man["memories"]} == {"rw"}
    assert {f["name"] for f in man["registers"][1]["fields"]} == {"start", "reset"}
    assert [f["name"] for f in man["streams"]["s_axis"]["fields"]] == ["z[0]", "z[1]", "u[0]"]
    assert len(man["streams"]["m_axis"]["fields"]) == 8
    assert "#define" in (rtl / "kf_small.h").read_text()


@pytest.mark.xdist_group("kf_core")
def test_lint(rtl):
    rc, messages = lint(rtl / "kf_small.v")
    assert rc == 0 and not messages, "\n".join(messages)


@pytest.mark.xdist_group("kf_core")
@pytest.mark.full  # (make test runs the testbench on the small UKF cores: kfgen.gen.smoke is one for all)
@pytest.mark.parametrize("simulator", ["icarus", pytest.param("verilator", marks=pytest.mark.verilator)])
def test_shipped_testbench(rtl, tmp_path, simulator):
    """The shipped TOP_tb.v replays TOP_vectors.hex on the core (n = 4, m = 2, nu = 1): PASS,
    and each iteration's cycles printed as the manifest's (the testbench checks every start's)."""
    out = run_shipped_testbench(rtl, "kf_small", simulator, tmp_path)
    cycles = json.loads((rtl / "kf_small.json").read_text())["cycles"]["iterate"]
    assert iteration_cycles(out) == [cycles] * ITERATIONS


@pytest.fixture(scope="module")
def sim(rtl):
    return build_core(rtl, "kf_small", VERILATOR_CACHE)


@pytest.mark.verilator
@pytest.mark.xdist_group("kf_core")
def test_cocotb(rtl, sim):
    """Every case on the one build (n = 4, m = 2, nu = 1, P = 2, binary32, streams)."""
    run_tb(sim, rtl, "kf_small", TB, ["iterations", "errors", "stream_iterations", "python_driver", "c_driver"],
           "all")


@pytest.mark.verilator
@pytest.mark.xdist_group("kf_core")
@pytest.mark.parametrize("sequences", [ENGINE_CAMPAIGN[0], pytest.param(ENGINE_CAMPAIGN[1], marks=pytest.mark.full)])
def test_fault_campaign(rtl, sim, sequences):
    run_fault_campaign(sim, rtl, "kf_small", TB, sequences)


#: More configurations, one Verilator build each, in ``make test-full``: the steady gain (its
#: prologue after writes of F, B, H, K) with streams, the default core at P = 1 and 4, and
#: binary64 (two-word elements).
CONFIGURATIONS = [
    pytest.param(["--states", "3", "--measurements", "2", "--inputs", "1", "--steady-gain", "--streams"],
                 id="steady", marks=pytest.mark.full),
    pytest.param([], id="default", marks=pytest.mark.full),
    pytest.param(["--pes", "4"], id="p4", marks=pytest.mark.full),
    pytest.param(["--states", "3", "--measurements", "1", "--format", "binary64"], id="binary64",
                 marks=pytest.mark.full),
]


@pytest.mark.verilator
@pytest.mark.parametrize("args", CONFIGURATIONS)
def test_cocotb_configurations(request, build_root, args):
    top = "kf_" + request.node.callspec.id
    out = build_root / top
    kfgen("kf", *args, "--name", top, "-o", out)
    rc, messages = lint(out / f"{top}.v")
    assert rc == 0 and not messages, "\n".join(messages)
    model = build_core(out, top, VERILATOR_CACHE)
    tests = ["iterations", "errors", "c_driver"] + (["stream_iterations"] if "--streams" in args else [])
    run_tb(model, out, top, TB, tests, "all")
