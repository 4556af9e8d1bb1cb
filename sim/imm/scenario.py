"""The slides' example (seed 004, "Example Scenario"): a satellite link whose channel changes
condition, tracked by an IMM with one constant-acceleration model per condition.

The slides name the state model (constant acceleration), the measurements (SNR, SIR) and the
five conditions, and give no numbers; every number below is ours.

Design
------
A Ka-band downlink sampled once a second (dt = 1 s) by a terminal that estimates its SNR and
its SIR, the interference being the co-channel and cross-polar beams of the same satellite.
Interference that shares the carrier's path fades with it, so path effects cancel in the SIR
except where they change the coupling: rain depolarises (the cross-polar discrimination falls
as the co-polar attenuation grows, ITU-R P.618) and multipath brings in reflected
interference. Each condition thus leaves its own signature in the two measurements:

* clear sky: both quiet (a slow wander of a tenth of a dB);
* rain fade: a slow, deep, smooth SNR fade (a mean depth of 5-12 dB, brought in and out over
  40 s, the rain cell's intensity varying by 30 % on a scale of tens of seconds, so that the
  deepest moments reach about 20 dB), the SIR sagging by half the attenuation;
* ionospheric scintillation: fast, large SNR fluctuation (2.5 dB, correlation 1 s), SIR
  unchanged;
* tropospheric scintillation: milder and slower (0.8 dB, 3 s), SIR unchanged;
* multipath fading: fast fading of both (1.5 dB on the SNR, 2 dB on the SIR, 0.5 s).

The truth is drawn from these physical pictures (:func:`satlink`), not from the filter's
models: no constant-acceleration model stays bounded over thousands of steps. The models share
F, H and R (the terminal's estimator, the same in every condition) and differ in Q, which
holds what each condition does to the state: white jerk on a channel's acceleration for
smooth motion (rain), white noise on its level for fluctuation that is nearly white at one
sample a second (scintillation, multipath: the increment variance 2 sigma^2 (1 - rho) of the
AR(1) fluctuation, rho = exp(-dt / tau), plus the wander's 2e-4; a random-walk level absorbing
it follows the fluctuation, so these models track the actual SNR, not a local mean). The IMM
tells the conditions apart by how widely each model's innovations spread: the level-noise
variances of neighbouring conditions differ by factors of 2 to 20 (clear 2e-4, trop 0.36,
multipath 3.9 and on the SIR 6.9, iono 7.9), and rain is the one condition whose SNR and SIR
move together and smoothly. The rain model's jerk density is tuned for identification, below
the matched value (its mean normalised innovation squared in rain is 1.0 to 1.3 times d; the
matched 3e-4 widens its S until the clear-sky model wins the quieter stretches of a fade).

The numbers
-----------
dt = 1 s. Clear-sky link budget: SNR 14 dB, SIR 20 dB. The terminal's estimator: 0.2 dB on the
SNR, 0.3 dB on the SIR, R = diag(0.04, 0.09) dB^2. Always present: a wander of SNR and SIR
(Ornstein-Uhlenbeck, 0.1 dB, 100 s).

========================== ======== ===================================== ========================
condition                  dwell, s truth (on top of link budget, wander) model q_level; q_jerk
                                                                          (SNR, SIR)
========================== ======== ===================================== ========================
clear sky                  100-300  nothing more                          2e-4, 2e-4; 1e-7, 1e-7
rain fade                  150-400  SNR -A, SIR -A/2; A = depth (5-12 dB  2e-4, 2e-4;
                                    uniform) x (1 + 0.3 g), 40 s ramps    5e-5, 1.25e-5
ionospheric scintillation   60-180  SNR + AR(1) of 2.5 dB, tau 1 s        7.9, 2e-4; 1e-7, 1e-7
tropospheric scintillation  80-250  SNR + AR(1) of 0.8 dB, tau 3 s        0.36, 2e-4; 1e-7, 1e-7
multipath fading            40-150  SNR + AR(1) of 1.5 dB, SIR + AR(1)    3.9, 6.9; 1e-7, 1e-7
                                    of 2 dB, both tau 0.5 s
========================== ======== ===================================== ========================

q_level is in dB^2 per step, added to the level's entry of Q; q_jerk in dB^2/s^5 is the
spectral density of the white jerk that the constant-acceleration model integrates over dt.
g is the rain cell's intensity variation: unit white noise through three cascaded first-order
lags of 10 s, scaled to unit variance (with three lags its third derivative, the jerk, is
white noise on scales short against 10 s: the constant-acceleration model's own assumption). The raised-cosine ramps bring A in and out
within the rain's dwell. A fluctuation decays with its own correlation time once its
condition ends, so the truth never jumps.

The schedule is a semi-Markov chain: it starts in clear sky; from clear sky it moves to one of
the four impairments with equal probability, from an impairment back to clear sky with
probability 1/2 or to each other impairment with 1/6; each dwell is drawn uniformly from its
condition's range (the mean stay is 176 s). The IMM's transition matrix pi has 0.99 on
the diagonal and 0.0025 elsewhere: a mean stay of 100 steps, near the truth's, for which the
IMM's most probable model follows a change of condition within 0 to 12 steps (seeds 1 to
6); with 0.97 it changes 1.4 times as often and is right up to 5 points less often.

The IMM starts from the link budget: every model at [14, 0, 0, 20, 0, 0],
P0 = diag(4, 0.04, 1e-3, 4, 0.04, 1e-3), mu0 uniform. Measurement k is taken at t = k dt;
truth row k is the state then. The truth's rate and acceleration columns are those of its
smooth part, the rain attenuation (central differences); the fluctuations and the wander
enter the level only, as the models' level noise does. Everything random comes from
``numpy.random.default_rng(seed)``.

With the default 2000 steps the float64 IMM's most probable model is the true condition at
92 % to 98 % of the steps over seeds 1 to 6, 95.2 % with the default seed 4.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .reference import ImmModel, ImmSystem

__all__ = ["CONDITIONS", "CLEAR", "RAIN", "IONO", "TROPO", "MULTIPATH", "DT", "SNR_CLEAR",
           "SIR_CLEAR", "SIGMA_Z", "WANDER", "PI_STAY", "STEPS", "SEED", "Condition",
           "ca_transition", "ca_noise", "system", "Scenario", "satlink", "identification"]

DT = 1.0  #: sampling interval, s
SNR_CLEAR = 14.0  #: clear-sky link budget, dB
SIR_CLEAR = 20.0  #: dB
SIGMA_Z = (0.2, 0.3)  #: the terminal's SNR and SIR estimator noise, dB
WANDER = (0.1, 100.0)  #: always-present wander: standard deviation (dB), correlation time (s)
RAIN_DEPTH = (5.0, 12.0)  #: range of a rain event's mean attenuation, dB
RAIN_VARIATION = 0.3  #: relative standard deviation of the rain cell's intensity
RAIN_TAU = 10.0  #: time constant of each of the intensity's lags, s
RAIN_LAGS = 3  #: cascaded lags shaping the intensity
RAIN_RAMP = 40.0  #: duration of the raised-cosine rise and fall, s
RAIN_SIR = 0.5  #: SIR lost per dB of rain attenuation (depolarisation)
PI_STAY = 0.99  #: the IMM's probability of staying in a model
STEPS = 2000  #: default length of a scenario
SEED = 4  #: default seed (the slides are seed 004)


@dataclass(frozen=True)
class Condition:
    """One channel condition: its dwell range, its fluctuation in the truth and its model.

    Parameters
    ----------
    name : the condition, as the slides name it.
    dwell : (shortest, longest) stay, in steps.
    fluctuation : per channel (SNR, SIR), the AR(1) fluctuation's (standard deviation in dB,
        correlation time in s); (0, 1) for none.
    q_level, q_jerk : per channel (SNR, SIR), the model's level-noise variance per step (dB^2)
        and white-jerk spectral density (dB^2/s^5).
    """
    name: str
    dwell: tuple[int, int]
    fluctuation: tuple[tuple[float, float], tuple[float, float]]
    q_level: tuple[float, float]
    q_jerk: tuple[float, float]


_QUIET = (0.0, 1.0)

CONDITIONS = (
    Condition("clear sky", (100, 300), (_QUIET, _QUIET), (2e-4, 2e-4), (1e-7, 1e-7)),
    Condition("rain fade", (150, 400), (_QUIET, _QUIET), (2e-4, 2e-4), (5e-5, 1.25e-5)),
    Condition("ionospheric scintillation", (60, 180), ((2.5, 1.0), _QUIET), (7.9, 2e-4),
              (1e-7, 1e-7)),
    Condition("tropospheric scintillation", (80, 250), ((0.8, 3.0), _QUIET), (0.36, 2e-4),
              (1e-7, 1e-7)),
    Condition("multipath fading", (40, 150), ((1.5, 0.5), (2.0, 0.5)), (3.9, 6.9),
              (1e-7, 1e-7)),
)
CLEAR, RAIN, IONO, TROPO, MULTIPATH = range(len(CONDITIONS))


def ca_transition(dt: float = DT) -> np.ndarray:
    """F of the constant-acceleration model of one channel (level, rate, acceleration)."""
    return np.array([[1.0, dt, dt * dt / 2], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])


def ca_noise(q_level: float, q_jerk: float, dt: float = DT) -> np.ndarray:
    """Q of one channel: white jerk of spectral density q_jerk integrated over dt, plus
    q_level on the level."""
    Q = q_jerk * np.array([[dt ** 5 / 20, dt ** 4 / 8, dt ** 3 / 6],
                           [dt ** 4 / 8, dt ** 3 / 3, dt ** 2 / 2],
                           [dt ** 3 / 6, dt ** 2 / 2, dt]])
    Q[0, 0] += q_level
    return Q


def _blockdiag(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    out = np.zeros((a.shape[0] + b.shape[0], a.shape[1] + b.shape[1]))
    out[:a.shape[0], :a.shape[1]] = a
    out[a.shape[0]:, a.shape[1]:] = b
    return out


def system() -> ImmSystem:
    """The five models (state [SNR, SNR rate, SNR accel, SIR, SIR rate, SIR accel], SNR and
    SIR measured) and the transition matrix."""
    F = _blockdiag(ca_transition(), ca_transition())
    H = np.zeros((2, 6))
    H[0, 0] = H[1, 3] = 1.0
    R = np.diag(np.square(SIGMA_Z))
    models = [ImmModel(c.name, F, _blockdiag(ca_noise(c.q_level[0], c.q_jerk[0]),
                                             ca_noise(c.q_level[1], c.q_jerk[1])), H, R)
              for c in CONDITIONS]
    Rm = len(models)
    pi = np.full((Rm, Rm), (1 - PI_STAY) / (Rm - 1))
    np.fill_diagonal(pi, PI_STAY)
    return ImmSystem(tuple(models), pi)


@dataclass(frozen=True)
class Scenario:
    """A seeded run of the satellite link."""
    system: ImmSystem
    truth: np.ndarray  #: (T, 6) the state at each measurement
    condition: np.ndarray  #: (T,) index into CONDITIONS of the true condition
    zs: np.ndarray  #: (T, 2) measured SNR and SIR, dB
    mu0: np.ndarray  #: (R,) initial model probabilities
    xs0: np.ndarray  #: (R, 6) initial model states
    Ps0: np.ndarray  #: (R, 6, 6) initial model covariances
    dt: float
    names: tuple[str, ...]
    seed: int

    @property
    def t(self) -> np.ndarray:
        """Time of each measurement, s."""
        return np.arange(len(self.zs)) * self.dt


def _schedule(rng, steps: int) -> np.ndarray:
    condition = np.empty(steps, dtype=np.int64)
    at, c = 0, CLEAR
    while at < steps:
        lo, hi = CONDITIONS[c].dwell
        dwell = int(rng.integers(lo, hi + 1))
        condition[at:at + dwell] = c
        at += dwell
        if c == CLEAR:
            c = int(rng.integers(1, len(CONDITIONS)))
        elif rng.random() < 0.5:
            c = CLEAR
        else:
            c = int(rng.choice([o for o in range(1, len(CONDITIONS)) if o != c]))
    return condition


def _ar1(rng, active: np.ndarray, sigma: float, tau: float) -> np.ndarray:
    """An AR(1) fluctuation driven only while ``active``; it decays freely otherwise."""
    rho = np.exp(-DT / tau)
    drive = sigma * np.sqrt(1 - rho * rho) * rng.standard_normal(active.size) * active
    out = np.empty(active.size)
    s = 0.0
    for k, e in enumerate(drive):
        s = rho * s + e
        out[k] = s
    return out


def _smooth(rng, steps: int) -> np.ndarray:
    """The rain cell's intensity variation g (unit variance, stationary from the first step):
    unit white noise through RAIN_LAGS cascaded first-order lags of RAIN_TAU."""
    rho = np.exp(-DT / RAIN_TAU)
    # impulse response of the cascade, long enough to start it in steady state
    h = np.zeros(int(40 * RAIN_TAU / DT))
    h[0] = 1.0
    for _ in range(RAIN_LAGS):
        for k in range(1, h.size):
            h[k] += rho * h[k - 1]
    x = np.convolve(rng.standard_normal(steps + h.size - 1), h, mode="valid")
    return x / np.sqrt(np.sum(h * h))


def _rain(rng, condition: np.ndarray) -> np.ndarray:
    """The rain attenuation A >= 0 (dB): per rain event, a depth times a smooth intensity,
    brought in and out by raised-cosine ramps inside the event."""
    steps = condition.size
    g = _smooth(rng, steps)
    A = np.zeros(steps)
    starts = np.flatnonzero(np.diff(np.r_[-1, condition]) != 0)
    for s, e in zip(starts, np.r_[starts[1:], steps]):
        if condition[s] != RAIN:
            continue
        depth = rng.uniform(*RAIN_DEPTH)
        length = e - s
        ramp = min(RAIN_RAMP / DT, length / 2)
        k = np.arange(length)
        env = np.minimum(1.0, np.minimum(k + 1, length - k) / ramp)
        env = 0.5 - 0.5 * np.cos(np.pi * env)
        A[s:e] = env * depth * np.maximum(0.0, 1 + RAIN_VARIATION * g[s:e])
    return A


def satlink(steps: int = STEPS, seed: int = SEED) -> Scenario:
    """A seeded satellite-link scenario of ``steps`` measurements (see the module docstring
    for every number). The same seed gives the same scenario."""
    if not isinstance(steps, (int, np.integer)) or steps < 1:
        raise ValueError(f"steps must be a positive integer, not {steps!r}")
    rng = np.random.default_rng(seed)
    condition = _schedule(rng, steps)
    A = _rain(rng, condition)
    level = [np.full(steps, SNR_CLEAR) - A, np.full(steps, SIR_CLEAR) - RAIN_SIR * A]
    for ch in range(2):
        level[ch] += _ar1(rng, np.ones(steps, dtype=bool), *WANDER)
        for c, cond in enumerate(CONDITIONS):
            sigma, tau = cond.fluctuation[ch]
            if sigma:
                level[ch] += _ar1(rng, condition == c, sigma, tau)
    truth = np.zeros((steps, 6))
    for ch, smooth in enumerate((-A, -RAIN_SIR * A)):
        truth[:, 3 * ch] = level[ch]
        if steps > 1:
            truth[:, 3 * ch + 1] = np.gradient(smooth, DT)
            truth[:, 3 * ch + 2] = np.gradient(truth[:, 3 * ch + 1], DT)
    zs = truth[:, [0, 3]] + rng.standard_normal((steps, 2)) * SIGMA_Z
    sys_ = system()
    R = sys_.R
    x0 = np.array([SNR_CLEAR, 0.0, 0.0, SIR_CLEAR, 0.0, 0.0])
    P0 = np.diag([4.0, 0.04, 1e-3, 4.0, 0.04, 1e-3])
    return Scenario(sys_, truth, condition, zs, np.full(R, 1.0 / R), np.tile(x0, (R, 1)),
                    np.tile(P0, (R, 1, 1)), DT, sys_.names, seed)


def identification(mu: np.ndarray, condition: np.ndarray) -> float:
    """The fraction of steps at which the most probable model (mu, (T, R)) is the true
    condition (T,)."""
    return float(np.mean(np.argmax(mu, axis=1) == condition))
