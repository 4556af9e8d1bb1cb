"""The UKF's step programs and their schedules for one :class:`~kfgen.hdl.ukf.params.UkfParams`:
the one place that turns the core's parameters into the engine's machine and programs, so
the core, its manifest and the golden model in the tests cannot disagree."""

from __future__ import annotations

from ..describe import once_per_params
from ..engine.machine import machine
from ..engine.machine import schedules as engine_schedules
from ..engine.params import check_work
from .programs import UkfPrograms, build_ukf

__all__ = ["programs", "machine", "schedules"]


@once_per_params
def programs(params) -> UkfPrograms:
    """The memory layout and the step programs (sig_gen, predict, update; or the on-chip
    core's), built once per parameter object."""
    return build_ukf(params)


def schedules(params, progs: UkfPrograms | None = None) -> dict:
    """Step name -> :class:`~kfgen.hdl.linalg.schedule.Schedule`, in CTRL.step's order."""
    progs = progs or programs(params)
    check_work(sum(prog.fma_count for prog in progs.steps.values()), params.pes, "states")
    return engine_schedules(progs.steps, machine(params))
