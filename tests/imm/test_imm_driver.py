"""The IMM's generated Python driver (``TOP_driver.py``) on the golden device (no RTL): load
takes the models' states and covariances as x0 and P0, their Q and R, and the model set (pi,
mu, F, H) by keyword; after load and every iteration the core's memory equals the golden model
driven by hand, word for word, and the driver returns the combined estimate."""

import numpy as np

from kfgen.hdl.imm.params import ImmParams
from kfgen.hdl.imm.steps import programs
from kfgen.sim.engine.device import GoldenDevice
from kfgen.sim.imm.tb import system

from helpers import GoldenRun, python_driver


def test_driver_on_golden_device(tmp_path):
    man, drv = python_driver(tmp_path, "imm", name="imm_drv", models=3, states=2, measurements=2, pes=1)
    p = ImmParams(**man["parameters"])
    dev = GoldenDevice(man, ImmParams, programs)
    core = drv.imm_drv(dev)
    ref = GoldenRun(programs(p))
    values = system(p, np.random.default_rng(3))
    assert [(arg, name) for arg, name, _ in drv.LOAD] == [
        ("x0", "x_model"), ("P0", "P_model"), ("Q", "Q"), ("R", "R"), ("pi", "pi"), ("mu", "mu"), ("F", "F"),
        ("H", "H")]
    core.load(values["x_model"], values["P_model"], values["Q"], values["R"], pi=values["pi"], mu=values["mu"],
              F=values["F"], H=values["H"])
    for name, value in values.items():
        ref.write(name, value)
    assert dev.mem == ref.mem
    rng = np.random.default_rng(4)
    for _ in range(3):
        z = rng.normal(size=p.d)
        x, P = core.step(z)
        ref.write("z", z)
        assert not ref.run("iterate").pivot
        assert dev.mem == ref.mem
        assert np.array_equal(x, dev.values("x").ravel()) and np.array_equal(P, dev.values("P"))
        assert np.array_equal(core.read_region("mu"), dev.values("mu"))
