"""A complete UKF application: a pendulum whose angle is seen through its sine.

The state is x = [angle (rad), angular rate (rad/s)]; f moves it by one forward-Euler step of
the pendulum's equation (g = 9.81 m/s^2, length 1 m), plus the process noise w; h observes
sin(angle) plus the measurement noise v. There is no control input: the scenario's ``u`` is
None, and f gets an empty array as ``u``.

Size a core for it, and co-simulate it on that core (generate, Verilator build, run; every
word checked against the golden model)::

    kfgen ukf --app docs/examples/pendulum.py:Pendulum -o build/pendulum
    python -m kfgen.gen.cosim ukf --app docs/examples/pendulum.py:Pendulum --steps 5 -o build/pendulum-cosim
"""

import numpy as np

from kfgen.sim.ukf.app import Scenario, UkfApplication


class Pendulum(UkfApplication):
    n, nw, nv, m = 2, 2, 1, 1  # sizes of x, w, v, z
    dt = 0.01  # s between iterations
    x0 = np.array([0.1, 0.0])  # the initial estimate
    P0 = np.eye(2) * 0.1  # its covariance
    Q = np.eye(2) * 1e-4  # covariance of w
    R = np.array([[1e-2]])  # covariance of v

    def f(self, x, w, u, dt):
        return x + dt * np.array([x[1], -9.81 * np.sin(x[0])]) + w

    def h(self, x, v):
        return np.array([np.sin(x[0])]) + v

    def scenario(self, steps, seed):
        """``steps`` iterations of a pendulum released near x0: the truth moves by f with
        noise drawn from Q, each measurement is h of the truth with noise drawn from R."""
        rng = np.random.default_rng(seed)
        x = rng.multivariate_normal(self.x0, self.P0)
        truth, z = [], []
        for _ in range(steps):
            x = self.f(x, rng.multivariate_normal(np.zeros(2), self.Q), None, self.dt)
            truth.append(x)
            z.append(self.h(x, rng.multivariate_normal(np.zeros(1), self.R)))
        t = np.arange(1, steps + 1) * self.dt
        return Scenario(t=t, truth=np.array(truth), u=None, z=np.array(z))
