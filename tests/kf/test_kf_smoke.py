"""The KF's shipped-testbench plan (:mod:`kfgen.sim.kf.smoke`) on the golden model alone: a
steady-gain core's first start runs the gain program too, and the gain the plan loads (numpy's
Riccati recursion: generating needs no scipy) is the DARE's."""

import numpy as np

from kfgen.hdl.kf.params import KfParams
from kfgen.sim.engine.script import START
from kfgen.sim.kf.reference import steady_gain
from kfgen.sim.kf.smoke import ITERATIONS, _riccati_gain, smoke_plan, system

from helpers import python_driver


def test_steady_gain_plan_counts_the_gain_program(tmp_path):
    man, _ = python_driver(tmp_path, "kf", name="kf_plan", states=3, measurements=1, inputs=1, steady_gain=True)
    plan = smoke_plan(KfParams(**man["parameters"]), man)
    cycles = man["cycles"]
    assert [op[3] for op in plan["ops"] if op[0] == START] == \
        [cycles["gain"] + cycles["iterate"]] + [cycles["iterate"]] * (ITERATIONS - 1)


def test_the_plans_gain_is_the_dare():
    values = system(KfParams(states=3, measurements=1, inputs=1, steady_gain=True), np.random.default_rng(1))
    F, H, Q, R = (values[k] for k in ("F", "H", "Q", "R"))
    assert np.allclose(_riccati_gain(F, H, Q, R), steady_gain(F, H, Q, R), rtol=1e-9, atol=1e-12)
