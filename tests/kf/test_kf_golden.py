"""The linear Kalman filter's golden model (the core's program, bit-exact) against the float64
reference: the full filter in binary64 and binary32, the steady-gain filter, err_pivot, and
the covariance update's long run in binary32 with precise sensors (Joseph's form, the core's,
against the symmetric one)."""

import numpy as np
import pytest

from kfgen.hdl.kf.params import KfParams
from kfgen.hdl.kf.steps import programs
from kfgen.sim.kf.reference import buffer_values, run_golden, run_golden_batch, run_reference, steady_gain
from kfgen.sim.kf.stability import cv_model, measure

from test_kf_reference import random_model


def _run(md, fmt, steady=False, **kw):
    progs = programs(KfParams(states=4, measurements=2, inputs=1, format=fmt, steady_gain=steady))
    values = buffer_values(progs, md["F"], md["H"], md["x0"], md["B"], md["Q"], md["R"], md["P0"], kw.get("K"))
    return run_golden(progs, values, md["zs"], md["us"], keep=("x",) if steady else ("x", "P"))


@pytest.mark.parametrize("fmt,tol", [("binary64", 1e-12), ("binary32", 1e-4)])
def test_golden_matches_reference(fmt, tol):
    """n = 4, m = 2, nu = 1, six iterations: x and P relative to their scale, no flags, P
    exactly symmetric."""
    md = random_model(np.random.default_rng(3))
    gold = _run(md, fmt)
    ref = run_reference(md["F"], md["H"], md["Q"], md["R"], md["x0"], md["P0"], md["zs"], md["B"], md["us"])
    assert not gold["flags"].any()
    for k in range(len(md["zs"])):
        x, P = gold["x"][k, :, 0], gold["P"][k]
        assert np.array_equal(P, P.T)
        assert np.abs(x - ref.x_post[k]).max() <= tol * np.abs(ref.x_post[k]).max()
        assert np.abs(P - ref.P_post[k]).max() <= tol * np.abs(ref.P_post[k]).max()


@pytest.mark.parametrize("fmt,tol", [("binary64", 1e-12), ("binary32", 1e-5)])
def test_steady_gain_matches_reference(fmt, tol):
    """The steady-gain filter with the DARE's K in the buffer: x as the reference's."""
    md = random_model(np.random.default_rng(4))
    K = steady_gain(md["F"], md["H"], md["Q"], md["R"])
    gold = _run(md, fmt, steady=True, K=K)
    ref = run_reference(md["F"], md["H"], md["Q"], md["R"], md["x0"], md["P0"], md["zs"], md["B"], md["us"], K=K)
    assert not gold["flags"].any()
    assert np.abs(gold["x"][..., 0] - ref.x_post).max() <= tol * np.abs(ref.x_post).max()


def test_indefinite_S_sets_err_pivot():
    """R = -10 I makes S indefinite: err_pivot on the first iteration."""
    md = random_model(np.random.default_rng(5))
    md["R"] = -10 * np.eye(2)
    assert _run(md, "binary64")["flags"][0] & 1


def test_batch_runner_is_the_golden_model():
    """The batch runner (over seeds) gives the word-by-word runner's values, bit for bit."""
    md = random_model(np.random.default_rng(6))
    progs = programs(KfParams(states=4, measurements=2, inputs=1))
    values = buffer_values(progs, md["F"], md["H"], md["x0"], md["B"], md["Q"], md["R"], md["P0"])
    one = run_golden(progs, values, md["zs"], md["us"])
    batch = run_golden_batch(progs, values, md["zs"][None], md["us"][None])
    for k in ("x", "P", "flags"):
        assert np.array_equal(batch[k][0], one[k]), k


def _long_run(steps):
    """Joseph's form stays positive definite with a sensor of R = 1e-8 against P0 = I; the
    symmetric form does not (the reason the core takes Joseph's: hdl/kf/programs.py)."""
    joseph = measure(cv_model(1, r=1e-8), "joseph", steps, 2)
    assert joseph["indefinite"] == 0 and joseph["flags"] == 0
    assert joseph["p_err_all"] < 1e-2 and joseph["x_err"] < 2e-2  # x: binary32's step of a growing position
    assert measure(cv_model(1, r=1e-8), "symmetric", steps, 2)["indefinite"] > 0
    at_1e6 = measure(cv_model(2, inputs=1), "joseph", steps, 2)
    assert at_1e6["indefinite"] == 0 and at_1e6["flags"] == 0 and at_1e6["p_err_all"] < 1e-2


def test_long_run_binary32():
    _long_run(150)  # (the symmetric form is indefinite by then: 10,000 steps in make test-full)


@pytest.mark.full
def test_long_run_binary32_full():
    _long_run(10_000)


@pytest.mark.full
def test_stability_command_prints_the_table(capsys):
    """docs/kf.md's ``python -m kfgen.sim.kf.stability``: Joseph's rows never indefinite."""
    from kfgen.sim.kf.stability import main

    main([])
    rows = [line.split(" | ") for line in capsys.readouterr().out.splitlines() if "| joseph |" in line]
    assert len(rows) == 3 and all(r[2] == "0" for r in rows)
