"""``python -m kfgen.gen.bench_filters`` (docs/choosing.md): its table is printed from the
schedules and the golden models, the filters agree where they must (on the linear
application every float64 filter is the Kalman filter, and each binary32 core is its float64
filter to binary32's precision; on the range-bearing tracker each core is its own float64
filter), its options are checked, and docs/choosing.md's cycles are the bench's. Synthesis
and place and route are the docs' command, not the regression's."""

import contextlib
import io

import numpy as np
import pytest

from kfgen.gen.bench_filters import APPS, FILTERS, accuracy_block, cycles, filter_params, filters_of, main

from helpers import ROOT


def test_linear_application_every_filter_is_the_kalman_filter():
    out = accuracy_block("cv", 0, 2, 15)
    kf = np.array(out["kf_f64"])
    assert np.all(np.isfinite(kf)) and np.all(kf > 0)
    for filt in filters_of("cv"):
        assert out[f"{filt}_faults"] == 0
        # the EKF's Jacobians and the UKF's sigma points are exact on a linear model (the EKF's
        # float64 reference takes its Jacobians by finite differences: to about 1e-8)
        assert np.allclose(out[f"{filt}_f64"], kf, rtol=1e-6, atol=0), filt
        assert np.allclose(out[f"{filt}_b32"], kf, rtol=1e-4, atol=0), filt
    assert set(filters_of("cv")) == set(FILTERS) and "kf" not in filters_of("tracker")


def test_tracker_cores_are_their_float64_filters():
    out = accuracy_block("tracker", 3, 1, 15)
    for filt in filters_of("tracker"):
        assert out[f"{filt}_faults"] == 0
        assert np.allclose(out[f"{filt}_b32"], out[f"{filt}_f64"], rtol=1e-4, atol=0), filt
    # the EKF is not the UKF on a nonlinear h
    assert not np.allclose(out["ekf_f64"], out["ukf_ldl_f64"], rtol=1e-6, atol=0)


def _run(*argv):
    with contextlib.redirect_stdout(io.StringIO()) as out, contextlib.redirect_stderr(io.StringIO()) as err:
        try:
            rc = main(list(argv))
        except SystemExit as exc:
            rc = exc.code
    return rc, out.getvalue(), err.getvalue()


def test_table_is_printed():
    rc, out, _ = _run("--apps", "cv", "--seeds", "1", "--steps", "5", "--no-synth", "--serial")
    assert rc == 0
    rows = [line.split() for line in out.splitlines()]
    for filt in filters_of("cv"):
        label = FILTERS[filt][1].split()
        cyc, fma = cycles(filter_params("cv", filt))
        assert ["cv", *label, "1", str(cyc), str(fma), "-", "-", "-", "-", "-", "-"] in rows, filt
        assert any(r[:1 + len(label)] == ["cv", *label] and len(r) == 6 + len(label) for r in rows), filt
    assert "Accuracy: position RMS (m) over 1 seeds" in out


@pytest.mark.parametrize("args,says", [
    (["--apps", "cv,radar"], "--apps must be names from cv, tracker"),
    (["--pes", "0"], "--pes must be integers from 1 to 16"),
    (["--pes", "1,x"], "--pes must be integers from 1 to 16"),
    (["--seeds", "-1"], "--seeds must be an integer from 0"),
    (["--steps", "0"], "--steps must be an integer from 1"),
    (["--pnr-seeds", ""], "--pnr-seeds must be integers"),
    (["--freq", "fast"], "--freq must be a clock from 1 to 1000 MHz"),
    (["--no-synth", "--no-pnr"], "--no-synth and --no-pnr: give one"),
])
def test_bad_options_exit_2(args, says):
    rc, out, err = _run(*args, "--serial")
    assert rc == 2 and err.startswith(f"error: {says}") and err.count("\n") == 1 and not out, err


def test_the_docs_cycles_are_the_bench():
    text = (ROOT / "docs" / "choosing.md").read_text()
    for app in APPS:
        for filt in filters_of(app):
            cyc, _ = cycles(filter_params(app, filt))
            assert f"| {app} | {FILTERS[filt][1]} | {cyc:,} |" in text, (app, filt)
