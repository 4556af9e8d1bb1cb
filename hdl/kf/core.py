"""The linear Kalman filter core: the linear-algebra engine running one predict and update a
start, behind the same AXI4 slave, registers and buffer rules as every engine core
(:mod:`kfgen.hdl.engine.core`, whose module docstring gives the bus rules), with the map of
:func:`kfgen.hdl.kf.regmap.kf_map`. A steady-gain core runs its ``gain`` step as the prologue
of an iteration that follows a write to F, B, H or K; ``streams`` adds the UKF's stream ports
(z, then u, in; x, then P's diagonal, out; a steady-gain core has no P: x only).
"""

from __future__ import annotations

from ..engine.core import EngineCore, Prologue, StreamSpec
from .regmap import kf_map
from .steps import programs, schedules

__all__ = ["Kf", "stream_spec"]


class Kf(EngineCore):
    """The KF core of ``params`` (a :class:`~kfgen.hdl.kf.params.KfParams`): the step
    ``iterate`` (and ``gain`` with a steady gain)."""

    def __init__(self, params):
        self._programs = progs = programs(params)
        rmap = kf_map(params)
        lay = progs.layout
        for mem in rmap.memories:  # the buffer is the engine's memory from word 0
            reg = lay[mem.name]
            if (mem.offset - rmap.buffer_base) // mem.element_size != reg.base or mem.shape != (reg.rows, reg.cols):
                raise AssertionError(f"region {mem.name} is not where the engine keeps it")
        super().__init__(params, rmap, schedules(params, progs),
                         stream_spec(params, progs) if params.streams else None, Prologue.of(progs))


def stream_spec(params, progs) -> StreamSpec:
    """The stream ports of a core with ``streams``: z then u in (adjacent in the buffer), x
    then the diagonal of P out (x only with a steady gain)."""
    lay, n = progs.layout, params.n
    x = lay["x"]
    ins = tuple(f"z[{i}]" for i in range(params.m)) + tuple(f"u[{i}]" for i in range(params.nu))
    outs = tuple(x(i) for i in range(n))
    names = tuple(f"x[{i}]" for i in range(n))
    if not params.steady_gain:
        outs += tuple(lay["P"](i, i) for i in range(n))
        names += tuple(f"P[{i},{i}]" for i in range(n))
    return StreamSpec(lay["z"].base, ins, outs, names, StreamSpec.field_bits_of(params.fmt.width))
