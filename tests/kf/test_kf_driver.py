"""The KF's generated Python driver (``TOP_driver.py``) on the golden device (no RTL): what it
leaves in the core's memory after load and every iteration equals the golden model driven by
hand, word for word, and it returns the golden estimate; the steady-gain core (no P) too. On
the Verilated core: ``kfgen.sim.kf.tb.python_driver`` in tests/kf/test_kf_core.py."""

import numpy as np
import pytest

from kfgen.hdl.kf.params import KfParams
from kfgen.hdl.kf.steps import programs
from kfgen.sim.engine.device import GoldenDevice
from kfgen.sim.kf.tb import system

from helpers import GoldenRun, python_driver


@pytest.mark.parametrize("params", [dict(states=4, measurements=2, inputs=1),
                                    dict(states=3, measurements=2, inputs=1, steady_gain=True),
                                    dict(states=3, measurements=1, format="binary64")],
                         ids=["small", "steady", "binary64"])
def test_driver_on_golden_device(tmp_path, params):
    man, drv = python_driver(tmp_path, "kf", name="kf_drv", **params)
    p = KfParams(**man["parameters"])
    dev = GoldenDevice(man, KfParams, programs)
    core = drv.kf_drv(dev)
    ref = GoldenRun(programs(p))
    rng = np.random.default_rng(5)
    values = system(p, rng)
    core.load(**{arg: values[name] for arg, name, _ in drv.LOAD})
    for name, v in values.items():
        ref.write(name, v)
    assert dev.mem == ref.mem
    for _ in range(3):
        z, u = rng.normal(size=p.m), rng.normal(size=p.nu)
        x, P = core.step(z, u if p.nu else None)
        ref.write("z", z)
        if p.nu:
            ref.write("u", u)
        assert not ref.run("iterate").pivot
        assert dev.mem == ref.mem
        assert np.array_equal(x, dev.values("x").ravel())
        assert P is None if p.steady_gain else np.array_equal(P, dev.values("P"))
    assert core.status == {"busy": 0, "done": 0, "err_pivot": 0, "err_nan": 0, "err_busy": 0}
    assert core.last_status["done"] == 1
