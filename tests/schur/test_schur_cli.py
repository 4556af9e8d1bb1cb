"""`kfgen schur`: bad values (exit 2, one line naming the option and the unit's range), the
parameters as built, and the manifest (ports, fields, latency, initiation interval)."""

import dataclasses

import pytest

from kfgen.gen.cli import main
from kfgen.gen.manifest import manifest
from kfgen.hdl.arith.float.format import FLAG_NAMES
from kfgen.hdl.arith.float.params import FpuParams, cycles_per_op_range, stages_range
from kfgen.hdl.describe import ParamError
from kfgen.hdl.schur.descriptor import CORE
from kfgen.hdl.schur.params import SIZE_MAX, SchurParams

from helpers import kfgen


def _range(op, fmt="binary32", cpo=1):
    lo, hi = stages_range(op, fmt, "ieee", cpo)
    return f"{lo}..{hi}"


MUL, ADD, DIV = _range("mul"), _range("add"), _range("div")
CPO = "{}..{}".format(*cycles_per_op_range("div", "binary32"))
CPO16 = "{}..{}".format(*cycles_per_op_range("div", "binary16"))

ERRORS = [
    (["--size", "0"], f"--size: must be an integer in 1..{SIZE_MAX} (d x d matrices), not 0"),
    (["--size", str(SIZE_MAX + 1)], f"--size: must be an integer in 1..{SIZE_MAX} (d x d matrices), "
                                    f"not {SIZE_MAX + 1}"),
    (["--size", "2.5"], f"--size: must be an integer in 1..{SIZE_MAX} (d x d matrices), not '2.5'"),
    (["--format", "binary128"], "--format: must be binary16, bfloat16, binary32, binary64 or eEmM"),
    (["--mul-latency", "0"], f"--mul-latency: must be an integer in {MUL} for mul binary32, not 0"),
    (["--mul-latency", "x"], f"--mul-latency: must be an integer in {MUL} for mul binary32, not 'x'"),
    (["--add-latency", "99"], f"--add-latency: must be an integer in {ADD} for add binary32, not 99"),
    (["--div-latency", "0"], f"--div-latency: must be an integer in {DIV} for div binary32, not 0"),
    (["--div-cycles-per-op", "0"], f"--div-cycles-per-op: must be an integer in {CPO} for div binary32, not 0"),
    (["--div-cycles-per-op", "27"], f"--div-cycles-per-op: must be an integer in {CPO} for div binary32, not 27"),
    (["--format", "binary16", "--div-cycles-per-op", "14"],
     f"--div-cycles-per-op: must be an integer in {CPO16} for div binary16, not 14"),
    # the slides' first row: a 14-cycle divider with latency 14, which ours cannot be
    (["--div-cycles-per-op", "14", "--div-latency", "14"],
     f"--div-latency: must be an integer in {_range('div', cpo=14)} for div binary32, cycles_per_op 14, not 14"),
    (["--name", "9x"], "--name: must be a Verilog identifier"),
    (["--stages", "3"], "--stages: unknown option"),
]


@pytest.mark.parametrize("args, message", ERRORS, ids=[" ".join(e[0]) for e in ERRORS])
def test_bad_values_exit_2_with_one_line(tmp_path, capsys, args, message):
    out = tmp_path / "out"
    assert main(["schur", *args, "-o", str(out)]) == 2
    err = capsys.readouterr()
    lines = err.err.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"kfgen: error: {message}"), err.err
    assert err.out == "" and not out.exists()


def test_bad_value_from_the_shell(tmp_path):
    """The same through the installed command: status 2, one line, no traceback, nothing written."""
    proc = kfgen("schur", "--add-latency", "0", "-o", tmp_path / "out", check=False)
    assert proc.returncode == 2 and proc.stdout == "" and not (tmp_path / "out").exists()
    assert proc.stderr == f"kfgen: error: --add-latency: must be an integer in {ADD} for add binary32, not 0\n"


def test_parameters_record_what_is_built():
    p = SchurParams(div_cycles_per_op=26)
    assert (p.mul_latency, p.add_latency) == (FpuParams(op="mul").stages, FpuParams(op="add").stages)
    assert p.div_latency == FpuParams(op="div", cycles_per_op=26).stages
    assert SchurParams(format="E8M23").format == "binary32"
    with pytest.raises(ParamError) as info:
        SchurParams(size=True)
    assert info.value.param == "size"
    assert SchurParams(**dataclasses.asdict(p)) == p


@pytest.mark.parametrize("kw", [{}, {"size": 3, "format": "binary16", "div_cycles_per_op": 13, "mul_latency": 3,
                                     "add_latency": 7, "div_latency": 14}],
                         ids=["default", "d3-binary16-iterative"])
def test_manifest(kw):
    p = SchurParams(**kw)
    core = CORE.build(p)
    core._MustUse__silence = True  # built for its ports and latencies only, never elaborated
    man = manifest("schur", p.name, dataclasses.asdict(p), core, lambda port: CORE.fields_of(p, port),
                   CORE.extra(p, core))
    ports = {q["name"]: q for q in man["ports"]}
    assert list(ports) == ["clk", "rst", "s_axis_tvalid", "s_axis_tready", "s_axis_tdata", "m_axis_tvalid",
                           "m_axis_tready", "m_axis_tdata", "m_axis_tuser"]
    d, w = p.size, p.fmt.width
    upper = [(i, j) for i in range(d) for j in range(i, d)]
    tdata = ports["s_axis_tdata"]["fields"]
    assert [(f["name"], f["lsb"], f["width"], f["format"]) for f in tdata] == \
        [(f"a{i}{j}", k * w, w, p.format) for k, (i, j) in enumerate(upper)]
    result = ports["m_axis_tdata"]["fields"]
    assert [f["name"] for f in result] == [f"inv{i}{j}" for i, j in upper] + ["det"]
    assert ports["m_axis_tdata"]["width"] == (len(upper) + 1) * w
    assert [(f["name"], f["lsb"]) for f in ports["m_axis_tuser"]["fields"]] == \
        [("pivot", 0), ("nan", 1)] + [(n, 2 + i) for i, n in enumerate(FLAG_NAMES)]
    assert man["initiation_interval"] == p.div_cycles_per_op
    assert man["latency_cycles"] == 1 + man["datapath_latency_cycles"] + 2
    if d == 2:
        assert man["datapath_latency_cycles"] == 2 * (p.div_latency + p.mul_latency + p.add_latency)
    assert man["units"]["div"] == d
    assert man["fifo_depth"] == -(-man["latency_cycles"] // p.div_cycles_per_op) + 1
