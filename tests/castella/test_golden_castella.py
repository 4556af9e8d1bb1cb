"""Golden models of the Castella tracker (kfgen.sim.castella.model) and their scenarios.

The fixed-point model is what the core is proven against bit for bit, so here it is
checked from the other side: against the paper's claims, against the float64 reference,
the float reference against filterpy and an independent matrix implementation, and its
integer helpers against exact rational arithmetic. Expected values come from the paper,
from exact arithmetic or from independent code, never from the model under test.
"""

from __future__ import annotations

import math
import random
from fractions import Fraction

import numpy as np
import pytest

from kfgen.hdl.castella.params import CastellaParams, Fmt
from kfgen.sim.castella import model
from kfgen.sim.castella.scenarios import SCENARIOS, measure, to_codes, truth

RUNS = 50
SEED = 1980  # Castella's paper
SCENARIO_NAMES = sorted(SCENARIOS)
PAPER = CastellaParams()
#: A non-default core: wider words, half-second period, a better sensor.
OTHER = CastellaParams(data_width=20, gain_width=10, q_width=5, period=0.5, sigma_r=50.0)


# ---------------------------------------------------------------------------- Monte Carlo
def monte_carlo(p: CastellaParams, sc, runs: int = RUNS, seed: int = SEED) -> dict:
    """Truth, measurement codes and the estimates of every filter (metres, m/s)."""
    t, rng_true, rate_true = truth(sc, p.period)
    codes = to_codes(p, measure(rng_true, p.sigma_r, runs, seed))
    y = codes * 2.0 ** -p.range_fmt.frac  # the floats see exactly what the core sees
    out = model.run_fixed(p, codes)
    mc = {"t": t, "range_true": rng_true, "rate_true": rate_true, "codes": codes, "out": out,
          "fixed": (out["range"] * 2.0 ** -p.range_fmt.frac, out["velocity"] * 2.0 ** -p.vel_fmt.frac),
          "cts": model.run_float(p, y, adaptive=True),
          "ckf": model.run_float(p, y, adaptive=False)}
    return mc


def rms_over_runs(est, true):
    return np.sqrt(np.mean((est - true) ** 2, axis=0))


def time_averaged_rms(mc, filt, skip=2):
    """RMS over runs at each sample, averaged over time after the two initialisation samples."""
    rng, vel = mc[filt]
    return (rms_over_runs(rng, mc["range_true"])[skip:].mean(),
            rms_over_runs(vel, mc["rate_true"])[skip:].mean())


def manoeuvre_rms(mc, filt, sc):
    """RMS range error over runs and the samples from turn_start to turn_end + 10 s."""
    t = mc["t"]
    window = (t >= sc.turn_start) & (t <= sc.turn_end + 10.0)
    return math.sqrt(np.mean((mc[filt][0] - mc["range_true"])[:, window] ** 2))


@pytest.fixture(scope="module")
def paper_mc():
    return {name: monte_carlo(PAPER, SCENARIOS[name]) for name in SCENARIO_NAMES}


# ---------------------------------------------------------------------------- paper's claims
@pytest.mark.parametrize("name", SCENARIO_NAMES)
def test_fixed_point_as_accurate_as_float(paper_mc, name):
    """The paper's point: the narrow datapath does not cost accuracy (within 10 %)."""
    mc = paper_mc[name]
    fl_r, fl_v = time_averaged_rms(mc, "cts")
    fx_r, fx_v = time_averaged_rms(mc, "fixed")
    print(f"{name}: float CTS {fl_r:.2f} m {fl_v:.2f} m/s, fixed CTS {fx_r:.2f} m {fx_v:.2f} m/s")
    assert abs(fx_r - fl_r) <= 0.10 * fl_r
    assert abs(fx_v - fl_v) <= 0.10 * fl_v
    # and it is a tracker at all: well below the raw measurement noise
    assert fx_r < 0.8 * PAPER.sigma_r


@pytest.mark.parametrize("name", SCENARIO_NAMES)
def test_cts_beats_ckf_during_manoeuvre(paper_mc, name):
    sc, mc = SCENARIOS[name], paper_mc[name]
    ckf, cts, fixed = (manoeuvre_rms(mc, f, sc) for f in ("ckf", "cts", "fixed"))
    print(f"{name} manoeuvre RMS range: CKF {ckf:.1f} m, CTS float {cts:.1f} m, CTS fixed {fixed:.1f} m")
    assert cts < ckf
    assert fixed < ckf


def test_non_default_parameters_keep_fixed_close_to_float():
    p = OTHER
    sc = SCENARIOS["scenario1"]
    mc = monte_carlo(p, sc)
    assert mc["t"][1] == pytest.approx(0.5)  # the truth is sampled at this core's period
    fl_r, fl_v = time_averaged_rms(mc, "cts")
    fx_r, fx_v = time_averaged_rms(mc, "fixed")
    print(f"T=0.5 s, sigma_r=50 m, 20/10/5 bits: float {fl_r:.2f} m {fl_v:.2f} m/s, "
          f"fixed {fx_r:.2f} m {fx_v:.2f} m/s")
    assert abs(fx_r - fl_r) <= 0.10 * fl_r
    assert abs(fx_v - fl_v) <= 0.10 * fl_v
    assert not mc["out"]["saturated"].any()


# ---------------------------------------------------------------------------- float references
def _ckf_q(p):
    T = p.period
    return p.q1 * np.array([[T ** 3 / 3, T ** 2 / 2], [T ** 2 / 2, T]])


def _init_eq17_18(p, y0, y1):
    T, r2 = p.period, p.sigma_r ** 2
    x = np.array([y1, (y1 - y0) / T])
    P = np.array([[r2, r2 / T], [r2 / T, 2 * r2 / T ** 2]])
    return x, P


def _close(actual, expected, rtol=1e-9):
    np.testing.assert_allclose(actual, expected, rtol=rtol, atol=rtol * np.max(np.abs(expected)))


def test_float_ckf_equals_filterpy():
    from filterpy.kalman import KalmanFilter

    p, sc = PAPER, SCENARIOS["scenario1"]
    _, rng_true, _ = truth(sc, p.period)
    y = measure(rng_true, p.sigma_r, 5, SEED)
    ckf_r, ckf_v = model.run_float(p, y, adaptive=False)
    T = p.period
    for run in range(y.shape[0]):
        kf = KalmanFilter(dim_x=2, dim_z=1)
        kf.F = np.array([[1.0, T], [0.0, 1.0]])
        kf.H = np.array([[1.0, 0.0]])
        kf.Q = _ckf_q(p)
        kf.R = np.array([[p.sigma_r ** 2]])
        x, P = _init_eq17_18(p, y[run, 0], y[run, 1])
        kf.x, kf.P = x.reshape(2, 1), P
        st = model.float_init(p, y[run, :1], y[run, 1:2])
        ref_x, ref_p, ref_k, got_p, got_k = [], [], [], [], []
        for k in range(2, y.shape[1]):
            kf.predict()
            kf.update(y[run, k])
            st, k1, k2, _ = model.float_step(p, st, y[run, k:k + 1], adaptive=False)
            ref_x.append(kf.x[:, 0].copy())
            ref_p.append([kf.P[0, 0], kf.P[0, 1], kf.P[1, 0], kf.P[1, 1]])
            ref_k.append(kf.K[:, 0].copy())
            got_p.append([st.p11[0], st.p12[0], st.p12[0], st.p22[0]])
            got_k.append([k1[0], k2[0]])
        ref_x = np.array(ref_x)
        _close(ckf_r[run, 2:], ref_x[:, 0])
        _close(ckf_v[run, 2:], ref_x[:, 1])
        _close(np.array(got_p), np.array(ref_p))
        _close(np.array(got_k), np.array(ref_k))


def _matrix_cts(p, y):
    """The adaptive filter written as the paper's matrix equations (3)-(10) and Figure 2."""
    T, R = p.period, p.sigma_r ** 2
    F = np.array([[1.0, T], [0.0, 1.0]])
    H = np.array([[1.0, 0.0]])
    Qunit = np.array([[T ** 3 / 3, T ** 2 / 2], [T ** 2 / 2, T]])
    x, P = _init_eq17_18(p, y[0], y[1])
    zhat, q = 0.0, p.q1
    xs, zs, qs = [], [], []
    for yk in y[2:]:
        x = F @ x                                             # (3)
        P = F @ P @ F.T + q * Qunit                           # (4)
        S = (H @ P @ H.T).item() + R
        K = P @ H.T / S                                       # (5)
        resid = yk - (H @ x).item()                           # (8)
        x = x + K[:, 0] * resid                               # (6)
        P = (np.eye(2) - K @ H) @ P                           # (7)
        zhat = p.alpha * resid / math.sqrt(S) + (1 - p.alpha) * zhat   # (9), (10)
        q = float(np.interp(abs(zhat), [p.z1, p.z2], [p.q1, p.q2]))    # Figure 2
        xs.append(x)
        zs.append(zhat)
        qs.append(q)
    return np.array(xs), np.array(zs), np.array(qs)


@pytest.mark.parametrize("name", SCENARIO_NAMES)
def test_float_cts_equals_matrix_implementation(name):
    p, sc = PAPER, SCENARIOS[name]
    _, rng_true, _ = truth(sc, p.period)
    y = measure(rng_true, p.sigma_r, RUNS, SEED + 1)
    cts_r, cts_v = model.run_float(p, y, adaptive=True)
    st = model.float_init(p, y[:, 0], y[:, 1])
    zf, q = [], []
    for k in range(2, y.shape[1]):
        st, _, _, z = model.float_step(p, st, y[:, k], adaptive=True)
        zf.append(z)
        q.append(st.q)
    zf, q = np.array(zf).T, np.array(q).T
    q_ref_all = []
    for run in range(RUNS):
        xs, zs, qs = _matrix_cts(p, y[run])
        _close(cts_r[run, 2:], xs[:, 0])
        _close(cts_v[run, 2:], xs[:, 1])
        _close(zf[run], zs)
        _close(q[run], qs)
        q_ref_all.append(qs)
    q_ref_all = np.concatenate(q_ref_all)
    # the comparison went through every branch of the q line
    assert (q_ref_all == p.q1).any() and (q_ref_all == p.q2).any()
    assert ((q_ref_all > p.q1) & (q_ref_all < p.q2)).any()


# ---------------------------------------------------------------------------- integer helpers
def _round_half_up(x: Fraction) -> int:
    return math.floor(x + Fraction(1, 2))


def test_rsr_hand_values():
    # worked by hand: half-way cases go up (towards +inf) for either sign
    assert model.rsr(3, 1) == 2      # 1.5
    assert model.rsr(-3, 1) == -1    # -1.5
    assert model.rsr(-5, 2) == -1    # -1.25
    assert model.rsr(-6, 2) == -1    # -1.5
    assert model.rsr(-7, 2) == -2    # -1.75
    assert model.rsr(5, 2) == 1      # 1.25
    assert model.rsr(6, 2) == 2      # 1.5
    assert model.rsr(-3, -2) == -12  # negative shift multiplies
    assert model.rsr(7, 0) == 7


@pytest.mark.parametrize("shift", list(range(-6, 0)) + [0, 1, 2, 3, 7, 8, 15, 16, 24, 31])
def test_rsr_equals_exact_rounding(shift):
    rnd = random.Random(shift)
    v = [rnd.randint(-(1 << 40), 1 << 40) for _ in range(2000)]
    v += [k << max(shift - 1, 0) for k in range(-9, 10)]  # exact ties and their neighbours
    v += [(k << max(shift - 1, 0)) + d for k in range(-9, 10, 2) for d in (-1, 1)]
    got = model.rsr(np.array(v, dtype=np.int64), shift)
    want = [_round_half_up(Fraction(x, 1 << shift)) if shift > 0 else x * 2 ** -shift for x in v]
    assert got.tolist() == want


@pytest.mark.parametrize("width,signed", [(8, True), (12, True), (16, False), (6, False), (24, True)])
def test_sat_clamps_to_format(width, signed):
    fmt = Fmt(width, 3, signed)
    lo, hi = (-2 ** (width - 1), 2 ** (width - 1) - 1) if signed else (0, 2 ** width - 1)
    assert (fmt.min, fmt.max) == (lo, hi)
    rnd = random.Random(width)
    v = [rnd.randint(-4 * 2 ** width, 4 * 2 ** width) for _ in range(3000)] + [lo - 1, lo, lo + 1, hi - 1, hi, hi + 1]
    got = model.sat(np.array(v, dtype=np.int64), fmt)
    assert got.tolist() == [min(max(x, lo), hi) for x in v]


@pytest.mark.parametrize("gain_width", [6, 8, 10, 12])
@pytest.mark.parametrize("extra_shift", [-2, 0, 1, 3])
def test_gain_divide_is_rounded_exact_quotient(gain_width, extra_shift):
    rnd = random.Random(gain_width * 100 + extra_shift)
    pairs = []
    for _ in range(3000):
        den = rnd.randint(1, (1 << 24) - 1)
        one = math.ceil(Fraction(den) / 2 ** extra_shift)  # smallest num with quotient >= 1
        # mostly quotients below 1 (the normal case), some at and above it
        num = rnd.randint(0, one - 1) if rnd.random() < 0.9 else rnd.randint(one, 4 * one)
        pairs.append((num, den))
    pairs += [(1, 1), (0, 1), (255, 256), (1, 3), (2, 3), ((1 << 24) - 2, (1 << 24) - 1)]
    num = np.array([a for a, _ in pairs], dtype=np.int64)
    den = np.array([b for _, b in pairs], dtype=np.int64)
    gain, over = model.gain_divide(num, den, extra_shift, gain_width)
    top = 2 ** gain_width - 1
    for (a, b), g, o in zip(pairs, gain.tolist(), over.tolist()):
        quotient = Fraction(a, b) * Fraction(2) ** extra_shift  # the gain as a real number
        assert g == min(_round_half_up(quotient * 2 ** gain_width), top), (a, b)
        assert o == (quotient >= 1), (a, b)
    assert over.any() and not over.all()


def rsqrt_bound(p: CastellaParams) -> float:
    """Largest relative error the U4 table may have against exact 1/sqrt(P11 + sigma_r^2).

    The table is indexed by the top 8 bits of P11, so a P11 code is at most half a bin
    (``step/2`` m^2) from the bin midpoint its entry was computed at. The worst case is the
    first bin, where the sum is smallest: relative error ``sqrt(1 + step/2/sigma_r^2) - 1``
    (about step/(4 sigma_r^2): 0.64 % for the paper's 256 m^2 bins and 10^4 m^2). On top of
    that each entry is rounded to an integer: at most half an LSB of the smallest entry.
    """
    dw, f11, r2 = p.data_width, p.p11_fmt.frac, p.sigma_r ** 2
    step = 2.0 ** (dw - 8 - f11)
    bin_error = math.sqrt(1 + step / 2 / r2) - 1
    smallest_entry = 2.0 ** p.rsqrt_frac / math.sqrt(r2 + 2.0 ** (dw - f11))
    return (1 + bin_error) * (1 + 0.5 / smallest_entry) - 1


@pytest.mark.parametrize("p", [PAPER, OTHER], ids=["paper", "20bit"])
def test_rsqrt_table_error(p):
    """Max relative error of the U4 table over all P11 codes, against :func:`rsqrt_bound`.

    Against thresholds z1, z2 that differ by 50 %, a sub-percent error in z is harmless.
    """
    dw, f11, r2 = p.data_width, p.p11_fmt.frac, p.sigma_r ** 2
    table = np.array(p.rsqrt_table, dtype=np.int64)
    assert table.size == 256 and table.min() > 0 and table.max() < 1 << 16
    codes = np.arange(1 << dw, dtype=np.int64)
    approx = table[codes >> (dw - 8)] * 2.0 ** -p.rsqrt_frac
    exact = 1.0 / np.sqrt(codes * 2.0 ** -f11 + r2)
    measured = float(np.max(np.abs(approx - exact) / exact))
    bound = rsqrt_bound(p)
    print(f"rsqrt LUT ({p.data_width}-bit P11): max relative error {measured:.5%}, bound {bound:.5%}")
    assert measured <= bound
    assert measured > 0.9 * bound  # the bound is tight: it describes the table
    assert bound < 0.01


# ---------------------------------------------------------------------------- scenarios
def _fly(sc, t_samples):
    """Integrate a 200 m/s target from (10 km, 0) heading +x, turning at accel/V in the turn."""
    from scipy.integrate import solve_ivp

    speed = 200.0
    rate = sc.accel / speed

    def f(turning):
        return lambda t, s: [speed * math.cos(s[2]), speed * math.sin(s[2]), rate if turning else 0.0]

    pieces = [(0.0, sc.turn_start, False), (sc.turn_start, sc.turn_end, True), (sc.turn_end, sc.duration, False)]
    state = [10_000.0, 0.0, 0.0]
    xs = np.zeros((t_samples.size, 3))
    for a, b, turning in pieces:
        if b <= a:
            continue
        inside = (t_samples >= a) & (t_samples <= b)
        t_eval = np.append(t_samples[inside & (t_samples < b)], b)
        sol = solve_ivp(f(turning), (a, b), state, t_eval=t_eval, rtol=1e-12, atol=1e-9, method="DOP853")
        xs[inside] = sol.y.T[:inside.sum()]
        state = list(sol.y[:, -1])
    x, y, heading = xs.T
    rng = np.hypot(x, y)
    rate_r = (x * speed * np.cos(heading) + y * speed * np.sin(heading)) / rng
    return rng, rate_r, heading


@pytest.mark.parametrize("name", SCENARIO_NAMES)
def test_truth_is_a_200_m_s_quarter_turn(name):
    sc = SCENARIOS[name]
    # the scenario times from the paper (and the derived scenario 2 end, see sim/scenarios.py)
    if name == "scenario1":
        assert (sc.turn_start, sc.turn_end, sc.duration) == (85.0, 110.0, 150.0)
    else:
        assert (sc.turn_start, sc.accel, sc.duration) == (100.0, 10.0, 131.0)
    assert (sc.turn_end - sc.turn_start) * sc.accel / 200.0 == pytest.approx(math.pi / 2, rel=1e-12)
    t, rng, rate = truth(sc)
    assert t[0] == 0 and t[-1] == sc.duration and np.all(np.diff(t) == 1.0)
    ref_rng, ref_rate, heading = _fly(sc, t)
    np.testing.assert_allclose(rng, ref_rng, rtol=0, atol=1e-4)
    np.testing.assert_allclose(rate, ref_rate, rtol=0, atol=1e-6)
    assert heading[-1] == pytest.approx(math.pi / 2 if t[-1] >= sc.turn_end else
                                        (t[-1] - sc.turn_start) * sc.accel / 200.0, abs=1e-9)
    # radial flight before the turn: all 200 m/s show in range
    before = t <= sc.turn_start
    np.testing.assert_allclose(rate[before], 200.0, atol=1e-9)
    np.testing.assert_allclose(rng[before], 10_000.0 + 200.0 * t[before], atol=1e-6)
    # range rate is the derivative of range (checked on a fine grid)
    tf, rf, vf = truth(sc, 0.01)
    np.testing.assert_allclose(np.gradient(rf, tf)[1:-1], vf[1:-1], atol=0.05)


@pytest.mark.parametrize("name", SCENARIO_NAMES)
def test_ranges_fit_the_16_bit_format(name):
    _, rng, _ = truth(SCENARIOS[name])
    assert PAPER.range_fmt.min == 0 and PAPER.range_fmt.max == 65535 and PAPER.range_fmt.frac == 0
    assert rng.min() - 6 * PAPER.sigma_r > 0 and rng.max() + 6 * PAPER.sigma_r < 65535
    codes = to_codes(PAPER, measure(rng, PAPER.sigma_r, RUNS, SEED))
    assert codes.min() > 0 and codes.max() < 65535  # nothing clipped


def test_measure_is_seeded():
    _, rng, _ = truth(SCENARIOS["scenario1"])
    a = measure(rng, 100.0, 20, 7)
    b = measure(rng, 100.0, 20, 7)
    c = measure(rng, 100.0, 20, 8)
    assert a.shape == (20, rng.size)
    assert np.array_equal(a, b)
    assert not np.any(a == c)
    noise = a - rng
    assert abs(noise.mean()) < 5.0 and noise.std() == pytest.approx(100.0, rel=0.05)
    assert not np.array_equal(noise[0], noise[1])  # runs are independent, not one sequence repeated


# ---------------------------------------------------------------------------- fixed-point model
@pytest.mark.parametrize("name", SCENARIO_NAMES)
def test_no_saturation_and_phases(paper_mc, name):
    out = paper_mc[name]["out"]
    steps = out["phase"].shape[1]
    assert not out["saturated"].any()
    assert np.array_equal(out["phase"], np.broadcast_to([0, 1] + [2] * (steps - 2), out["phase"].shape))
    # the first output echoes the measurement; only tracking outputs carry gains and q
    assert np.array_equal(out["range"][:, 0], paper_mc[name]["codes"][:, 0])
    for key in ("velocity", "k1", "k2", "q", "manoeuvre"):
        assert not out[key][:, 0].any()
    for key in ("k1", "k2", "q", "manoeuvre"):
        assert not out[key][:, 1].any()
    # the manoeuvre detector fired, and q swept its whole range
    assert out["manoeuvre"].any()
    assert out["q"].min() == 0 and out["q"].max() == PAPER.q_max


@pytest.mark.parametrize("k", [1, 2, 40, 95])
def test_restart_mid_stream_equals_fresh_track(paper_mc, k):
    p, codes = PAPER, paper_mc["scenario1"]["codes"]
    n, steps = codes.shape
    st, outs = model.fixed_init(n), []
    for j in range(steps):
        st, out = model.fixed_step(p, st, codes[:, j], np.full(n, j in (0, k)))
        outs.append(out)
    fresh = model.run_fixed(p, codes[:, k:])
    if k == 95:  # mid-turn: the restart must also clear the detector state
        assert outs[k - 1]["q"].any()
    for key, want in fresh.items():
        got = np.stack([o[key] for o in outs[k:]], axis=1)
        assert np.array_equal(got, want), key


def test_expected_stream_interleaved_tracks_are_independent():
    p = CastellaParams(tracks=8)
    rnd = np.random.default_rng(SEED)
    steps = 120
    tracks = []
    for tid in range(p.tracks):
        sc = SCENARIOS[SCENARIO_NAMES[tid % 2]]
        _, rng, _ = truth(sc)
        tracks.append(to_codes(p, measure(rng[tid:tid + steps], p.sigma_r, 1, SEED + tid))[0])
    order = rnd.permutation(np.repeat(np.arange(p.tracks), steps))
    nxt = np.zeros(p.tracks, dtype=int)
    tids, ys, restarts = [], [], []
    for tid in order:
        tids.append(int(tid))
        ys.append(int(tracks[tid][nxt[tid]]))
        restarts.append(nxt[tid] == 0)
        nxt[tid] += 1
    half = len(tids) // 2
    rows, st = model.expected_stream(p, tids[:half], ys[:half], restarts[:half])
    more, _ = model.expected_stream(p, tids[half:], ys[half:], restarts[half:], state=st)
    rows += more
    for tid in range(p.tracks):
        want = model.run_fixed(p, tracks[tid][None, :])
        mine = [r for r, t in zip(rows, tids) if t == tid]
        assert len(mine) == steps
        for key, arr in want.items():
            assert [r[key] for r in mine] == arr[0].tolist(), (tid, key)


@pytest.mark.parametrize("p", [PAPER, OTHER], ids=["paper", "20bit"])
def test_initialisation_is_exact(p):
    """Step 1 stores eq. (17)-(18) exactly (T = 1 and 0.5 make 1/T exact in binary)."""
    sc = SCENARIOS["scenario1"]
    _, rng, _ = truth(sc, p.period)
    codes = to_codes(p, measure(rng, p.sigma_r, RUNS, SEED))
    st, _ = model.fixed_step(p, model.fixed_init(RUNS), codes[:, 0], np.ones(RUNS, bool))
    st, out = model.fixed_step(p, st, codes[:, 1], np.zeros(RUNS, bool))
    scale = Fraction(2) ** (p.vel_fmt.frac - p.range_fmt.frac) / Fraction(p.period)
    want_v = [_round_half_up((Fraction(int(b)) - int(a)) * scale) for a, b in zip(codes[:, 0], codes[:, 1])]
    assert st.x1.tolist() == codes[:, 1].tolist() and out["range"].tolist() == codes[:, 1].tolist()
    assert st.x2.tolist() == want_v and out["velocity"].tolist() == want_v
    r2, T = Fraction(p.sigma_r) ** 2, Fraction(p.period)
    for got, value, fmt in ((st.p11, r2, p.p11_fmt), (st.p12, r2 / T, p.p12_fmt), (st.p22, 2 * r2 / T ** 2, p.p22_fmt)):
        code = value * 2 ** fmt.frac
        assert code.denominator == 1 and code <= fmt.max  # representable: no saturation at start
        assert np.all(got == int(code))
    assert not st.zf.any() and not st.qc.any()


@pytest.mark.parametrize("p,name", [(PAPER, "scenario1"), (PAPER, "scenario2"), (OTHER, "scenario1")],
                         ids=["paper-scenario1", "paper-scenario2", "20bit-scenario1"])
def test_each_fixed_step_is_the_float_step_within_quantisation(p, name):
    """From the same (decoded) state, one fixed-point update lands within the error its
    quantisation allows of the float64 update: gains rounded to half an LSB (K2 may also clip
    by one LSB at its format's top), each rounded shift half an LSB, the rsqrt table within
    :func:`rsqrt_bound`. Biases, wrong shifts or a wrong branch exceed these bounds."""
    sc = SCENARIOS[name]
    _, rng, _ = truth(sc, p.period)
    codes = to_codes(p, measure(rng, p.sigma_r, RUNS, SEED))
    lr, lv = 2.0 ** -p.range_fmt.frac, 2.0 ** -p.vel_fmt.frac
    l11, l12, l22 = (2.0 ** -f.frac for f in (p.p11_fmt, p.p12_fmt, p.p22_fmt))
    lk1, lk2, lz = 2.0 ** -p.k1_fmt.frac, 2.0 ** -p.k2_fmt.frac, 2.0 ** -p.z_fmt.frac
    q_step = (p.q2 - p.q1) / (2 ** p.q_width - 1)
    worst = {}
    st = model.fixed_init(RUNS)
    for k in range(codes.shape[1]):
        new, out = model.fixed_step(p, st, codes[:, k], np.full(RUNS, k == 0))
        if k >= 2:
            fs = model.FloatState(st.x1 * lr, st.x2 * lv, st.p11 * l11, st.p12 * l12, st.p22 * l22,
                                  st.zf * lz, p.q1 + (p.q2 - p.q1) * st.qc / (2 ** p.q_width - 1))
            y = codes[:, k] * lr
            fl, k1, k2, _ = model.float_step(p, fs, y)
            s = fs.p11 + 2 * p.period * fs.p12 + p.period ** 2 * fs.p22 + fs.q * p.period ** 3 / 3 + p.sigma_r ** 2
            pp12 = fl.p12 / (1 - k1)
            resid = np.abs(y - fs.x1 - p.period * fs.x2)
            # gain errors: rounding, the predicted P words (rounded by up to 2 LSB), and for K2
            # clipping at its format's top (it starts just above 0.5/T)
            e_k1 = 0.5 * lk1 + 2 * l11 / s
            e_k2 = 0.5 * lk2 + 2 * (l12 + k2 * l11) / s + np.maximum(0.0, k2 - (2 ** p.gain_width - 1) * lk2)
            zf = new.zf * lz
            checks = {
                "k1": (out["k1"] * lk1 - k1, e_k1),
                "k2": (out["k2"] * lk2 - k2, e_k2),
                "x1": (new.x1 * lr - fl.x1, lr + e_k1 * resid),
                "x2": (new.x2 * lv - fl.x2, 0.5 * lv + e_k2 * resid + 0.5 * lr * k2),
                "p11": (new.p11 * l11 - fl.p11, 3 * l11 + e_k1 * (fl.p11 / (1 - k1))),
                "p12": (new.p12 * l12 - fl.p12, 3 * l12 + e_k1 * pp12),
                "p22": (new.p22 * l22 - fl.p22, 3 * l22 + e_k2 * pp12),
                # rounding, plus alpha times z_n's error (table, rounding, residual off by half an LSB)
                "zf": (zf - fl.zf, lz + p.alpha * (rsqrt_bound(p) * resid / np.sqrt(s) + lz + lr / np.sqrt(s))),
                # the q line evaluated at the core's own z: half a code, plus z1, z2 rounded to z LSBs
                "q": (p.q1 + q_step * new.qc - np.interp(np.abs(zf), [p.z1, p.z2], [p.q1, p.q2]),
                      0.5 * q_step + (p.q2 - p.q1) / (p.z2 - p.z1) * lz),
            }
            for key, (err, bound) in checks.items():
                worst[key] = max(worst.get(key, 0.0), float(np.max(np.abs(err) / bound)))
        st = new
    print(f"{name} {p.data_width}-bit worst error / bound:", {k: round(v, 3) for k, v in worst.items()})
    assert all(v <= 1.0 for v in worst.values()), worst


# ---------------------------------------------------------------------------- figures
def test_plots_monte_carlo_and_figures(paper_mc, tmp_path, capsys):
    from kfgen.sim.castella import plots

    mc = plots.monte_carlo(PAPER, "scenario1", runs=RUNS, seed=SEED)
    mine = paper_mc["scenario1"]
    assert np.array_equal(mc["codes"], mine["codes"])
    for filt in ("ckf", "cts", "fixed"):
        assert np.array_equal(mc[f"{filt}_range"], mine[filt][0])
        assert np.array_equal(mc[f"{filt}_velocity"], mine[filt][1])
    # a "Verilator" run equal to the model but for one word, velocity given as raw unsigned bits
    hw = {}
    for name in SCENARIO_NAMES:
        out = plots.monte_carlo(PAPER, name)["fixed"]
        hw[f"{name}_range"] = out["range"]
        hw[f"{name}_velocity"] = out["velocity"] & 0xFFFF
    hw["scenario2_velocity"][3, 50] ^= 1
    np.savez(tmp_path / "hw.npz", **hw)
    plots.main(["-o", str(tmp_path / "fig"), "--verilator", str(tmp_path / "hw.npz")])
    assert sorted(f.name for f in (tmp_path / "fig").iterdir()) == [f"{n}.png" for n in SCENARIO_NAMES]
    printed = capsys.readouterr().out
    lines = {line.split()[0]: line for line in printed.splitlines() if "CTS (Verilator)" in line}
    assert lines["scenario1"].endswith("words differing from the model: 0")
    assert lines["scenario2"].endswith("words differing from the model: 1")
