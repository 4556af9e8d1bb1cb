"""The IMM core: the linear-algebra engine running one IMM iteration a start, behind the same
AXI4 slave, registers and buffer rules as every engine core (:mod:`kfgen.hdl.engine.core`, whose
module docstring gives the bus rules; ``x`` and ``P``, the combined estimate, are read-only).
"""

from __future__ import annotations

from ..engine.core import EngineCore
from .regmap import imm_map
from .steps import programs, schedules

__all__ = ["Imm"]


class Imm(EngineCore):
    """The IMM core of ``params`` (an :class:`~kfgen.hdl.imm.params.ImmParams`): one step,
    ``iterate``."""

    def __init__(self, params):
        self._programs = programs(params)
        rmap = imm_map(params)
        lay = self._programs.layout
        for mem in rmap.memories:  # the buffer is the engine's memory from word 0
            reg = lay[mem.name]
            if (mem.offset - rmap.buffer_base) // mem.element_size != reg.base or mem.shape != (reg.rows, reg.cols):
                raise AssertionError(f"region {mem.name} is not where the engine keeps it")
        super().__init__(params, rmap, schedules(params, self._programs))
