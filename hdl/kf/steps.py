"""The linear Kalman filter's program and schedule for one :class:`~kfgen.hdl.kf.params.KfParams`:
the one place that turns the core's parameters into the engine's machine and program, so the
core, its manifest and the golden model in the tests cannot disagree."""

from __future__ import annotations

from ..describe import once_per_params
from ..engine.machine import machine as engine_machine
from ..engine.machine import schedules as engine_schedules
from ..engine.params import check_work
from .programs import KfPrograms, KfSizes, build_kf

__all__ = ["programs", "machine", "schedules"]


@once_per_params
def programs(params) -> KfPrograms:
    """The memory layout and the iteration's program (and the steady gain's prologue), built
    once per parameter object."""
    return build_kf(KfSizes(params.n, params.m, params.nu, params.steady_gain), params.format)


def machine(params):
    """The engine's (:func:`kfgen.hdl.engine.machine.machine`: P PEs, ``params.banks`` banks, the
    divider and square root of ``params.div_sqrt``)."""
    return engine_machine(params)


def schedules(params, progs: KfPrograms | None = None) -> dict:
    """``{"iterate": Schedule}``."""
    progs = progs or programs(params)
    check_work(sum(prog.fma_count for prog in progs.steps.values()), params.pes, "states")
    return engine_schedules(progs.steps, machine(params))
