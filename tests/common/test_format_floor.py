"""The UKF's narrowest format (``FORMAT_FLOOR``, ``kfgen ukf --help``), measured: the golden
model runs an application's scenario in a format, and its error is held against the float64
reference's. ``python -m pytest tests/common/test_format_floor.py -s`` prints the table."""

import numpy as np
import pytest

import kfgen.hdl.ukf.params as ukf_params
from kfgen.hdl.describe import ParamError
from kfgen.hdl.ukf.params import FORMAT_FLOOR, UkfParams
from kfgen.sim.ukf.accuracy import run_golden, run_reference
from kfgen.sim.ukf.app import checked_scenario, load_app
from kfgen.sim.ukf.software import StepError

from helpers import ROOT

#: The mildest application: a pendulum, Q = 1e-4 I, R = 1e-2.
PENDULUM = f"{ROOT / 'docs' / 'examples' / 'pendulum.py'}:Pendulum"
STEPS = 200


def error_ratio(spec: str, fmt: str, steps: int = STEPS) -> float:
    """RMS error of the golden model in ``fmt`` over the float64 reference's, against the
    scenario's truth (seed 1); infinity when a step faults (err_pivot, err_nan)."""
    app = load_app(spec)
    sc = checked_scenario(app, steps, 1)

    def rms(x):
        return float(np.sqrt(np.mean((x - sc.truth) ** 2)))
    try:
        golden = run_golden(app, sc, format=fmt)
    except StepError:
        return float("inf")
    return rms(golden) / rms(run_reference(app, sc))


@pytest.mark.parametrize("fmt, tracks", [
    ("binary16", True), ("bfloat16", True),
    (f"e{FORMAT_FLOOR[0]}m{FORMAT_FLOOR[1]}", True),       # the floor: within 1.25x of float64
    (f"e{FORMAT_FLOOR[0] - 1}m10", False),                 # Q = 1e-4 below the normal range
    (f"e{FORMAT_FLOOR[0]}m{FORMAT_FLOOR[1] - 1}", False),  # pivots round to zero
    (f"e8m{FORMAT_FLOOR[1] - 1}", False),
])
def test_the_floor_is_where_the_filter_stops_tracking(fmt, tracks, monkeypatch):
    monkeypatch.setattr(ukf_params, "FORMAT_FLOOR", (3, 2))  # the model below the floor, past its check
    ratio = error_ratio(PENDULUM, fmt)
    print(f"{fmt}: golden / float64 RMS error {ratio:.3f}")
    assert (ratio < 1.25) == tracks, ratio


def test_below_the_floor_is_refused():
    with pytest.raises(ParamError, match="e3m2 is too narrow") as exc:
        UkfParams(format="e3m2")
    assert exc.value.param == "format"
    UkfParams(format=f"e{FORMAT_FLOOR[0]}m{FORMAT_FLOOR[1]}")
