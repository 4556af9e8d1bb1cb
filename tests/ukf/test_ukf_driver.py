"""The UKF's generated Python driver (``TOP_driver.py``) on the golden device (no RTL), the
tracker application's iterations: the chapter's three steps with f and h in the driver (LDLᵀ
and square-root forms) and f and h on chip; after load and every iteration the core's memory
equals what the simulation's own software (:func:`kfgen.sim.ukf.software.iteration` on
:class:`~kfgen.sim.ukf.software.GoldenCore`) leaves, word for word, and the driver returns its
estimate."""

import numpy as np
import pytest

from kfgen.hdl.ukf.params import UkfParams
from kfgen.hdl.ukf.steps import programs
from kfgen.sim.engine.device import GoldenDevice
from kfgen.sim.ukf.app import load_app
from kfgen.sim.ukf.software import GoldenCore, complete, initial_words, iteration

from helpers import python_driver

TRACKER = "kfgen.sim.ukf.apps.tracker:Tracker"


@pytest.mark.parametrize("how", ["ldl", "sqrt", "on_chip"])
def test_driver_on_golden_device(tmp_path, how):
    app = load_app(TRACKER)
    params = (dict(app.core_parameters(), app=TRACKER, on_chip=True) if how == "on_chip"
              else dict(app.core_parameters(), form="sqrt" if how == "sqrt" else "ldl"))
    man, drv = python_driver(tmp_path, "ukf", name="ukf_drv", pes=1, **params)
    p = UkfParams(**man["parameters"])
    dev = GoldenDevice(man, UkfParams, programs)
    core = drv.ukf_drv(dev)
    ref = GoldenCore(p)
    core.load(app.x0, app.P0, app.Q, app.R)
    for name, words in initial_words(app, p.fmt, p.form).items():
        complete(ref.write(name, words))
    assert dev.mem == ref.mem
    scenario = app.scenario(3, seed=4)
    for z in scenario.z:
        if how == "on_chip":
            x, P = core.step(z)
        else:
            x, P = core.step(z, f=lambda x, w, u: app.f(x, w, u, app.dt), h=app.h)
        complete(iteration(ref, app, p.fmt, None, z, on_chip=how == "on_chip"))
        assert dev.mem == ref.mem
        assert np.array_equal(x, dev.values("x").ravel())
        S = dev.values("sqrtP" if how == "sqrt" else "P")
        assert np.array_equal(P, np.tril(S) @ np.tril(S).T if how == "sqrt" else S)
    assert dev.steps == (["iteration"] * 3 if how == "on_chip" else ["sig_gen", "predict", "update"] * 3)
    with pytest.raises(ValueError, match="f and h" if how != "on_chip" else "z holds"):
        core.step(np.zeros(2 if how != "on_chip" else 5))
