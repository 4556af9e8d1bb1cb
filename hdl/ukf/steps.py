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


def _sqrt_stages(fmt, per_op):
    """The square root's stages: its default, except that a pipelined one gets its rounding's
    select registered too (the fewest stages from the default on with a ``round.select``
    register), whose last stage was the pipelined core's critical path on the ECP5."""
    unit = FloatSqrt(fmt, cycles_per_op=per_op)
    unit._MustUse__silence = True  # only its plans are read
    if per_op != 1:
        return unit.stages
    return min((k for k, plan in unit.PLANS.items() if k >= unit.stages and "round.select" in plan),
               default=unit.stages)


def machine(params) -> Machine:
    """P processing elements (the FMA's default pipeline), ``params.banks`` memory banks, and
    the divider and square root of ``params.div_sqrt``: iterative (one result bit a cycle: an
    operation every :meth:`~kfgen.hdl.arith.float.div.FloatDiv.iterations` cycles) or
    pipelined (the square root with its rounding's select registered)."""
    fmt = params.fmt
    per_op = {cls: cls.iterations(fmt) if params.div_sqrt == "iterative" else 1 for cls in (FloatDiv, FloatSqrt)}
    div = FloatDiv(fmt, cycles_per_op=per_op[FloatDiv])
    sqrt = FloatSqrt(fmt, cycles_per_op=per_op[FloatSqrt], stages=_sqrt_stages(fmt, per_op[FloatSqrt]))
    return Machine(params.pes, FloatFMA(fmt).latency, div.latency, sqrt.latency, banks=params.banks,
                   div_interval=div.initiation_interval, sqrt_interval=sqrt.initiation_interval)


def schedules(params, progs: UkfPrograms | None = None) -> dict:
    """Step name -> :class:`~kfgen.hdl.linalg.schedule.Schedule`, in CTRL.step's order."""
    progs = progs or programs(params)
    mc = machine(params)
    return {name: schedule(prog, mc) for name, prog in progs.steps.items()}
