"""An application's scenario through the float64 reference and through the bit-exact golden
model of its core, for accuracy checks and Figure 12.

Both return the estimate x after each iteration's update, (K, n), to be held against the
scenario's truth. The golden model runs the core's step programs
(:mod:`kfgen.sim.linalg.exec`) with the processor's software between them
(:func:`kfgen.sim.ukf.software.iteration`): what the generated core computes, word for word.
"""

from __future__ import annotations

import numpy as np

from kfgen.hdl.ukf.params import UkfParams
from kfgen.sim.linalg.exec import from_words

from .app import Scenario, UkfApplication
from .reference import AugmentedUKF, SquareRootUKF
from .software import GoldenCore, complete, initial_words, iteration

__all__ = ["run_reference", "run_golden"]


def run_reference(app: UkfApplication, sc: Scenario, form: str = "ldl") -> np.ndarray:
    """The float64 reference (:class:`~kfgen.sim.ukf.reference.AugmentedUKF`, or
    :class:`~kfgen.sim.ukf.reference.SquareRootUKF` for ``form="sqrt"``) over ``sc``."""
    ukf = (SquareRootUKF if form == "sqrt" else AugmentedUKF)(app.n, app.nw, app.nv, app.m, app.f, app.h, app.W0, app.x0, app.P0, app.Q, app.R)
    out = np.empty((len(sc.z), app.n))
    for k, (u, z) in enumerate(sc.inputs()):
        ukf.predict(u, app.dt)
        ukf.update(z)
        out[k] = ukf.x
    return out


def run_golden(app: UkfApplication, sc: Scenario, format: str = "binary32", pes: int = 1,
               on_chip: str | None = None, form: str = "ldl") -> np.ndarray:
    """The bit-exact model of the core sized for ``app`` in ``format`` over ``sc``; with
    ``on_chip`` (the application's spec, ``module:Class``) the core with f and h compiled
    into it (``kfgen ukf --app SPEC --on-chip``), one ``iteration`` step per measurement;
    ``form`` the core's covariance form (``--form``).

    Raises
    ------
    kfgen.sim.ukf.software.StepError
        When a step raises ``err_pivot`` or ``err_nan``.
    """
    chip = {} if on_chip is None else {"app": on_chip, "on_chip": True}
    core = GoldenCore(UkfParams(**app.core_parameters(), format=format, pes=pes, form=form, **chip))
    for name, words in initial_words(app, core.fmt, form).items():
        complete(core.write(name, words))
    out = np.empty((len(sc.z), app.n))
    for k, (u, z) in enumerate(sc.inputs()):
        complete(iteration(core, app, core.fmt, u, z, on_chip is not None))
        out[k] = from_words(core.fmt, complete(core.read("x")))
    return out
