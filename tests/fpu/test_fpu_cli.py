"""`kfgen fpu`: parameters, errors, manifest, and the generated Verilog in Icarus and Verilator."""

import json
import subprocess

import pytest

from kfgen.hdl.arith.float.params import OPS, FpuParams
from kfgen.sim.toolchain import iverilog, run_verilator

from conftest import kfgen


@pytest.mark.parametrize("args,param", [
    (["--op", "pow"], "--op"),
    (["--format", "binary128"], "--format"),
    (["--format", "e2m10"], "--format"),
    (["--subnormals", "daz"], "--subnormals"),
    (["--op", "add", "--cycles-per-op", "2"], "--cycles-per-op"),
    (["--op", "div", "--cycles-per-op", "0"], "--cycles-per-op"),
    (["--stages", "0"], "--stages"),
    (["--stages", "99"], "--stages"),
    (["--stages", "two"], "--stages"),
    (["--name", "9x"], "--name"),
])
def test_bad_parameters_exit_2_with_one_line(tmp_path, args, param):
    proc = kfgen("fpu", *args, "-o", tmp_path, check=False)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"kfgen: error: {param}:"), proc.stderr
    assert "Traceback" not in proc.stderr and not list(tmp_path.iterdir())


@pytest.mark.parametrize("op", list(OPS))
def test_manifest_matches_the_unit(tmp_path, op):
    kfgen("fpu", "--op", op, "--format", "binary16", "--name", f"u_{op}", "-o", tmp_path)
    man = json.loads((tmp_path / f"u_{op}.json").read_text())
    unit = FpuParams(op=op, format="binary16").build()
    assert man["latency_cycles"] == unit.latency
    assert man["initiation_interval"] == unit.initiation_interval == 1
    ports = {p["name"]: p for p in man["ports"]}
    assert set(ports) >= {"clk", "rst", "i_valid", "i_a", "o_valid", "o_y", "o_flags"}
    assert ("i_b" in ports) == (op in ("add", "sub", "mul", "div", "fma"))
    assert ("i_c" in ports) == (op == "fma") and "i_ready" not in ports
    assert [f["name"] for f in ports["o_flags"]["fields"]] == ["NX", "UF", "OF", "DZ", "NV"]
    a_field, y_field = ports["i_a"]["fields"][0], ports["o_y"]["fields"][0]
    assert (a_field.get("format") == "binary16") == (op != "i2f")
    assert (y_field.get("format") == "binary16") == (op != "f2i")
    assert ports["i_a"]["width"] == (32 if op == "i2f" else 16)
    assert ports["o_y"]["width"] == (32 if op == "f2i" else 16)


def test_iterative_divider_has_ready_and_exact_interval(tmp_path):
    kfgen("fpu", "--op", "div", "--cycles-per-op", "4", "--name", "d4", "-o", tmp_path)
    man = json.loads((tmp_path / "d4.json").read_text())
    assert man["initiation_interval"] == 4
    assert {"name": "i_ready", "direction": "output", "width": 1} in man["ports"]


def test_deterministic(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    for out in (a, b):
        kfgen("fpu", "--op", "fma", "--name", "f", "-o", out)
    for name in ("f.v", "f.vlt", "f.json"):
        assert (a / name).read_bytes() == (b / name).read_bytes()
        assert str(tmp_path) not in (a / name).read_text()


@pytest.mark.parametrize("args", [["--op", "add"], ["--op", "mul"], ["--op", "fma"], ["--op", "div"],
                                  ["--op", "sqrt", "--cycles-per-op", "4"], ["--op", "i2f"], ["--op", "f2i"],
                                  ["--op", "add", "--subnormals", "ftz"]])
def test_icarus_compiles(tmp_path, args):
    kfgen("fpu", *args, "--name", "u", "-o", tmp_path)
    ic = subprocess.run([iverilog(), "-g2012", "-o", str(tmp_path / "u.vvp"), str(tmp_path / "u.v")],
                        capture_output=True, text=True)
    assert ic.returncode == 0, ic.stderr


def _min_stages(op):
    return min(s for s in FpuParams(op=op).build().PLANS if s >= 1)


#: Cores linted: every operation's default, then other formats (a constant exponent and a padded
#: significand in i2f binary64, the split leading-zero count of fma), the fewest stages (the
#: most logic between registers, where Yosys folds the most), ftz, and iterative cores.
LINT_CONFIGS = {
    **{op: ["--op", op] for op in OPS},
    **{f"{op}_{fmt}": ["--op", op, "--format", fmt] for op, fmt in [
        ("add", "binary16"), ("fma", "binary16"), ("sqrt", "binary16"),
        ("mul", "binary64"), ("fma", "binary64"), ("div", "binary64"), ("i2f", "binary64"),
        ("f2i", "binary64"), ("add", "e6m11"), ("fma", "e6m11"), ("sqrt", "e6m11")]},
    **{f"{op}_min": ["--op", op, "--stages", str(_min_stages(op))]
       for op in ("add", "mul", "fma", "div", "i2f", "f2i")},
    **{f"{op}_ftz": ["--op", op, "--subnormals", "ftz"] for op in ("add", "mul", "fma", "div")},
    "div_cpo4": ["--op", "div", "--cycles-per-op", "4"],
    "div_cpo26": ["--op", "div", "--cycles-per-op", "26", "--format", "binary64"],
    "sqrt_cpo4": ["--op", "sqrt", "--cycles-per-op", "4"],
}


@pytest.mark.parametrize("args", list(LINT_CONFIGS.values()), ids=list(LINT_CONFIGS))
def test_verilator_lint_clean(tmp_path, args):
    """``verilator -Wall --lint-only`` with the core's own waivers: not one warning."""
    kfgen("fpu", *args, "--name", "u", "-o", tmp_path)
    proc = run_verilator(["--lint-only", "-Wall", str(tmp_path / "u.vlt"), str(tmp_path / "u.v"),
                          "--top-module", "u"])
    messages = [line for line in proc.stderr.splitlines() if line.startswith("%")]
    assert proc.returncode == 0 and not messages, "\n".join(messages)
