"""Golden models of the Castella tracking system (CTS).

* :func:`fixed_step` is the bit-accurate twin of the hardware datapath in
  ``kfgen.hdl.castella``: the same widths, the same round-half-up shifts, the same
  saturation, the same look-up tables, in the same order. Every output word of the
  generated Verilog must equal it.
* :func:`float_step` is the float64 reference of the paper's equations (1)-(10) and
  the q-variation line of its Figure 2; ``adaptive=False`` gives the conventional
  Kalman filter (CKF) with q fixed at q1.

Both work on numpy arrays of independent tracks at once (one element per track), so a
50-run Monte Carlo is one vectorised pass over time.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kfgen.hdl.castella.params import (ALPHA_FRAC, QSLOPE_SHIFT, RSQRT_INDEX_BITS, CastellaParams, Fmt)

__all__ = ["FixedState", "FloatState", "fixed_init", "fixed_step", "float_init", "float_step",
           "run_fixed", "run_float", "expected_stream", "rsr", "sat", "PHASE_FIRST", "PHASE_INIT",
           "PHASE_TRACK"]

PHASE_FIRST, PHASE_INIT, PHASE_TRACK = 0, 1, 2


# ---------------------------------------------------------------------------- integer helpers
def rsr(v, s: int):
    """Shift right by ``s`` rounding half up (``s < 0`` shifts left): the hardware's only rounding."""
    v = np.asarray(v, dtype=np.int64)
    if s > 0:
        return (v + (1 << (s - 1))) >> s
    return v << (-s)


def sat(v, fmt: Fmt):
    """Clamp to a format's range: overflow saturates, never wraps."""
    return np.clip(v, fmt.min, fmt.max)


def _sat_flag(v, fmt: Fmt):
    return (v < fmt.min) | (v > fmt.max)


def gain_divide(num, den, extra_shift: int, gain_width: int):
    """Rounded quotient ``num * 2**(extra_shift + gain_width) / den`` saturated to ``gain_width`` bits.

    Mirrors the restoring divider: ``gain_width + 1`` quotient bits, then round half up.
    Returns ``(gain, overflowed)``; ``overflowed`` when ``num >= den`` after alignment (the
    quotient needs more than ``gain_width`` bits); a quotient that only rounds up to
    ``2**gain_width`` is clamped without the flag.
    """
    num = np.asarray(num, dtype=np.int64) << max(extra_shift, 0)
    den = np.asarray(den, dtype=np.int64) << max(-extra_shift, 0)
    over = num >= den
    q = (num << (gain_width + 1)) // den
    g = np.minimum((q + 1) >> 1, (1 << gain_width) - 1)
    return np.where(over, (1 << gain_width) - 1, g), over


# ---------------------------------------------------------------------------- fixed point
@dataclass
class FixedState:
    """Per-track state words as stored in the core's state memory (integer codes)."""

    x1: np.ndarray
    x2: np.ndarray
    p11: np.ndarray
    p12: np.ndarray
    p22: np.ndarray
    zf: np.ndarray
    qc: np.ndarray
    phase: np.ndarray  # measurements seen, capped at 2: 0 empty, 1 first stored, 2 tracking


def fixed_init(n: int) -> FixedState:
    """``n`` empty tracks, as after reset."""
    z = np.zeros(n, dtype=np.int64)
    return FixedState(*(z.copy() for _ in range(8)))


def fixed_step(p: CastellaParams, st: FixedState, y, restart):
    """One measurement for each track in ``st`` (arrays of equal length).

    Returns ``(new_state, out)`` where ``out`` holds the output fields
    ``range, velocity, k1, k2, q, phase, manoeuvre, saturated`` as integer arrays.
    """
    y = np.asarray(y, dtype=np.int64)
    restart = np.asarray(restart, dtype=bool)
    phase = np.where(restart, PHASE_FIRST, st.phase)
    fr, fv = p.range_fmt, p.vel_fmt
    f11, f12, f22 = p.p11_fmt, p.p12_fmt, p.p22_fmt
    gw, fk2 = p.gain_width, p.k2_fmt.frac
    zfmt = p.z_fmt

    # U1, prediction (eqs. 3, 4)
    (tm, tf), (t2m, t2f), (tsm, tsf) = p.t_const, p.t2x_const, p.tsq_const
    q11, q12, q22 = (np.asarray(t, dtype=np.int64) for t in p.q_tables)
    qc = st.qc
    x1p_w = st.x1 + rsr(st.x2 * tm, tf + fv.frac - fr.frac)
    pp11_w = st.p11 + rsr(st.p12 * t2m, t2f + f12.frac - f11.frac) \
        + rsr(st.p22 * tsm, tsf + f22.frac - f11.frac) + q11[qc]
    pp12_w = st.p12 + rsr(st.p22 * tm, tf + f22.frac - f12.frac) + q12[qc]
    pp22_w = st.p22 + q22[qc]
    x1p, pp11, pp12, pp22 = sat(x1p_w, fr), sat(pp11_w, f11), sat(pp12_w, f12), sat(pp22_w, f22)
    flag = _sat_flag(x1p_w, fr) | _sat_flag(pp11_w, f11) | _sat_flag(pp12_w, f12) | _sat_flag(pp22_w, f22)

    # U1, gains (eq. 5): exact rounded division instead of the paper's 8-bit reciprocal LUT
    s = pp11 + p.sr2_code
    k1, _ = gain_divide(pp11, s, 0, gw)
    # K2 may clip at its format's top (about 0.5/T, reached at a track's first update): harmless, not flagged
    k2, _ = gain_divide(pp12, s, fk2 + f11.frac - f12.frac - gw, gw)

    # U2, state update (eq. 6) and U3, covariance update (eq. 7)
    r = y - x1p
    x1_w = x1p + rsr(k1 * r, gw)
    x2_w = st.x2 + rsr(k2 * r, fk2 + fr.frac - fv.frac)
    p11_w = rsr(((1 << gw) - k1) * pp11, gw)
    p12_w = rsr(((1 << gw) - k1) * pp12, gw)
    p22_w = pp22 - rsr(k2 * pp12, fk2 + f12.frac - f22.frac)
    flag |= _sat_flag(x1_w, fr) | _sat_flag(x2_w, fv) | _sat_flag(p11_w, f11) \
        | _sat_flag(p12_w, f12) | _sat_flag(p22_w, f22)

    # U4, manoeuvre detector (eqs. 8-10): residual over a LUT of 1/sqrt(P11 + sigma_r^2)
    rsq = np.asarray(p.rsqrt_table, dtype=np.int64)[pp11 >> (p.data_width - RSQRT_INDEX_BITS)]
    zn = sat(rsr(r * rsq, fr.frac + p.rsqrt_frac - zfmt.frac), zfmt)
    a = p.alpha_code
    zf = sat(rsr(a * zn + ((1 << ALPHA_FRAC) - a) * st.zf, ALPHA_FRAC), zfmt)
    za = np.abs(zf)
    manoeuvre = za > p.z1_code
    # U5, q variation (Figure 2): straight line from (z1, code 0) to (z2, code q_max)
    d = za - p.z1_code
    qn = np.where(d <= 0, 0, np.minimum(p.q_max, rsr(np.maximum(d, 0) * p.q_slope, QSLOPE_SHIFT)))

    # U0, initial values (eqs. 17, 18)
    im, inf_ = p.inv_t_const
    v0_w = rsr((y - st.x1) * im, fr.frac + inf_ - fv.frac)
    pi11, pi12, pi22 = p.p_init_codes

    first, init, track = phase == PHASE_FIRST, phase == PHASE_INIT, phase == PHASE_TRACK
    zero = np.zeros_like(y)

    def pick(f_first, f_init, f_track):
        return np.where(first, f_first, np.where(init, f_init, f_track))

    new = FixedState(
        x1=pick(y, y, sat(x1_w, fr)),
        x2=pick(zero, sat(v0_w, fv), sat(x2_w, fv)),
        p11=pick(zero, pi11, sat(p11_w, f11)),
        p12=pick(zero, pi12, sat(p12_w, f12)),
        p22=pick(zero, pi22, sat(p22_w, f22)),
        zf=pick(zero, zero, zf),
        qc=pick(zero, zero, qn),
        phase=pick(zero + PHASE_INIT, zero + PHASE_TRACK, zero + PHASE_TRACK),
    )
    out = {
        "range": new.x1,
        "velocity": new.x2,
        "k1": np.where(track, k1, 0),
        "k2": np.where(track, k2, 0),
        "q": np.where(track, qc, 0),
        "phase": phase,
        "manoeuvre": (track & manoeuvre).astype(np.int64),
        "saturated": pick(zero, _sat_flag(v0_w, fv), flag).astype(np.int64),
    }
    return new, out


def run_fixed(p: CastellaParams, y_codes):
    """Run tracks over time. ``y_codes``: (tracks, steps) measurement codes; the first is a restart.

    Returns a dict of (tracks, steps) output arrays.
    """
    y_codes = np.asarray(y_codes, dtype=np.int64)
    n, steps = y_codes.shape
    st = fixed_init(n)
    outs = []
    for k in range(steps):
        st, out = fixed_step(p, st, y_codes[:, k], np.full(n, k == 0))
        outs.append(out)
    return {key: np.stack([o[key] for o in outs], axis=1) for key in outs[0]}


def expected_stream(p: CastellaParams, tids, ys, restarts, state: FixedState | None = None):
    """Expected outputs, in input order, for an interleaved stream of (tid, y, restart).

    Tracks are independent, so the stream is replayed in order one element at a time on
    the per-track state (``state`` carries over between calls; a fresh core is empty).
    """
    st = state if state is not None else fixed_init(p.tracks)
    rows = []
    for tid, y, rs in zip(tids, ys, restarts):
        one = FixedState(*(getattr(st, f)[tid:tid + 1] for f in FixedState.__dataclass_fields__))
        new, out = fixed_step(p, one, [y], [rs])
        for f in FixedState.__dataclass_fields__:
            getattr(st, f)[tid] = getattr(new, f)[0]
        rows.append({k: int(v[0]) for k, v in out.items()})
    return rows, st


# ---------------------------------------------------------------------------- float reference
@dataclass
class FloatState:
    x1: np.ndarray
    x2: np.ndarray
    p11: np.ndarray
    p12: np.ndarray
    p22: np.ndarray
    zf: np.ndarray
    q: np.ndarray


def float_init(p: CastellaParams, y0, y1) -> FloatState:
    """Eqs. (17)-(18): state from the first two measurements of a track."""
    y0, y1 = np.asarray(y0, dtype=float), np.asarray(y1, dtype=float)
    T, r2 = p.period, p.sigma_r ** 2
    one = np.ones_like(y1)
    return FloatState(y1.copy(), (y1 - y0) / T, r2 * one, r2 / T * one, 2 * r2 / T ** 2 * one,
                      0 * one, p.q1 * one)


def float_step(p: CastellaParams, st: FloatState, y, adaptive: bool = True):
    """Eqs. (3)-(10) in float64; returns ``(new_state, k1, k2, zf)``."""
    T, r2 = p.period, p.sigma_r ** 2
    q = st.q
    x1p = st.x1 + T * st.x2
    pp11 = st.p11 + 2 * T * st.p12 + T * T * st.p22 + q * T ** 3 / 3
    pp12 = st.p12 + T * st.p22 + q * T ** 2 / 2
    pp22 = st.p22 + q * T
    s = pp11 + r2
    k1, k2 = pp11 / s, pp12 / s
    r = np.asarray(y, dtype=float) - x1p
    zf = p.alpha * r / np.sqrt(s) + (1 - p.alpha) * st.zf
    if adaptive:
        frac = np.clip((np.abs(zf) - p.z1) / (p.z2 - p.z1), 0.0, 1.0)
        qn = p.q1 + (p.q2 - p.q1) * frac
    else:
        qn = np.full_like(q, p.q1)
    new = FloatState(x1p + k1 * r, st.x2 + k2 * r, (1 - k1) * pp11, (1 - k1) * pp12,
                     pp22 - k2 * pp12, zf, qn)
    return new, k1, k2, zf


def run_float(p: CastellaParams, y, adaptive: bool = True):
    """Run tracks (rows of ``y``, metres) over time; returns (range, velocity) estimates.

    Step 0 outputs the measurement with zero velocity, step 1 the eq. (17) initialisation,
    as the hardware does.
    """
    y = np.asarray(y, dtype=float)
    n, steps = y.shape
    rng_est, vel_est = np.zeros((n, steps)), np.zeros((n, steps))
    rng_est[:, 0] = y[:, 0]
    st = float_init(p, y[:, 0], y[:, 1])
    rng_est[:, 1], vel_est[:, 1] = st.x1, st.x2
    for k in range(2, steps):
        st, *_ = float_step(p, st, y[:, k], adaptive)
        rng_est[:, k], vel_est[:, k] = st.x1, st.x2
    return rng_est, vel_est
