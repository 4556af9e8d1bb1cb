"""--target-mhz: the delay model's longest stage per plan, the fewest stages a target picks,
what the manifest records, and the errors. (Every stage count a target can pick is one of the
unit's plans, which tests/fpu's unit tests stream random operands through.)"""

import json

import pytest

from helpers import kfgen_in_process

from kfgen.gen.output import generate
from kfgen.hdl.arith.float.descriptor import CORE
from kfgen.hdl.arith.float.format import FloatFormat
from kfgen.hdl.arith.float.params import FpuParams, _unit_args, _unit_class, unit_timing
from kfgen.hdl.arith.float.timing import MEASURED_MHZ, StagePlans, longest_stage, predicted_mhz, stages_for_target

OPS = ("add", "sub", "mul", "div", "sqrt", "fma", "i2f", "f2i", "exp")
TARGETS = (75, 100, 125, 150)


def _delays(op, fmt="binary32", subnormals="ieee", cycles_per_op=1):
    return _unit_class(op).stage_delays(fmt, **_unit_args(op, subnormals, None, cycles_per_op))


@pytest.mark.parametrize("op", OPS)
def test_longest_stage_of_every_plan(op):
    """A plan's longest stage is the longest run of segments between its registers, and more
    registers never make it longer where the model places them (StagePlans)."""
    cls = _unit_class(op)
    delays = _delays(op)
    plans = cls.plan("binary32", **_unit_args(op, "ieee", None, 1)).plans
    assert set(delays) == set(plans)
    if isinstance(plans, StagePlans):
        segments = list(zip(plans._names, plans._delays))
        for k in plans:
            assert delays[k] == pytest.approx(longest_stage(segments, plans[k])), k
        counts = sorted(delays)
        assert all(delays[a] >= delays[b] - 1e-9 for a, b in zip(counts, counts[1:]))
    else:
        segments = object.__new__(cls).stage_segments(FloatFormat.parse("binary32"), "ieee")
        assert [name for name, _ in segments][-1] == "out"
        assert all(set(plan) <= {name for name, _ in segments} for plan in plans.values()), \
            "every boundary a plan registers has a segment"
        assert delays[0] == pytest.approx(sum(d for _, d in segments))


@pytest.mark.parametrize("op", OPS)
@pytest.mark.parametrize("target", TARGETS)
def test_target_picks_the_fewest_stages(op, target):
    delays = _delays(op)
    stages, mhz = stages_for_target(op, delays, target)
    assert mhz == pytest.approx(predicted_mhz(op, delays[stages]))
    fewer = [k for k in delays if 0 < k < stages]
    if mhz >= target:
        assert all(predicted_mhz(op, delays[k]) < target for k in fewer), "none fewer reaches it"
    else:
        assert stages == max(delays), "else the most stages"
    assert FpuParams(op=op, target_mhz=target).stages == stages
    assert unit_timing(op, "binary32", target_mhz=target) == (stages, mhz)


def test_higher_targets_take_more_stages():
    for op in OPS:
        picked = [FpuParams(op=op, target_mhz=t).stages for t in TARGETS]
        assert picked == sorted(picked), op


def _files(**kw):
    return generate(CORE, FpuParams(**kw))


def test_manifest_records_target_and_prediction():
    params = FpuParams(op="add", target_mhz=150)
    files = _files(op="add", target_mhz=150)
    manifest = json.loads(files["fpu.json"])
    assert manifest["parameters"]["target_mhz"] == 150.0 and manifest["parameters"]["stages"] == params.stages
    timing = manifest["timing"]
    assert timing["target_mhz"] == 150.0 and timing["met"] == (timing["predicted_fmax_mhz"] >= 150)
    assert timing["predicted_fmax_mhz"] == round(unit_timing("add", "binary32", stages=params.stages)[1], 1)
    assert f"kfgen fpu --stages {params.stages} --target-mhz 150.0 -o DIR" in files["fpu.v"]
    # the recorded command regenerates the same bytes
    again = FpuParams(op="add", stages=params.stages, target_mhz=150.0)
    assert generate(CORE, again) == files


def test_without_a_target_nothing_is_recorded():
    manifest = json.loads(_files(op="add")["fpu.json"])
    assert "timing" not in manifest and "target_mhz" not in manifest["parameters"]
    assert "target_mhz" not in _files(op="add")["fpu.v"]


@pytest.mark.parametrize("argv, says", [
    (["--target-mhz", "5"], "--target-mhz: must be a clock in MHz, a number in 10..1000, not 5"),
    (["--target-mhz", "fast"], "--target-mhz: must be a clock in MHz, a number in 10..1000, not 'fast'"),
    (["--op", "sin", "--target-mhz", "100"], "--target-mhz: sin has one pipeline"),
    (["--stages", "3", "--target-mhz", "125"], "--stages: 3 is not the"),
])
def test_bad_targets(tmp_path, argv, says):
    proc = kfgen_in_process("fpu", *argv, "-o", str(tmp_path / "x"))
    assert proc.returncode == 2 and says in proc.stderr and len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert not (tmp_path / "x").exists()


def test_engine_cores_pick_their_units():
    from kfgen.hdl.engine.machine import ENGINE_MHZ, engine_mhz, machine, timing
    from kfgen.hdl.imm.params import ImmParams
    from kfgen.hdl.schur.params import SchurParams
    from kfgen.hdl.ukf.params import UkfParams

    for cls in (UkfParams, ImmParams):
        base = machine(cls())
        for t in TARGETS:
            params = cls(target_mhz=t)
            mc = machine(params)
            assert mc.fma_latency == FpuParams(op="fma", target_mhz=t).stages
            assert mc.exp_latency == FpuParams(op="exp", target_mhz=t).stages
            tm = timing(params, mc, {"fma", "exp"})
            assert mc.fetch_register == (t > ENGINE_MHZ) and tm["fetch_register"] == bool(mc.fetch_register)
            assert tm["predicted_fmax_mhz"] <= engine_mhz(mc) and tm["met"] == (tm["predicted_fmax_mhz"] >= t)
            assert tm["units"]["exp"]["stages"] == mc.exp_latency
            assert "exp" not in timing(params, mc, {"fma"})["units"], "the exponential only where it is built"
            assert mc.pes == base.pes and mc.banks == base.banks
    schur = SchurParams(target_mhz=150, mul_latency=3)
    assert schur.mul_latency == 3, "a latency given stays"
    assert schur.add_latency == FpuParams(op="add", target_mhz=150).stages
    assert schur.timing["units"]["mul"]["stages"] == 3


def test_trig_units_have_no_model():
    for op in MEASURED_MHZ:
        assert _delays(op) is None
        assert unit_timing(op, "binary32") == (None, None)


@pytest.mark.full  # two UKF cores generated (the --target-mhz RTL and bench tests run in make test)
def test_bench_timing_engine_rows(tmp_path):
    """bench_timing's UKF rows: the manifest's timing, one core to measure per distinct choice
    (above the engine's own clock the fetch register makes a choice of its own)."""
    from kfgen.gen.bench_timing import _engine_rows
    from kfgen.hdl.engine.machine import ENGINE_MHZ, FETCHED_MHZ

    rows, cores = _engine_rows([100, 125], tmp_path)
    slow, fast = rows
    assert "fetch register" not in slow["stages"] and "fetch register" in fast["stages"]
    assert slow["predicted"] <= ENGINE_MHZ < fast["predicted"] <= FETCHED_MHZ
    assert set(cores) == {slow["stages"], fast["stages"]}
    assert cores[fast["stages"]]["cycles"] > cores[slow["stages"]]["cycles"], "deeper units, a longer fetch"
