"""The EKF IP core: the linear-algebra engine running one EKF iteration a start behind the AXI4
slave every engine core has (:class:`kfgen.hdl.engine.core.EngineCore`, whose module docstring
gives the bus rules), with the EKF's register and memory map
(:func:`kfgen.hdl.ekf.regmap.ekf_map`) and, with ``streams``, the UKF's stream ports."""

from __future__ import annotations

from ..engine.core import EngineCore, StreamSpec
from .regmap import ekf_map
from .steps import programs, schedules

__all__ = ["Ekf", "stream_spec"]


class Ekf(EngineCore):
    """The EKF core of ``params`` (an :class:`~kfgen.hdl.ekf.params.EkfParams`): one step,
    ``iterate``."""

    def __init__(self, params):
        self._programs = programs(params)
        rmap = ekf_map(params)
        lay = self._programs.layout
        for mem in rmap.memories:  # the buffer is the engine's memory from word 0
            reg = lay[mem.name]
            if (mem.offset - rmap.buffer_base) // mem.element_size != reg.base or mem.shape != (reg.rows, reg.cols):
                raise AssertionError(f"region {mem.name} is not where the engine keeps it")
        super().__init__(params, rmap, schedules(params, self._programs),
                         stream_spec(params, self._programs) if params.streams else None)


def stream_spec(params, progs) -> StreamSpec:
    """The stream ports of a core with ``streams`` (the UKF's on-chip core's): z then u in, x
    then the diagonal of P out."""
    lay, n = progs.layout, params.n
    x, P = lay["x"], lay["P"]
    ins = tuple(f"z[{i}]" for i in range(params.m)) + tuple(f"u[{i}]" for i in range(params.nu))
    return StreamSpec(lay["z"].base, ins, tuple(x(i) for i in range(n)) + tuple(P(i, i) for i in range(n)),
                      tuple(f"x[{i}]" for i in range(n)) + tuple(f"P[{i},{i}]" for i in range(n)),
                      StreamSpec.field_bits_of(params.fmt.width))
