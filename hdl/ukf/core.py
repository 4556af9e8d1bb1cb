"""The UKF IP core: the linear-algebra engine running the three UKF steps behind an AXI4
slave (:class:`kfgen.hdl.engine.core.EngineCore`, whose module docstring gives the bus rules),
with the UKF's register and memory map (:func:`kfgen.hdl.ukf.regmap.ukf_map`)."""

from __future__ import annotations

from ..engine.core import EngineCore
from .regmap import ukf_map
from .steps import programs, schedules

__all__ = ["Ukf"]


class Ukf(EngineCore):
    """The UKF IP core of ``params`` (a :class:`~kfgen.hdl.ukf.params.UkfParams`; see the
    module docstring and the generated ``TOP.md``): the three steps sig_gen, predict and
    update."""

    def __init__(self, params):
        self._programs = programs(params)
        super().__init__(params, ukf_map(params), schedules(params, self._programs))
