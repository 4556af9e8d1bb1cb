"""The engine's machine for one engine core's parameters: P processing elements, the memory
banks and the divider and square root a core's ``pes``, ``banks``, ``div_sqrt`` and ``fmt``
ask for, and the schedules of a core's programs on it."""

from __future__ import annotations

from ..arith.float.div import FloatDiv
from ..arith.float.exp import FloatExp
from ..arith.float.fma import FloatFMA
from ..arith.float.sqrt import FloatSqrt
from ..arith.float.trig import FloatAtan2, FloatCos, FloatSin
from ..linalg.schedule import Machine, schedule

__all__ = ["machine", "schedules"]


def _sqrt_stages(fmt, per_op):
    """The square root's stages: its default, except that a pipelined one gets its rounding's
    select registered too (the fewest stages from the default on with a ``round.select``
    register), whose last stage was the pipelined core's critical path on the ECP5."""
    unit = FloatSqrt.plan(fmt, cycles_per_op=per_op)
    if per_op != 1:
        return unit.stages
    return min((k for k, plan in unit.plans.items() if k >= unit.stages and "round.select" in plan),
               default=unit.stages)


def machine(params) -> Machine:
    """P processing elements (the FMA's default pipeline), ``params.banks`` memory banks, and
    the divider and square root of ``params.div_sqrt``: iterative (one result bit a cycle: an
    operation every :meth:`~kfgen.hdl.arith.float.div.FloatDiv.iterations` cycles) or
    pipelined (the square root with its rounding's select registered); the exponential at its
    default pipeline and the iterative sin, cos and atan2 (a core builds them only when its
    programs use them)."""
    fmt = params.fmt
    per_op = {cls: cls.iterations(fmt) if params.div_sqrt == "iterative" else 1 for cls in (FloatDiv, FloatSqrt)}
    div = FloatDiv.plan(fmt, cycles_per_op=per_op[FloatDiv])
    sqrt = FloatSqrt.plan(fmt, cycles_per_op=per_op[FloatSqrt], stages=_sqrt_stages(fmt, per_op[FloatSqrt]))
    trig = {}
    for name, cls in (("sin", FloatSin), ("cos", FloatCos), ("atan2", FloatAtan2)):
        try:
            plan = cls.plan(fmt)
        except ValueError:  # a format it cannot take: a program that uses it fails to build
            continue
        trig |= {f"{name}_latency": plan.latency, f"{name}_interval": plan.initiation_interval}
    return Machine(params.pes, FloatFMA.plan(fmt).latency, div.latency, sqrt.latency, banks=params.banks,
                   div_interval=div.initiation_interval, sqrt_interval=sqrt.initiation_interval,
                   exp_latency=FloatExp.plan(fmt).latency, **trig)


def schedules(steps: dict, mc: Machine) -> dict:
    """Step name -> :class:`~kfgen.hdl.linalg.schedule.Schedule` of each of ``steps`` (name ->
    :class:`~kfgen.hdl.linalg.program.Program`, in ``CTRL.step``'s order) on ``mc``."""
    return {name: schedule(prog, mc) for name, prog in steps.items()}
