"""The generated Castella Verilog in Verilator under cocotb, word for word against the model."""

import json
import os
from fractions import Fraction

import numpy as np
import pytest

from kfgen.hdl.castella.params import CastellaParams
from kfgen.sim.castella import model
from kfgen.sim.castella import scenarios
from kfgen.sim.castella.run import run_castella
from kfgen.sim.verilator import pack_fields

from helpers import VERILATOR_CACHE, kfgen

pytestmark = pytest.mark.verilator

CONFIGS = {
    "castella": dict(tracks=1),
    "castella8": dict(tracks=8),
    "castella32": dict(tracks=32),
    "castella_w20": dict(tracks=3, data_width=20, gain_width=10, q_width=5, period=0.5, sigma_r=50.0),
    "castella64": dict(tracks=64),
    "castella100": dict(tracks=100),
    # --multipliers dsp: the gain products as `*` for Xilinx DSP48E1 blocks, bit-exact
    "castella8_dsp": dict(tracks=8, multipliers="dsp"),
    "castella_w20_dsp": dict(tracks=3, data_width=20, gain_width=10, q_width=5, period=0.5, sigma_r=50.0,
                             multipliers="dsp"),
}

_CLI = {"tracks": "--tracks", "data_width": "--data-width", "gain_width": "--gain-width",
        "q_width": "--q-width", "period": "--period", "sigma_r": "--sigma-r", "multipliers": "--multipliers"}


def _args(top):
    """``kfgen castella ...`` options of a configuration in CONFIGS."""
    return ["castella", *(x for k, v in CONFIGS[top].items() for x in (_CLI[k], v))]


# Tests of one core share its generated Verilog (this module's fixture) and its Verilator
# build: under pytest-xdist each such set is an xdist_group, so it runs on one worker.
@pytest.fixture(scope="module")
def core(build_root):
    made = {}

    def get(top):
        if top not in made:
            out = build_root / top
            kfgen(*_args(top), "--name", top, "-o", out)
            params = CastellaParams(name=top, **CONFIGS[top])
            made[top] = (out, params, json.loads((out / f"{top}.json").read_text()))
        return made[top]
    return get


def expected_words(params, manifest, tids, ys, restarts):
    rows, _ = model.expected_stream(params, tids, ys, restarts)
    cols = {k: np.array([r[k] for r in rows]) for k in rows[0]}
    return {"tdata": pack_fields(manifest, "m_axis_tdata", cols),
            "tuser": pack_fields(manifest, "m_axis_tuser", cols),
            "tid": np.asarray(tids)}, cols


def scenario_codes(params, runs, seed, which=("scenario1", "scenario2")):
    """``runs`` noisy measurement sequences per scenario, as rows, truncated to a common length."""
    rows = []
    for i, name in enumerate(which):
        _, rng, _ = scenarios.truth(scenarios.SCENARIOS[name], params.period)
        rows.append(scenarios.to_codes(params, scenarios.measure(rng, params.sigma_r, runs, seed + i)))
    steps = min(r.shape[1] for r in rows)
    return np.concatenate([r[:, :steps] for r in rows])


def run_checked(out, params, manifest, tids, ys, rs, **kw):
    expected, cols = expected_words(params, manifest, tids, ys, rs)
    waves = bool(os.environ.get("KFGEN_WAVES"))  # KFGEN_WAVES=1 make test: dump.fst per run
    run_dir = out / ("sim_build_fst" if waves else "sim_build")
    res = run_castella(out, params.name, tids, ys, rs, expected=expected, build_dir=run_dir,
                       cache_dir=VERILATOR_CACHE, waves=waves, **kw)
    # The testbench compared every word as it arrived; check the count and order here too.
    assert len(res["tid"]) == len(tids)
    assert np.array_equal(res["tid"], tids)
    for k in ("range", "velocity", "k1", "k2", "q", "phase", "manoeuvre", "saturated"):
        assert np.array_equal(res[k], cols[k]), k
    return res, cols


def check_sustained_rate(man, tracks, in_cycle):
    """The accepts of a run offered back to back, whole rounds of ``tracks`` in round robin,
    against the manifest's ``sustained_measurements_per_cycle``, s = min(1, tracks / TI)
    (TI = ``track_interval_cycles``).

    Such a run goes in rounds: every track once on consecutive cycles, the next round TI
    cycles after the last (at once if tracks >= TI). From the first accept to the last, over
    L cycles, the n accepts are s * L plus the head start of the first round, which nothing
    before it paid for: n = s * L + tracks * (1 - s) exactly, so n / L tends to s from above
    (n = L when s = 1)."""
    ti = man["track_interval_cycles"]
    s = Fraction(min(tracks, ti), ti)
    assert man["sustained_measurements_per_cycle"] == round(float(s), 6)
    n, span = len(in_cycle), int(in_cycle[-1] - in_cycle[0]) + 1
    assert n % tracks == 0
    assert n == s * span + tracks * (1 - s), (n, span, float(s))


@pytest.mark.xdist_group("castella")
def test_single_track_scenarios_with_gaps_backpressure_restarts(core):
    out, p, man = core("castella")
    codes = scenario_codes(p, 1, seed=11)  # scenario 1 then scenario 2 on the same track
    ys = codes.reshape(-1)
    rs = np.zeros(ys.size, dtype=bool)
    steps = codes.shape[1]
    rs[[0, 60, steps]] = True  # a restart mid-scenario and one at the second scenario
    tids = np.zeros(ys.size, dtype=np.int64)
    res, cols = run_checked(out, p, man, tids, ys, rs, gap=0.3, stall=0.3, seed=3, name="gaps")
    # the protocol checker saw results wait for ready (and found them held)
    assert res["m_axis_waits"] > 0
    # the scenarios exercise every phase, the manoeuvre bit and the q line
    assert set(cols["phase"]) == {0, 1, 2}
    assert cols["manoeuvre"].any() and cols["q"].max() == p.q_max


@pytest.mark.xdist_group("castella")
def test_single_track_cycle_counts(core):
    """With no gaps and output always ready: exact latency, and one track every track_interval,
    which with one track is the manifest's initiation interval and sustained rate."""
    out, p, man = core("castella")
    codes = scenario_codes(p, 1, seed=12, which=("scenario1",))[:, :60]
    ys = codes.reshape(-1)
    rs = np.zeros(ys.size, dtype=bool)
    rs[0] = True
    res, _ = run_checked(out, p, man, np.zeros(ys.size, dtype=np.int64), ys, rs, name="timing")
    assert np.all(res["out_cycle"] - res["in_cycle"] == man["latency_cycles"])
    assert np.all(np.diff(res["in_cycle"]) == man["track_interval_cycles"])
    assert man["initiation_interval"] == man["track_interval_cycles"]
    check_sustained_rate(man, p.tracks, res["in_cycle"])


@pytest.mark.xdist_group("castella8")
def test_eight_tracks_random_order(core):
    out, p, man = core("castella8")
    rng = np.random.default_rng(21)
    codes = scenario_codes(p, 4, seed=21)
    tids, ys, rs = scenarios.interleave(codes, rng, "random", restart_at=[(1, 40), (5, 90), (6, 2)])
    # same track back to back happens in a random interleaving: the hazard stall is exercised
    assert np.any(np.diff(tids) == 0)
    run_checked(out, p, man, tids, ys, rs, gap=0.25, stall=0.25, seed=5, name="random")


@pytest.mark.xdist_group("castella8")
def test_eight_tracks_round_robin_timing(core):
    out, p, man = core("castella8")
    codes = scenario_codes(p, 4, seed=22)[:, :30]
    tids, ys, rs = scenarios.interleave(codes, None, "rr")
    res, _ = run_checked(out, p, man, tids, ys, rs, name="rr")
    # fewer tracks than the pipeline holds: each track waits exactly track_interval
    per_track = [np.diff(res["in_cycle"][tids == t]) for t in range(8)]
    assert all(np.all(d == man["track_interval_cycles"]) for d in per_track)
    # measurements of different tracks are taken back to back: the manifest's II of 1
    assert man["initiation_interval"] == 1 and np.diff(res["in_cycle"]).min() == 1
    check_sustained_rate(man, p.tracks, res["in_cycle"])


def test_one_measurement_per_clock(core):
    """With at least track_interval tracks in round robin the core takes one measurement a clock."""
    out, p, man = core("castella32")
    assert p.tracks >= man["track_interval_cycles"]
    codes = scenario_codes(p, 16, seed=23)[:, :12]
    tids, ys, rs = scenarios.interleave(codes, None, "rr")
    res, _ = run_checked(out, p, man, tids, ys, rs, name="rate")
    assert np.all(np.diff(res["in_cycle"]) == 1)
    assert np.all(np.diff(res["out_cycle"]) == 1)
    assert man["initiation_interval"] == 1
    check_sustained_rate(man, p.tracks, res["in_cycle"])


def test_many_tracks_random_order(core):
    """Beyond the busy bitmap (more than 64 entries) the hazard check compares track indices."""
    out, p, man = core("castella100")
    rng = np.random.default_rng(41)
    codes = scenario_codes(p, 3, seed=41)[:, :40]
    tids, ys, rs = scenarios.interleave(codes, rng, "random", restart_at=[(0, 20)])
    tids = np.where(tids == 5, 99, tids)  # the highest track index too
    run_checked(out, p, man, tids, ys, rs, gap=0.2, stall=0.2, seed=8, name="many")


@pytest.mark.parametrize("top, lut", [pytest.param("castella8_dsp", "castella8", marks=pytest.mark.full),
                                      pytest.param("castella_w20_dsp", "castella_w20", marks=pytest.mark.full)])
def test_dsp_multipliers_bit_exact(core, top, lut):
    """--multipliers dsp: every output word as the model's (so as the LUT core's), with gaps,
    backpressure and restarts, and the same latency and intervals in the manifest."""
    out, p, man = core(top)
    assert p.multipliers == "dsp"
    ref = out.parent / f"{top}_lut"
    kfgen(*_args(lut), "--name", lut, "-o", ref)
    lut_man = json.loads((ref / f"{lut}.json").read_text())
    for key in ("latency_cycles", "initiation_interval", "track_interval_cycles"):
        assert man[key] == lut_man[key], key
    rng = np.random.default_rng(51)
    codes = scenario_codes(p, p.tracks, seed=51, which=("scenario1",))[:, :80]
    tids, ys, rs = scenarios.interleave(codes, rng, "random", restart_at=[(1, 40)])
    _, cols = run_checked(out, p, man, tids, ys, rs, gap=0.2, stall=0.2, seed=9, name="dsp")
    assert set(cols["phase"]) == {0, 1, 2}


@pytest.mark.full  # a second width's build (15 s): make test runs the default widths
def test_non_default_widths(core):
    out, p, man = core("castella_w20")
    rng = np.random.default_rng(31)
    codes = scenario_codes(p, 3, seed=31, which=("scenario1",))
    tids, ys, rs = scenarios.interleave(codes, rng, "random", restart_at=[(2, 100)])
    run_checked(out, p, man, tids, ys, rs, gap=0.2, stall=0.2, seed=7, name="w20")


@pytest.mark.full
@pytest.mark.xdist_group("castella64")
@pytest.mark.parametrize("scenario", ["scenario1", "scenario2"])
def test_monte_carlo_50_runs(core, scenario):
    out, p, man = core("castella64")
    codes = scenario_codes(p, 50, seed=41, which=(scenario,))
    tids, ys, rs = scenarios.interleave(codes, np.random.default_rng(41), "random")
    run_checked(out, p, man, tids, ys, rs, gap=0.1, stall=0.1, seed=9, name=f"mc_{scenario}")


#: Fault campaign sequences: make test runs the first, make test-full the second.
CAMPAIGN = [pytest.param(40, id="40"), pytest.param(10_000, id="10000", marks=pytest.mark.full)]


@pytest.mark.xdist_group("castella")
@pytest.mark.parametrize("sequences", CAMPAIGN)
def test_fault_campaign(core, sequences):
    """Random traffic on both streams cut by resets at random cycles, then after each
    sequence a clean run (restart on the first measurement) against the golden model
    (:func:`kfgen.sim.castella.tb.fault_campaign`)."""
    out, p, man = core("castella")
    ys = scenario_codes(p, 1, seed=5)[0, :10]
    tids = np.zeros(ys.size, dtype=np.int64)
    rs = np.zeros(ys.size, dtype=bool)
    rs[0] = True
    expected, _ = expected_words(p, man, tids, ys, rs)
    run_castella(out, p.name, tids, ys, rs, expected=expected, gap=0.2, stall=0.2, seed=sequences,
                 build_dir=out / "sim_build", cache_dir=VERILATOR_CACHE, name=f"campaign_{sequences}",
                 test="fault_campaign", env={"KFGEN_TB_SEQUENCES": str(sequences)})
