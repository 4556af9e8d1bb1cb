"""The EKF's generated C driver (``TOP_driver.c``, compiled with its MMIO hooks) on the golden
device (no RTL), the tracker's and the nanosatellite's (a control input u) scenarios: what it leaves in the core's memory after
``TOP_load`` and every ``TOP_iterate`` equals the golden model driven by hand, word for word,
its estimate is the golden model's, err_pivot is returned and a core of another ID refused. On
the Verilated core: ``kfgen.sim.ekf.tb.c_driver`` in tests/ekf/test_ekf_core.py."""

import numpy as np
import pytest

from kfgen.hdl.ekf.params import EkfParams
from kfgen.hdl.ekf.steps import programs
from kfgen.hdl.engine.app import load_app
from kfgen.sim.ekf.reference import measurements
from kfgen.sim.engine.cdriver import CDriver
from kfgen.sim.engine.device import GoldenDevice

from helpers import GoldenRun, c_driver


@pytest.mark.parametrize("spec", ["tracker:Tracker", "nanosat:Nanosat"])  # the nanosatellite has a control input
def test_c_driver_on_golden_device(tmp_path, spec):
    man, lib = c_driver(tmp_path, "ekf", name="ekf_c", app=spec, pes=1)
    p = EkfParams(**man["parameters"])
    app = load_app(p.app)
    dev = GoldenDevice(man, EkfParams, programs)
    drv = CDriver.on_device(lib, "ekf_c", dev)
    assert drv.init() == 0
    ref = GoldenRun(programs(p))
    drv("load", app.x0, app.P0, app.Q, app.R)
    for name, value in (("x", app.x0), ("P", app.P0), ("Q", app.Q), ("R", app.R)):
        ref.write(name, value)
    assert dev.mem == ref.mem
    us, zs = measurements(app, 3, 7)
    x, P = np.zeros(p.n), np.zeros(p.n * p.n)
    for u, z in zip(us, zs):
        assert drv("iterate", u if p.nu else None, z) == 0
        ref.write("z", z)
        if p.nu:
            ref.write("u", u)
        assert not ref.run("iterate").pivot
        assert dev.mem == ref.mem
        drv("estimate", x, P)
        assert np.array_equal(x, dev.values("x").ravel()) and np.array_equal(P.reshape(p.n, p.n), dev.values("P"))
    drv("estimate", None, P)  # NULL skips x
    assert dev.steps == ["iterate"] * 3
    drv("write", dev.offset("R"), -1e9 * np.eye(p.nv), p.nv * p.nv)
    assert drv("iterate", us[0] if p.nu else None, zs[0]) & 1 << dev.lsb("STATUS", "err_pivot")
    dev.ident ^= 1 << 56  # another m: not this driver's core
    assert drv.init() == -1
