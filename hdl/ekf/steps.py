"""The EKF's program and schedule for one :class:`~kfgen.hdl.ekf.params.EkfParams` and its
application's compiled models: the one place that turns them into the engine's machine and
program, so the core, its manifest and the golden model cannot disagree."""

from __future__ import annotations

from ..describe import once_per_params
from ..engine.machine import machine as engine_machine
from ..engine.machine import schedules as engine_schedules
from ..engine.params import check_work
from .models import EkfModels
from .programs import EkfPrograms, build_ekf

__all__ = ["programs", "machine", "schedules"]


@once_per_params
def _own(params) -> EkfPrograms:
    return build_ekf(params, params.models)


def programs(params, models: EkfModels | None = None) -> EkfPrograms:
    """The memory layout and the iteration's program of ``models``; by default the parameters'
    own application's (:attr:`~kfgen.hdl.ekf.params.EkfParams.models`), built once per
    parameter object."""
    return _own(params) if models is None else build_ekf(params, models)


def machine(params):
    """The engine's (:func:`kfgen.hdl.engine.machine.machine`: P PEs, ``params.banks`` banks, the
    divider and square root of ``params.div_sqrt``, the units the programs use)."""
    return engine_machine(params)


def schedules(params, progs: EkfPrograms | None = None) -> dict:
    """``{"iterate": Schedule}``."""
    progs = progs or programs(params)
    check_work(sum(prog.fma_count for prog in progs.steps.values()), params.pes, "states")
    return engine_schedules(progs.steps, machine(params))
