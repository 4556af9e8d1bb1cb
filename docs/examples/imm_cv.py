"""A complete IMM application: a target on a line, tracked by two constant-velocity models.

The state is x = [position (m), velocity (m/s)], measured as its position every 0.1 s. The two
models share F and H and differ in their process noise: "steady" (small accelerations) and
"manoeuvre" (large ones); the scenario's target keeps its speed, brakes hard for a second in
the middle, then keeps its new speed, and the manoeuvre model's probability rises while it
brakes.

Co-simulate it on the IMM core sized for it (R = 2, n = 2, d = 1: generate, Verilator build,
run; every word checked against the golden model)::

    python -m kfgen.gen.cosim imm --app docs/examples/imm_cv.py:ConstantVelocity --steps 3 -o build/imm-cosim
"""

import numpy as np

from kfgen.sim.imm.app import ImmApplication, ImmModel, ImmScenario

DT = 0.1  # s between measurements
F = np.array([[1.0, DT], [0.0, 1.0]])
H = np.array([[1.0, 0.0]])
#: Process noise of a white acceleration of unit variance over DT (per m^2/s^4).
G = np.array([[DT**4 / 4, DT**3 / 2], [DT**3 / 2, DT**2]])
SIGMA_Z = 0.5  # m, the position's measurement noise


class ConstantVelocity(ImmApplication):
    models = [ImmModel("steady", F, G * 0.01, H, np.array([[SIGMA_Z**2]])),
              ImmModel("manoeuvre", F, G * 25.0, H, np.array([[SIGMA_Z**2]]))]
    pi = np.array([[0.95, 0.05], [0.10, 0.90]])  # pi[i, j]: from model i to model j
    mu0 = np.array([0.9, 0.1])
    x0 = np.array([0.0, 10.0])  # every model's initial estimate
    P0 = np.diag([1.0, 4.0])

    def scenario(self, steps, seed):
        rng = np.random.default_rng(seed)
        x, truth = np.array([0.0, 10.0]), []
        for k in range(steps):
            accel = -8.0 if steps // 2 <= k < steps // 2 + 10 else 0.0  # braking: 1 s at -8 m/s^2
            x = F @ x + np.array([DT**2 / 2, DT]) * accel
            truth.append(x)
        truth = np.array(truth)
        z = truth[:, :1] + rng.normal(0.0, SIGMA_Z, (steps, 1))
        return ImmScenario(z, truth)
