"""The EKF's generated Python driver (``TOP_driver.py``) on the golden device (no RTL): the
tracker's scenario; after load and every iteration the core's memory equals the golden model
driven by hand, word for word, and the driver returns its estimate."""

import numpy as np

from kfgen.hdl.ekf.params import EkfParams
from kfgen.hdl.ekf.steps import programs
from kfgen.hdl.engine.app import load_app
from kfgen.sim.ekf.reference import measurements
from kfgen.sim.engine.device import GoldenDevice

from helpers import GoldenRun, python_driver


def test_driver_on_golden_device(tmp_path):
    man, drv = python_driver(tmp_path, "ekf", name="ekf_drv", app="tracker:Tracker", pes=1)
    p = EkfParams(**man["parameters"])
    app = load_app(p.app)
    dev = GoldenDevice(man, EkfParams, programs)
    core = drv.ekf_drv(dev)
    ref = GoldenRun(programs(p))
    assert [arg for arg, _, _ in drv.LOAD] == ["x0", "P0", "Q", "R"]
    core.load(app.x0, app.P0, app.Q, app.R)
    for name, value in (("x", app.x0), ("P", app.P0), ("Q", app.Q), ("R", app.R)):
        ref.write(name, value)
    assert dev.mem == ref.mem
    us, zs = measurements(app, 3, 7)
    for z in zs:
        x, P = core.step(z)
        ref.write("z", z)
        assert not ref.run("iterate").pivot
        assert dev.mem == ref.mem
        assert np.array_equal(x, dev.values("x").ravel()) and np.array_equal(P, dev.values("P"))
