"""The chapter's nanosatellite attitude filter (seed 000, section 4) and a simulated tumble.

The model (sections 4.1-4.4):

* state x = [q1, q2, q3, q0, b1, b2, b3] (eq. 36): the attitude quaternion, scalar last, and
  the gyro bias beta (rad/s);
* control input u = z_g, the gyro reading (eq. 32: true body rate + bias + noise, rad/s);
* f by eqs. (37)-(38), forward Euler over dt of the quaternion kinematics (29)-(30), with one
  change: the printed f integrates z_g itself, so the bias never reaches the prediction and
  the filter cannot learn it (it is unobservable: nothing it does changes z). Here f
  integrates z_g - b, the gyro reading less the estimated bias, as (32) implies;
* process noise w = [eta_q (4), beta_dot (3)] added to f' (38), so nw = 7;
* h by eqs. (39)-(40): the accelerometer and magnetometer vectors A_q(q) g b_a and
  A_q(q) b_m, g = 8.94 m/s^2 (300 km), b_a = [0, 0, 1], b_m = [1, 0, 0] (gauss), plus
  v = [eta_a (3), eta_m (3)], so nv = m = 6.

M = 7 + 7 + 6 = 20, the chapter's split (eq. 41: the state, then 0_4 and 0_3 for eta_q and
beta_dot, then 0_3 and 0_3 for eta_a and eta_m).

The filter's numbers (section 4.5): Q = diag(eta_q I_4, eta_d I_3) with the printed
covariances eta_q = 1e-6 and eta_d = 1e-2; x0 = [0, 0, 0, 1, 0, 0, 0] (level, no bias
known); W0 = 0. Two departures, both measured:

* R. The printed eta_a = 1e-2 g and eta_m = 1e-2 gauss, read as standard deviations, leave
  this simulation's attitude error at 0.17 degrees on average after the first second (up
  to 0.5), never the chapter's own "< 0.1 degree" (Figure 12); read as variances (sigma 0.1),
  at 0.6 (up to 2). The simulated sensors are ten times better than the first reading,
  sigma_a = 1e-3 g and sigma_m = 1e-3 gauss, and R holds their variances.
* P0. Eq. (42) gives P0 = I (it prints 1_{6x1} for the seven states). With sensors that
  good, the first update takes P from 1 to about 1e-8 in the quaternion's directions, and
  in binary32 the cancellation in P - Pxz K^T (rounding errors near 1e-7) leaves P
  indefinite: the core's next ``sig_gen`` raises ``err_pivot`` (4 seeds in 5; the float64
  reference converges). P0 = 0.01 I, the initial estimate's actual uncertainty (0.1 per
  quaternion component, about 11 degrees; 0.1 rad/s of bias), works in both.

The truth (section 4.5 gives the recipe, not the data): a slow tumble at constant
roll-pitch-yaw rates (3, -2, 4) deg/s from angles drawn in +-10 degrees, turned into the
attitude by eq. (43) (as a quaternion: A_q of it is A_euler); gyro noise 0.1 deg/s per sample
(the chapter's eta_g = 10^-1/s read in degrees, which is what the filter's eta_q = 1e-6
amounts to: (1/2 sigma_g)^2 = 7.6e-7); a true bias beta = (0.05, -0.03, 0.04) rad/s (about
3 deg/s) drifting by (33) with the filter's eta_d; 100 samples a second (Figure 12a shows the
first tenth of a second, ten samples; the text's 1 Hz cannot be the figure's rate) and
:data:`STEPS` = 1000 iterations (10 s). Everything random comes from the scenario's seed.
"""

from __future__ import annotations

import numpy as np

from ..app import Scenario, UkfApplication

__all__ = ["G", "B_A", "B_M", "RATE", "STEPS", "rotation", "euler_rotation", "quat_multiply",
           "euler_quaternion", "attitude_error_deg", "Nanosat", "NanosatPrinted"]

G = 8.94  #: gravity at 300 km, m/s^2
B_A = np.array([0.0, 0.0, 1.0])
B_M = np.array([1.0, 0.0, 0.0])
RATE = 100.0  #: samples per second
STEPS = 1000  #: iterations of the chapter-style run (10 s)


def rotation(q) -> np.ndarray:
    """A_q(q) of eq. (40), q = [q1, q2, q3, q0] (not normalised: it scales by |q|^2)."""
    q1, q2, q3, q0 = q
    return np.array([
        [q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3, 2 * (q1 * q2 - q0 * q3), 2 * (q0 * q2 + q1 * q3)],
        [2 * (q1 * q2 + q0 * q3), q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3, 2 * (q2 * q3 - q0 * q1)],
        [2 * (q1 * q3 - q0 * q2), 2 * (q0 * q1 + q2 * q3), q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3],
    ])


def euler_rotation(a1, a2, a3) -> np.ndarray:
    """A_euler of eq. (43) (c_i = cos a_i, s_i = sin a_i): a turn by a1 about z, a2 about y,
    a3 about x, applied right to left."""
    c1, c2, c3 = np.cos([a1, a2, a3])
    s1, s2, s3 = np.sin([a1, a2, a3])
    return np.array([
        [c1 * c2, c1 * s2 * s3 - s1 * c3, s1 * s3 + c1 * s2 * c3],
        [s1 * c2, s1 * s2 * s3 + c1 * c3, s1 * s2 * c3 - c1 * s3],
        [-s2, c2 * s3, c2 * c3],
    ])


def quat_multiply(a, b) -> np.ndarray:
    """The product a b of [v, s] quaternions, the one whose A_q is A_q(a) A_q(b) (for unit
    quaternions); the kinematics (29)-(30) are dq/dt = 1/2 q [omega, 0]."""
    av, a0 = np.asarray(a[:3], dtype=np.float64), a[3]
    bv, b0 = np.asarray(b[:3], dtype=np.float64), b[3]
    return np.r_[a0 * bv + b0 * av + np.cross(av, bv), a0 * b0 - av @ bv]


def _conjugate(q) -> np.ndarray:
    return np.r_[-np.asarray(q[:3]), q[3]]


def euler_quaternion(a1, a2, a3) -> np.ndarray:
    """The unit quaternion q with A_q(q) = A_euler(a1, a2, a3) (eqs. 40, 43)."""
    qz = np.r_[0.0, 0.0, np.sin(a1 / 2), np.cos(a1 / 2)]
    qy = np.r_[0.0, np.sin(a2 / 2), 0.0, np.cos(a2 / 2)]
    qx = np.r_[np.sin(a3 / 2), 0.0, 0.0, np.cos(a3 / 2)]
    return quat_multiply(quat_multiply(qz, qy), qx)


def _angle(dq) -> float:
    return float(np.degrees(2 * np.arctan2(np.linalg.norm(dq[:3]), abs(dq[3]))))


def attitude_error_deg(q_est, q_true) -> np.ndarray:
    """Absolute attitude error (Figure 12), degrees: the angle of the rotation from the true
    attitude to the estimated one (the estimate normalised; q and -q are one attitude).

    ``q_est`` and ``q_true`` are (4,) or (K, 4) arrays of [q1, q2, q3, q0]; returns (K,)."""
    q_est = np.atleast_2d(np.asarray(q_est, dtype=np.float64))
    q_true = np.atleast_2d(np.asarray(q_true, dtype=np.float64))
    return np.array([_angle(quat_multiply(_conjugate(t), e / np.linalg.norm(e)))
                     for e, t in zip(q_est, q_true)])


def _rotation_vector(dq) -> np.ndarray:
    """The axis times the angle (rad) of a unit quaternion."""
    s = np.linalg.norm(dq[:3])
    return np.zeros(3) if s == 0 else dq[:3] / s * 2 * np.arctan2(s, dq[3])


class Nanosat(UkfApplication):
    """The nanosatellite attitude and gyro-bias filter, n = 7, nw = 7, nv = 6, m = 6 (M = 20).

    Parameters
    ----------
    rate : float
        Samples per second (dt = 1 / rate).
    sigma_a, sigma_m : float
        Accelerometer (m/s^2) and magnetometer (gauss) noise, standard deviations: the
        simulated sensors' and R's.
    """

    n, nw, nv, m = 7, 7, 6, 6
    nu = 3  #: the gyro's reading, rad/s
    W0 = 0.0
    eta_q = 1e-6  #: covariance of the quaternion-rate noise (section 4.5)
    eta_d = 1e-2  #: covariance of the bias drift rate, (rad/s^2)^2 (section 4.5)
    sigma_g = np.radians(0.1)  #: the simulated gyro's noise, rad/s
    bias = (0.05, -0.03, 0.04)  #: the true gyro bias at t = 0, rad/s
    euler_rates = np.radians([3.0, -2.0, 4.0])  #: the tumble, rad/s, angles a1, a2, a3 of (43)
    start_spread = np.radians(10.0)  #: the first attitude's angles are drawn in +- this

    def __init__(self, rate: float = RATE, sigma_a: float = 1e-3 * G, sigma_m: float = 1e-3):
        self.dt = 1.0 / rate
        self.x0 = np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0])
        self.P0 = np.eye(7) * 1e-2  # not eq. (42)'s I: see the module's docstring
        self.Q = np.diag([self.eta_q] * 4 + [self.eta_d] * 3)
        self.R = np.diag([sigma_a ** 2] * 3 + [sigma_m ** 2] * 3)

    def f(self, x, w, u, dt):
        """Eqs. (37)-(38), integrating the gyro reading less the estimated bias."""
        x = np.asarray(x, dtype=np.float64)
        q, q0, b = x[:3], x[3], x[4:]
        omega = np.asarray(u, dtype=np.float64) - b
        q_cross = np.array([[0.0, -q[2], q[1]], [q[2], 0.0, -q[0]], [-q[1], q[0], 0.0]])  # (31)
        rate = np.r_[0.5 * (q0 * np.eye(3) + q_cross) @ omega, -0.5 * q @ omega, 0.0, 0.0, 0.0]
        return x + (rate + w) * dt

    def h(self, x, v):
        """Eq. (39): gravity and the magnetic field as A_q(q) turns them."""
        A = rotation(x[:4])
        return np.r_[A @ (G * B_A), A @ B_M] + v

    def scenario(self, steps: int, seed: int) -> Scenario:
        """``steps`` samples of the tumble: truth, gyro readings (u) and the accelerometer and
        magnetometer readings (z)."""
        rng = np.random.default_rng(seed)
        dt = self.dt
        t = np.arange(steps + 1) * dt
        angles = rng.uniform(-self.start_spread, self.start_spread, 3) + np.outer(t, self.euler_rates)
        q = np.array([euler_quaternion(*a) for a in angles])  # continuous in t: no sign flips
        bias = np.array(self.bias, dtype=np.float64)
        truth, u, z = [], [], []
        noise = np.sqrt(np.diag(self.R))
        for k in range(steps):
            # the mean body rate over the interval, which moves q[k] to q[k + 1]
            omega = _rotation_vector(quat_multiply(_conjugate(q[k]), q[k + 1])) / dt
            u.append(omega + bias + rng.normal(0.0, self.sigma_g, 3))  # (32)
            bias = bias + rng.normal(0.0, np.sqrt(self.eta_d), 3) * dt  # (33)
            truth.append(np.r_[q[k + 1], bias])
            z.append(self.h(truth[-1], rng.normal(0.0, noise)))  # (34), (35)
        return Scenario(t[1:], np.array(truth), np.array(u), np.array(z))


class NanosatPrinted(Nanosat):
    """:class:`Nanosat` with eq. (42)'s printed P0 = I: the setup on which the ldl form's
    binary32 core raises err_pivot and the square-root form's (``--form sqrt``) does not
    (``python -m kfgen.sim.ukf.montecarlo``)."""

    def __init__(self, rate: float = RATE, sigma_a: float = 1e-3 * G, sigma_m: float = 1e-3):
        super().__init__(rate, sigma_a, sigma_m)
        self.P0 = np.eye(7)
