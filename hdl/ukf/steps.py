# amaranth: UnusedElaboratable=no
# (The float units made here are only asked their latency, never elaborated: Amaranth's
# public linter option for that; it covers only what this file creates.)
"""The UKF's step programs and their schedules for one :class:`~kfgen.hdl.ukf.params.UkfParams`:
the one place that turns the core's parameters into the engine's machine and programs, so
the core, its manifest and the golden model in the tests cannot disagree."""

from __future__ import annotations

from ..arith.float.div import FloatDiv
from ..arith.float.fma import FloatFMA
from ..arith.float.sqrt import FloatSqrt
from ..linalg.schedule import Machine, schedule
from ..linalg.ukf_steps import UkfPrograms, UkfSizes, build_ukf

__all__ = ["programs", "machine", "schedules"]


def programs(params) -> UkfPrograms:
    """The memory layout and the three step programs (sig_gen, predict, update)."""
    return build_ukf(UkfSizes(params.n, params.nw, params.nv, params.m), params.w0, params.format)


def machine(params) -> Machine:
    """P processing elements with the default pipelines of the FMA, divider and square root."""
    return Machine(params.pes, *(cls(params.fmt).latency for cls in (FloatFMA, FloatDiv, FloatSqrt)))


def schedules(params, progs: UkfPrograms | None = None) -> dict:
    """Step name -> :class:`~kfgen.hdl.linalg.schedule.Schedule`, in CTRL.step's order."""
    progs = progs or programs(params)
    mc = machine(params)
    return {name: schedule(prog, mc) for name, prog in progs.steps.items()}
