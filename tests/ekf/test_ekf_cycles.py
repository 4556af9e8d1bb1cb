"""Cycles: the EKF's iteration (one schedule, its exact length) against the UKF's on-chip
iteration for the same shipped application, at P = 1 and 2 (issue 35's goal: EKF <= 0.5 x
UKF). The numbers are printed with ``pytest -s``."""

import pytest

from kfgen.hdl.ekf.params import EkfParams
from kfgen.hdl.ekf.steps import programs as ekf_programs
from kfgen.hdl.ekf.steps import schedules as ekf_schedules
from kfgen.hdl.ukf.params import UkfParams
from kfgen.hdl.ukf.steps import programs as ukf_programs
from kfgen.hdl.ukf.steps import schedules as ukf_schedules

#: The goal: the EKF's iteration at most this fraction of the UKF's.
GOAL = 0.5


@pytest.mark.parametrize("which, spec", [("tracker", "tracker:Tracker"), ("nanosat", "nanosat:Nanosat")])
@pytest.mark.parametrize("pes", [1, 2])
def test_ekf_iteration_at_most_half_the_ukf(which, spec, pes, request, capsys):
    app, models = request.getfixturevalue(which)
    ekf = EkfParams(spec, app.n, app.m, app.nw, app.nv, app.nu, pes=pes)
    eprogs = ekf_programs(ekf, models)
    e = ekf_schedules(ekf, eprogs)["iterate"].cycles
    ukf = UkfParams(**app.core_parameters(), app=spec, on_chip=True, pes=pes)
    uprogs = ukf_programs(ukf)
    u = ukf_schedules(ukf, uprogs)["iteration"].cycles
    with capsys.disabled():
        print(f"\n{which} P={pes}: EKF {e} cycles ({eprogs.iteration.fma_count} multiply-adds), "
              f"UKF on chip {u} ({uprogs.iteration.fma_count}): {e / u:.2f}")
    assert e <= GOAL * u
