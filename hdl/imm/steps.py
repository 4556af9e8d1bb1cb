# amaranth: UnusedElaboratable=no
# (The float units made here are only asked their latency, never elaborated.)
"""The IMM's program and schedule for one :class:`~kfgen.hdl.imm.params.ImmParams`: the one
place that turns the core's parameters into the engine's machine and program, so the core,
its manifest and the golden model in the tests cannot disagree."""

from __future__ import annotations

import dataclasses

from ..arith.float.exp import FloatExp
from ..linalg.imm_steps import ImmPrograms, ImmSizes, build_imm
from ..linalg.schedule import schedule
from ..ukf.steps import machine as ukf_machine

__all__ = ["programs", "machine", "schedules"]


def programs(params) -> ImmPrograms:
    """The memory layout and the iteration's program."""
    return build_imm(ImmSizes(params.R, params.n, params.d), params.format)


def machine(params):
    """As the UKF's (:func:`kfgen.hdl.ukf.steps.machine`: P PEs, ``params.banks`` banks, the
    divider and square root of ``params.div_sqrt``), with the exponential's pipeline."""
    return dataclasses.replace(ukf_machine(params), exp_latency=FloatExp(params.fmt).latency)


def schedules(params, progs: ImmPrograms | None = None) -> dict:
    """``{"iterate": Schedule}``."""
    progs = progs or programs(params)
    mc = machine(params)
    return {name: schedule(prog, mc) for name, prog in progs.steps.items()}
