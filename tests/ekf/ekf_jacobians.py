"""The tracker's Jacobians by hand, for the EKF's tests (a module of its own: ``conftest`` is not
importable by name when several test folders have one)."""

import numpy as np


class TrackerJacobians:
    """The tracker's Jacobians written from its equations (independent of any differentiation):
    f is linear (constant velocity, w an acceleration), h is range and bearing."""

    def __init__(self, app):
        dt = app.dt
        self.F = np.array([[1, 0, dt, 0], [0, 1, 0, dt], [0, 0, 1, 0], [0, 0, 0, 1.0]])
        self.L = np.array([[dt * dt / 2, 0], [0, dt * dt / 2], [dt, 0], [0, dt]])

    def fx(self, x, u):
        return self.F, self.L

    def hx(self, x):
        px, py = x[0], x[1]
        r2 = px * px + py * py
        r = np.sqrt(r2)
        return np.array([[px / r, py / r, 0, 0], [-py / r2, px / r2, 0, 0]]), np.eye(2)
