"""The application API of the IMM core: a user's own model set and its scenario, run on the RTL
by ``python -m kfgen.gen.cosim imm --app FILE.py:Class`` (docs/imm.md, "Your own model set on
the RTL").

An application is a class, subclass of :class:`ImmApplication`, named ``file.py:Class`` or
``module:Class`` and loaded as the UKF's are (:func:`load_imm_app`, over
:func:`kfgen.hdl.engine.app.load_app`): the models (:class:`~kfgen.sim.imm.reference.ImmModel`),
the transition matrix pi, the initial probabilities mu0, the initial estimates x0 and P0 (one
for every model, or one each), and a seeded :meth:`ImmApplication.scenario`. Everything is
checked when it loads, each wrong value named on one line (:class:`AppError`), before a core
is generated.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from kfgen.hdl.engine.app import AppError, _positive_definite, checked_array, load_app, one_line

from .reference import ImmModel, ImmSystem

__all__ = ["AppError", "ImmApplication", "ImmModel", "ImmScenario", "load_imm_app", "checked_scenario"]

#: How far mu0 may be from summing to one (pi's rows: :data:`kfgen.sim.imm.reference.ROW_SUM_TOLERANCE`).
MU_SUM_TOLERANCE = 1e-9


class ImmScenario(NamedTuple):
    """A simulated run: the measurements ``z`` (steps, d) and, if the application knows it,
    the true state ``truth`` (steps, n) after each step."""
    z: np.ndarray
    truth: np.ndarray | None = None


class ImmApplication:
    """Base class of an IMM application.

    Attributes
    ----------
    models : list of ImmModel
        R >= 2 models, all of one state size n and measurement size d:
        x' = F x + w, w ~ N(0, Q); z = H x + v, v ~ N(0, R).
    pi : array_like
        (R, R) transition matrix, ``pi[i, j]`` the probability of a switch from model i to
        model j: non-negative, every row sums to 1.
    mu0 : array_like
        (R,) initial model probabilities, non-negative, summing to 1.
    x0 : array_like
        The initial state: (n,), every model's, or (R, n), one a model.
    P0 : array_like
        Its covariance: (n, n) or (R, n, n), symmetric positive definite.

    Subclasses set these (as class attributes or in ``__init__``, which takes no arguments)
    and define :meth:`scenario`.
    """

    models: tuple = ()
    pi = mu0 = x0 = P0 = None

    def scenario(self, steps: int, seed: int):
        """A simulated run of ``steps`` measurements, reproducible from ``seed``: an
        :class:`ImmScenario`, or the measurements alone, a (steps, d) array."""
        raise NotImplementedError

    def system(self) -> ImmSystem:
        """The models and pi as the references take them."""
        return ImmSystem(tuple(self.models), np.asarray(self.pi, dtype=np.float64))

    def initial(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """mu0 (R,), the models' states (R, n) and covariances (R, n, n): a shared x0 or P0
        repeated for every model."""
        R, n = len(self.models), self.models[0].n
        x0 = np.asarray(self.x0, dtype=np.float64)
        P0 = np.asarray(self.P0, dtype=np.float64)
        return (np.asarray(self.mu0, dtype=np.float64), np.broadcast_to(x0, (R, n)).copy(),
                np.broadcast_to(P0, (R, n, n)).copy())

    def core_parameters(self) -> dict:
        """The IMM core's parameters this application fixes: keyword arguments of
        :class:`kfgen.hdl.imm.params.ImmParams`, ``models`` (R), ``states`` (n) and
        ``measurements`` (d)."""
        return {"models": len(self.models), "states": self.models[0].n, "measurements": self.models[0].d}

    def check(self) -> None:
        """Validate the models (at least two ImmModel of one n and d, every R positive
        definite: the core factorises each innovation covariance H P H^T + R, and Q positive
        semi-definite), pi (row-stochastic R x R), mu0 (a distribution), x0 and P0 (their
        shapes, finite, P0 symmetric positive definite).

        Raises
        ------
        AppError
            Naming the first attribute that is wrong and what it should be.
        """
        name = type(self).__name__
        models = self.models
        if not isinstance(models, (list, tuple)) or len(models) < 2 \
                or not all(isinstance(m, ImmModel) for m in models):
            got = f"{len(models)} of them" if isinstance(models, (list, tuple)) else type(models).__name__
            raise AppError(f"{name}.models must be a list of at least two ImmModel "
                           f"(kfgen.sim.imm.app.ImmModel), not {got}")
        R = len(models)
        try:
            ImmSystem(tuple(models), checked_array(f"{name}.pi", self.pi, (R, R)))
        except ValueError as exc:
            raise AppError(f"{name}: {one_line(exc)}") from None
        n = models[0].n
        for m in models:
            _positive_definite(f"{name}: model {m.name!r}: R", m.R)
            low = float(np.linalg.eigvalsh(m.Q).min())
            if low < -1e-12 * max(float(np.abs(m.Q).max()), 1e-300):
                raise AppError(f"{name}: model {m.name!r}: Q must be positive semi-definite, "
                               f"not with eigenvalue {low:.3g}")
        mu0 = checked_array(f"{name}.mu0", self.mu0, (R,))
        if np.any(mu0 < 0) or abs(mu0.sum() - 1) > MU_SUM_TOLERANCE:
            raise AppError(f"{name}.mu0 must be non-negative and sum to 1 (a probability per model), "
                           f"not {mu0.tolist()}")
        x0 = np.asarray(self.x0, dtype=np.float64) if self.x0 is not None else None
        shared = x0 is not None and x0.ndim == 1
        checked_array(f"{name}.x0", self.x0, (n,) if shared else (R, n))
        P0 = np.asarray(self.P0, dtype=np.float64) if self.P0 is not None else None
        shared = P0 is not None and P0.ndim == 2
        P0 = checked_array(f"{name}.P0", self.P0, (n, n) if shared else (R, n, n))
        for r, P in enumerate([P0] if shared else P0):
            _positive_definite(f"{name}.P0" if shared else f"{name}.P0[{r}]", P)


def load_imm_app(spec: str) -> ImmApplication:
    """The IMM application ``spec`` names (``file.py:Class`` or ``module:Class``), instantiated
    with no arguments and checked (:meth:`ImmApplication.check`).

    Raises
    ------
    AppError
        One line: the spec, the import, the class or a value is wrong.
    """
    return load_app(spec, ImmApplication, "kfgen.sim.imm.app")


def checked_scenario(app: ImmApplication, steps: int, seed: int) -> ImmScenario:
    """``app.scenario(steps, seed)`` as an :class:`ImmScenario` of float64 arrays, checked:
    z finite of shape (steps, d), the truth (if any) of shape (steps, n).

    Raises
    ------
    AppError
        One line naming what the scenario returned wrong (or what it raised).
    """
    name = f"{type(app).__name__}.scenario({steps}, {seed})"
    try:
        got = app.scenario(steps, seed)
    except Exception as exc:  # the user's function: whatever it raises, one line
        raise AppError(f"{name} raised {type(exc).__name__}: {one_line(exc)}") from None
    z, truth = (got.z, got.truth) if isinstance(got, ImmScenario) else (got, None)
    d, n = app.models[0].d, app.models[0].n
    z = checked_array(f"{name}.z", z, (steps, d))
    if truth is not None:
        truth = checked_array(f"{name}.truth", truth, (steps, n))
    return ImmScenario(z, truth)
