"""The engine's machine for one engine core's parameters: P processing elements, the memory
banks and the divider and square root a core's ``pes``, ``banks``, ``div_sqrt`` and ``fmt``
ask for, and the schedules of a core's programs on it."""

from __future__ import annotations

from ..arith.float.div import FloatDiv
from ..arith.float.exp import FloatExp
from ..arith.float.fma import FloatFMA
from ..arith.float.params import core_timing, unit_timing
from ..arith.float.sqrt import FloatSqrt
from ..arith.float.trig import FloatAtan2, FloatCos, FloatSin
from ..describe import once_per_params
from ..linalg.schedule import Machine, schedule

__all__ = ["machine", "schedules", "timing", "engine_mhz", "ENGINE_MHZ", "FETCHED_MHZ"]

#: The clock of the engine's own paths beside its units, measured (ECP5-85, nextpnr, UKF core
#: at P = 1, docs/ukf.md): a program-store DP16KD's word into the fetch register (9.4 ns) and
#: a bus read's address into the AXI front end (9.9 ns). ``--target-mhz`` pipelines the units
#: only, so a core's predicted Fmax is at most this.
ENGINE_MHZ = 101.0

#: The same with the program store's fetch register (a step a cycle longer), which a core's
#: ``target_mhz`` above :data:`ENGINE_MHZ` adds: the UKF core at P = 1 and ``--target-mhz 125``
#: measured 119.8 MHz (``python -m kfgen.gen.bench_timing``, median of seeds 1-3: 119.8, 114.0,
#: 122.7), its critical path a program-store DP16KD into its own register (5.8 ns of
#: clock-to-output and 2.5 ns of routing, 8.3 ns).
FETCHED_MHZ = 119.8


def engine_mhz(mc: Machine) -> float:
    """The clock of the engine's own paths on ``mc``: :data:`FETCHED_MHZ` with the fetch
    register, else :data:`ENGINE_MHZ`."""
    return FETCHED_MHZ if mc.fetch_register else ENGINE_MHZ


def _target_stages(params, op: str, per_op: int, default):
    """The stages of ``op``'s unit for the core's ``target_mhz`` (``default`` without one)."""
    if params.target_mhz is None:
        return default
    return unit_timing(op, params.fmt, "ieee", per_op, params.target_mhz)[0]


def timing(params, mc: Machine, used) -> dict:
    """The manifest's ``timing`` of an engine core with a ``target_mhz``: the target, each
    unit's stages and predicted Fmax by the calibrated model, and the core's prediction (the
    slowest unit, at most :func:`engine_mhz`). The exponential is listed when ``used`` (the
    units the programs use) holds it: it is built only then."""
    units = {"fma": ("fma", 1, mc.fma_latency), "div": ("div", mc.div_interval, mc.div_latency),
             "sqrt": ("sqrt", mc.sqrt_interval, mc.sqrt_latency)}
    if "exp" in used:
        units["exp"] = ("exp", 1, mc.exp_latency)
    return {**core_timing(params.target_mhz, params.fmt, units, engine_mhz(mc),
                          "ECP5-85, nextpnr (kfgen.hdl.arith.float.timing; the engine's own paths measured)"),
            "engine_mhz": engine_mhz(mc), "fetch_register": bool(mc.fetch_register)}


def _sqrt_stages(fmt, per_op):
    """The square root's stages: its default, except that a pipelined one gets its rounding's
    select registered too (the fewest stages from the default on with a ``round.select``
    register), whose last stage was the pipelined core's critical path on the ECP5."""
    unit = FloatSqrt.plan(fmt, cycles_per_op=per_op)
    if per_op != 1:
        return unit.stages
    return min((k for k, plan in unit.plans.items() if k >= unit.stages and "round.select" in plan),
               default=unit.stages)


@once_per_params
def machine(params) -> Machine:
    """P processing elements (the FMA's default pipeline), ``params.banks`` memory banks, and
    the divider and square root of ``params.div_sqrt``: iterative (one result bit a cycle: an
    operation every :meth:`~kfgen.hdl.arith.float.div.FloatDiv.iterations` cycles) or
    pipelined (the square root with its rounding's select registered); the exponential at its
    default pipeline and the iterative sin, cos and atan2 (a core builds them only when its
    programs use them). A core's ``target_mhz`` (when set) picks the FMA's, divider's,
    square root's and exponential's stages instead (:func:`timing`). Built once per
    parameter object."""
    fmt = params.fmt
    per_op = {cls: cls.iterations(fmt) if params.div_sqrt == "iterative" else 1 for cls in (FloatDiv, FloatSqrt)}
    div = FloatDiv.plan(fmt, cycles_per_op=per_op[FloatDiv],
                        stages=_target_stages(params, "div", per_op[FloatDiv], None))
    sqrt = FloatSqrt.plan(fmt, cycles_per_op=per_op[FloatSqrt],
                          stages=_target_stages(params, "sqrt", per_op[FloatSqrt], _sqrt_stages(fmt, per_op[FloatSqrt])))
    trig = {}
    for name, cls in (("sin", FloatSin), ("cos", FloatCos), ("atan2", FloatAtan2)):
        try:
            plan = cls.plan(fmt)
        except ValueError:  # a format it cannot take: a program that uses it fails to build
            continue
        trig |= {f"{name}_latency": plan.latency, f"{name}_interval": plan.initiation_interval}
    fma = FloatFMA.plan(fmt, stages=_target_stages(params, "fma", 1, None))
    exp = FloatExp.plan(fmt, stages=_target_stages(params, "exp", 1, None))
    target = params.target_mhz
    return Machine(params.pes, fma.latency, div.latency, sqrt.latency, banks=params.banks,
                   div_interval=div.initiation_interval, sqrt_interval=sqrt.initiation_interval,
                   exp_latency=exp.latency, fetch_register=int(target is not None and target > ENGINE_MHZ), **trig)


def schedules(steps: dict, mc: Machine) -> dict:
    """Step name -> :class:`~kfgen.hdl.linalg.schedule.Schedule` of each of ``steps`` (name ->
    :class:`~kfgen.hdl.linalg.program.Program`, in ``CTRL.step``'s order) on ``mc``."""
    return {name: schedule(prog, mc) for name, prog in steps.items()}
