"""The IMM core end to end: ``kfgen imm`` output (files, manifest, lint, bad values), then
Verilator builds driven through AXI4 by cocotbext-axi (:mod:`kfgen.sim.imm.tb`): iterations
with every word against the golden model and the cycles against the manifest, an outlier
measurement, and the bus and fault cases."""

import json

import pytest

from kfgen.hdl.imm.params import ImmParams
from kfgen.hdl.imm.steps import schedules
from kfgen.hdl.linalg.engine import OVERHEAD
from kfgen.hdl.linalg.schedule import chain_bound
from kfgen.sim.toolchain import lint
from kfgen.sim.engine.run import build_core, run_tb
from kfgen.sim.imm.run import TB
from kfgen.sim.imm.smoke import ITERATIONS

from helpers import (ENGINE_CAMPAIGN, VERILATOR_CACHE, iteration_cycles, kfgen, kfgen_in_process, run_fault_campaign,
                     run_shipped_testbench)

SMALL = ["--models", "3", "--states", "2", "--measurements", "2", "--pes", "2"]


@pytest.fixture(scope="module")
def rtl(build_root):
    out = build_root / "imm_core"
    kfgen("imm", *SMALL, "--name", "imm_small", "-o", out)
    return out


@pytest.mark.xdist_group("imm_core")
def test_files_and_manifest(rtl):
    names = sorted(p.name for p in rtl.glob("imm_small.*"))
    assert names == sorted(f"imm_small.{ext}" for ext in ("v", "vlt", "json", "rdl", "h", "md", "core", "xdc", "sdc",
                                                                  "xml"))
    man = json.loads((rtl / "imm_small.json").read_text())
    params = ImmParams(**man["parameters"])
    assert (params.R, params.n, params.d, params.pes) == (3, 2, 2, 2)
    sched = schedules(params)["iterate"]
    assert man["cycles"] == {"iterate": sched.cycles + OVERHEAD}
    assert man["bounds"]["chain"] == chain_bound(sched.program, sched.machine) <= sched.cycles
    assert man["bounds"]["fma"] == sched.program.fma_count
    assert {r["name"] for r in man["registers"]} == {"ID", "CTRL", "STATUS", "IRQ_ENABLE"}
    assert [m["name"] for m in man["memories"]] == ["pi", "mu", "F", "Q", "H", "R", "x_model", "P_model", "z",
                                                    "x", "P"]
    access = {m["name"]: m["access"] for m in man["memories"]}
    assert access["x"] == access["P"] == "ro" and access["mu"] == "rw"
    assert {f["name"] for f in man["registers"][1]["fields"]} == {"start", "reset"}
    assert "#define" in (rtl / "imm_small.h").read_text()


@pytest.mark.xdist_group("imm_core")
def test_lint(rtl):
    rc, messages = lint(rtl / "imm_small.v")
    assert rc == 0 and not messages, "\n".join(messages)


@pytest.mark.xdist_group("imm_core")
@pytest.mark.full  # (make test runs the testbench on the small UKF cores: kfgen.gen.smoke is one for all)
@pytest.mark.parametrize("simulator", ["icarus", pytest.param("verilator", marks=pytest.mark.verilator)])
def test_shipped_testbench(rtl, tmp_path, simulator):
    """The shipped TOP_tb.v replays TOP_vectors.hex on the core (R = 3, n = 2, d = 2): PASS,
    and each iteration's cycles printed as the manifest's (the testbench checks every start's)."""
    out = run_shipped_testbench(rtl, "imm_small", simulator, tmp_path)
    cycles = json.loads((rtl / "imm_small.json").read_text())["cycles"]["iterate"]
    assert iteration_cycles(out) == [cycles] * ITERATIONS


@pytest.mark.parametrize("args,says", [
    (["--models", "1"], "--models: "),
    (["--states", "0"], "--states: "),
    (["--measurements", "9"], "--measurements: "),
    (["--pes", "0"], "--pes: "),
    (["--banks", "1"], "--banks: "),
    (["--div-sqrt", "fast"], "--div-sqrt: "),
    (["--format", "binary128"], "--format: "),
    (["--address-width", "5"], "--address-width: "),
])
def test_bad_values_exit_2(tmp_path, args, says):
    proc = kfgen_in_process("imm", *args, "-o", tmp_path / "x")
    assert proc.returncode == 2 and proc.stderr.startswith(f"kfgen: error: {says}")
    assert proc.stderr.count("\n") == 1 and not (tmp_path / "x").exists()


@pytest.fixture(scope="module")
def sim(rtl):
    return build_core(rtl, "imm_small", VERILATOR_CACHE)


@pytest.mark.verilator
@pytest.mark.xdist_group("imm_core")
@pytest.mark.parametrize("tests", [["iterations"], ["errors"], pytest.param(["python_driver"], marks=pytest.mark.full)],
                         ids=lambda t: t[0])
def test_cocotb(rtl, sim, tests):
    """Both cases on one build (R = 3, n = 2, d = 2, P = 2, binary32)."""
    run_tb(sim, rtl, "imm_small", TB, tests, tests[0])


#: More configurations, one Verilator build each, in ``make test-full`` (the default core's
#: build alone takes about two minutes): the slides' scenario size (R = 5, n = 6, d = 2: the
#: default core) at P = 1 and 4, d = 3 (the Schur graph's odd split) in binary64, and
#: binary16. (``make plots`` and the drift test run the default size at P = 4 too.)
CONFIGURATIONS = [
    pytest.param([], id="default", marks=pytest.mark.full),
    pytest.param(["--pes", "4"], id="p4", marks=pytest.mark.full),
    pytest.param(["--models", "2", "--states", "3", "--measurements", "3", "--format", "binary64"],
                 id="d3_binary64", marks=pytest.mark.full),
    pytest.param([*SMALL, "--format", "binary16"], id="small_binary16", marks=pytest.mark.full),
    # --target-mhz above the engine's clock: deeper units (the exponential too) and the fetch register
    pytest.param([*SMALL, "--target-mhz", "125"], id="small_t125", marks=pytest.mark.full),
]


@pytest.mark.verilator
@pytest.mark.parametrize("args", CONFIGURATIONS)
def test_cocotb_configurations(request, build_root, args):
    top = "imm_" + request.node.callspec.id
    out = build_root / top
    kfgen("imm", *args, "--name", top, "-o", out)
    rc, messages = lint(out / f"{top}.v")
    assert rc == 0 and not messages, "\n".join(messages)
    model = build_core(out, top, VERILATOR_CACHE)
    run_tb(model, out, top, TB, ["iterations", "errors"], "all")



@pytest.mark.verilator
@pytest.mark.xdist_group("imm_core")
@pytest.mark.parametrize("sequences", [ENGINE_CAMPAIGN[0], pytest.param(ENGINE_CAMPAIGN[1], marks=pytest.mark.full)])
def test_fault_campaign(rtl, sim, sequences):
    run_fault_campaign(sim, rtl, "imm_small", TB, sequences)
