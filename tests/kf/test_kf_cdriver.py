"""The KF's generated C driver (``TOP_driver.c``, compiled with its MMIO hooks) on the golden
device (no RTL): what it leaves in the core's memory after ``TOP_load``, every ``TOP_iterate``
and ``TOP_set_gain`` equals the golden model driven by hand, word for word (binary32 by the C
cast, binary64 as two words), its estimate is the golden model's, a core of another ID is
refused and err_pivot is returned. On the Verilated core: ``kfgen.sim.kf.tb.c_driver`` in
tests/kf/test_kf_core.py."""

import numpy as np
import pytest

from kfgen.hdl.kf.params import KfParams
from kfgen.hdl.kf.steps import programs
from kfgen.sim.engine.cdriver import CDriver
from kfgen.sim.engine.device import GoldenDevice
from kfgen.sim.kf.tb import system

from helpers import GoldenRun, c_driver


@pytest.mark.parametrize("params", [dict(states=4, measurements=2, inputs=1),
                                    dict(states=3, measurements=2, inputs=1, steady_gain=True),
                                    dict(states=3, measurements=1, format="binary64")],
                         ids=["small", "steady", "binary64"])
def test_c_driver_on_golden_device(tmp_path, params):
    man, lib = c_driver(tmp_path, "kf", name="kf_c", **params)
    p = KfParams(**man["parameters"])
    dev = GoldenDevice(man, KfParams, programs)
    drv = CDriver.on_device(lib, "kf_c", dev)
    assert drv.init() == 0
    ref = GoldenRun(programs(p))
    rng = np.random.default_rng(3)
    v = system(p, rng)
    B = v["B"] if p.nu else None
    if p.steady_gain:
        drv("load", v["x"], v["F"], B, v["H"], v["K"])
    else:
        drv("load", v["x"], v["P"], v["F"], B, v["Q"], v["H"], v["R"])
    for name, value in v.items():
        ref.write(name, value)
    assert dev.mem == ref.mem
    x, P = np.zeros(p.n), np.zeros(p.n * p.n)
    for it in range(3):
        if p.steady_gain and it == 2:  # a new gain, its step started by the driver
            assert drv("set_gain", v["K"] * 0.5) == 0
            ref.write("K", v["K"] * 0.5)
            ref.run("gain")
            assert dev.steps[-1] == "gain" and dev.mem == ref.mem
        z, u = rng.normal(size=p.m), rng.normal(size=p.nu)
        assert drv("iterate", u if p.nu else None, z) == 0
        ref.write("z", z)
        if p.nu:
            ref.write("u", u)
        assert not ref.run("iterate").pivot
        assert dev.mem == ref.mem
        drv("estimate", x) if p.steady_gain else drv("estimate", x, P)
        assert np.array_equal(x, dev.values("x").ravel())
        assert p.steady_gain or np.array_equal(P.reshape(p.n, p.n), dev.values("P"))
    want = (["iterate", "iterate", "gain", "iterate"] if p.steady_gain else ["iterate"] * 3)
    assert dev.steps == want
    if not p.steady_gain:  # R not positive definite: S indefinite, the iteration returns err_pivot
        drv("write", dev.offset("R"), -np.eye(p.m), p.m * p.m)
        assert drv("iterate", u if p.nu else None, z) == 1 << dev.lsb("STATUS", "err_pivot")
    dev.ident ^= 1 << 32  # another n: not this driver's core
    assert drv.init() == -1

