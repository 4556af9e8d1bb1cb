"""The paper's two manoeuvring-target scenarios, flown in 2-D and measured in range.

A radar at the origin measures the range of a target with Gaussian noise sigma_r. The
target starts 10 km out on the x axis flying radially away at V = 200 m/s, so its whole
speed shows in the range coordinate, then turns through 90 degrees at constant speed so
that the range rate falls towards zero: a manoeuvre in range.

The paper's numbers do not agree with each other (a 35 m/s^2 turn at 200 m/s completes a
quarter turn in 9 s, not in the 25 s from t = 85 s to t = 110 s). We keep the times and
derive the acceleration:

* scenario 1: quarter turn from t = 85 s to t = 110 s, so a = V (pi/2) / 25 s = 12.6 m/s^2;
  straight flight again until t = 150 s.
* scenario 2: turn at a = 10 m/s^2 from t = 100 s to the end of the run, which is when the
  quarter turn completes (t = 100 + (pi/2) V / a = 131.4 s, so 132 samples at T = 1 s).

Ranges stay between 10 km and 32 km, inside the 16-bit measurement format (0..65535 m).
Everything is seeded (``numpy.random.default_rng``) and reproducible.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from kfgen.hdl.castella.params import CastellaParams

__all__ = ["Scenario", "SCENARIOS", "truth", "measure", "to_codes"]

SPEED = 200.0
START = (10_000.0, 0.0)


@dataclass(frozen=True)
class Scenario:
    name: str
    turn_start: float  # s
    turn_end: float    # s, inclusive of the quarter turn
    accel: float       # m/s^2, centripetal
    duration: float    # s, last sample time


def _scenario1() -> Scenario:
    return Scenario("scenario1", 85.0, 110.0, SPEED * (math.pi / 2) / 25.0, 150.0)


def _scenario2() -> Scenario:
    end = 100.0 + (math.pi / 2) * SPEED / 10.0
    return Scenario("scenario2", 100.0, end, 10.0, math.floor(end))


SCENARIOS = {"scenario1": _scenario1(), "scenario2": _scenario2()}


def truth(sc: Scenario, period: float = 1.0):
    """True (time, range, range rate) sampled every ``period`` seconds, analytically."""
    t = np.arange(0.0, sc.duration + 1e-9, period)
    w = sc.accel / SPEED  # turn rate, rad/s
    radius = SPEED / w
    x0, y0 = START
    # straight along +x until the turn, then an arc to the left through angle theta
    tau = np.clip(t - sc.turn_start, 0.0, sc.turn_end - sc.turn_start)
    theta = w * tau
    x = x0 + SPEED * np.minimum(t, sc.turn_start) + radius * np.sin(theta)
    y = y0 + radius * (1 - np.cos(theta))
    vx, vy = SPEED * np.cos(theta), SPEED * np.sin(theta)
    # after the turn: straight along the final heading
    after = np.maximum(t - sc.turn_end, 0.0)
    x = x + vx * after
    y = y + vy * after
    rng = np.hypot(x, y)
    rate = (x * vx + y * vy) / rng
    return t, rng, rate


def measure(rng_true, sigma_r: float, runs: int, seed: int):
    """``runs`` independent noisy range sequences, shape (runs, steps), metres."""
    gen = np.random.default_rng(seed)
    return rng_true[None, :] + sigma_r * gen.standard_normal((runs, rng_true.size))


def to_codes(p: CastellaParams, y_metres):
    """Measurement codes in the core's range format (rounded, saturated)."""
    f = p.range_fmt
    return np.clip(np.round(np.asarray(y_metres) * 2.0 ** f.frac), f.min, f.max).astype(np.int64)


def interleave(y_codes, rng, order: str = "random", restart_at=()):
    """Merge per-track sequences (rows of ``y_codes``) into one stream of (tid, y, restart).

    ``order="rr"`` is round robin; ``"random"`` picks a random track with measurements left
    each time (so one track often comes twice in a row), keeping each track's own order.
    Each track's first measurement is a restart, and so is every step in ``restart_at``
    (pairs ``(track, step)``).
    """
    y_codes = np.asarray(y_codes)
    n, steps = y_codes.shape
    if order == "rr":
        tids = np.tile(np.arange(n), steps)
    elif order == "random":
        tids = rng.permutation(np.repeat(np.arange(n), steps))
    else:
        raise ValueError(f"order must be 'rr' or 'random', not {order!r}")
    pos = np.zeros(n, dtype=np.int64)
    restarts = set(restart_at)
    ys, rs = [], []
    for t in tids:
        k = pos[t]
        ys.append(int(y_codes[t, k]))
        rs.append(k == 0 or (int(t), int(k)) in restarts)
        pos[t] += 1
    return tids.astype(np.int64), np.array(ys, dtype=np.int64), np.array(rs, dtype=bool)
