"""A 2-D range-bearing tracker: a second, smaller UKF application (n = 4, nw = 2, nv = 2,
m = 2, so M = 8).

A sensor at the origin measures the range and bearing of a target moving at nearly constant
velocity:

* state x = [px, py, vx, vy] (m, m/s);
* f: constant velocity over dt driven by a random acceleration w = [ax, ay] (m/s^2), the
  discrete white-noise-acceleration model x' = [p + v dt + w dt^2 / 2, v + w dt];
* h: [sqrt(px^2 + py^2), atan2(py, px)] + v, with v = [range noise (m), bearing noise (rad)].

The scenario flies the same model (the truth is f with drawn accelerations) from a start
drawn around x0 with P0, so the filter's numbers are the truth's. The target stays well
inside the first quadrant, so the bearing never wraps at +-pi (h does not handle the wrap).

:class:`PositionTracker` is its linear variant (the same target seen by a sensor of its
position, h = [px, py] + v): what a linear Kalman filter runs as well as an EKF or a UKF, its
F, H, Q, R from :meth:`PositionTracker.linear_model` (``kfgen kf``'s buffer).
"""

from __future__ import annotations

import numpy as np

from ..app import Scenario, UkfApplication

__all__ = ["Tracker", "PositionTracker"]


class Tracker(UkfApplication):
    """Range-bearing tracking of a nearly-constant-velocity target, one sample a second."""

    n, nw, nv, m = 4, 2, 2, 2
    W0 = 0.0
    dt = 1.0
    sigma_accel = 0.5  #: m/s^2, the target's random acceleration
    sigma_range = 10.0  #: m
    sigma_bearing = 0.01  #: rad (0.57 degrees)

    def __init__(self):
        self.x0 = np.array([2000.0, 1500.0, -10.0, 15.0])
        self.P0 = np.diag([100.0 ** 2, 100.0 ** 2, 10.0 ** 2, 10.0 ** 2])
        self.Q = np.eye(2) * self.sigma_accel ** 2
        self.R = np.diag([self.sigma_range ** 2, self.sigma_bearing ** 2])

    def f(self, x, w, u, dt):
        p, v = np.asarray(x[:2], dtype=np.float64), np.asarray(x[2:], dtype=np.float64)
        return np.r_[p + v * dt + w * dt * dt / 2, v + w * dt]

    def h(self, x, v):
        return np.array([np.hypot(x[0], x[1]), np.arctan2(x[1], x[0])]) + v

    def scenario(self, steps: int, seed: int) -> Scenario:
        rng = np.random.default_rng(seed)
        x = rng.multivariate_normal(self.x0, self.P0)
        truth, z = [], []
        for _ in range(steps):
            x = self.f(x, rng.normal(0.0, self.sigma_accel, 2), None, self.dt)
            truth.append(x)
            z.append(self.h(x, self._measurement_noise(rng)))
        return Scenario(np.arange(1, steps + 1) * self.dt, np.array(truth), np.zeros((steps, 0)), np.array(z))

    def _measurement_noise(self, rng):
        return rng.normal(0.0, [self.sigma_range, self.sigma_bearing])


class PositionTracker(Tracker):
    """The same nearly-constant-velocity target, its position measured directly (a GPS-like
    sensor, sigma_position per axis): f and h are linear."""

    sigma_position = 10.0  #: m

    def __init__(self):
        super().__init__()
        self.R = np.eye(2) * self.sigma_position ** 2

    def h(self, x, v):
        return np.array([x[0], x[1]]) + v

    def _measurement_noise(self, rng):
        return rng.normal(0.0, self.sigma_position, 2)

    def linear_model(self) -> dict:
        """The model as a linear Kalman filter's, float64 arrays by ``kfgen kf`` region: F (f's
        transition), Q = G Q_w G^T (G, f's noise gain: the acceleration's effect over dt), H
        and R."""
        dt, eye = self.dt, np.eye(2)
        F = np.block([[eye, dt * eye], [np.zeros((2, 2)), eye]])
        G = np.vstack([eye * dt * dt / 2, eye * dt])
        H = np.hstack([eye, np.zeros((2, 2))])
        return {"F": F, "Q": G @ self.Q @ G.T, "H": H, "R": self.R.copy()}
