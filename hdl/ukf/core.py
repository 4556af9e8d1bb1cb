"""The UKF IP core: the linear-algebra engine running the three UKF steps behind an AXI4
slave (:class:`kfgen.hdl.engine.core.EngineCore`, whose module docstring gives the bus rules),
with the UKF's register and memory map (:func:`kfgen.hdl.ukf.regmap.ukf_map`)."""

from __future__ import annotations

from ..engine.core import EngineCore, Prologue, StreamSpec
from .regmap import ukf_map
from .steps import programs, schedules

__all__ = ["Ukf"]


class Ukf(EngineCore):
    """The UKF IP core of ``params`` (a :class:`~kfgen.hdl.ukf.params.UkfParams`; see the
    module docstring and the generated ``TOP.md``): the three steps sig_gen, predict and
    update."""

    def __init__(self, params):
        self._programs = programs(params)
        super().__init__(params, ukf_map(params), schedules(params, self._programs),
                         stream_spec(params, self._programs) if params.streams else None,
                         prologue(self._programs))


def prologue(progs) -> Prologue | None:
    """The ``noise`` step before an ``iteration`` after a write to Q or R (an on-chip core's)."""
    if progs.prologue is None:
        return None
    pre, main, regions = progs.prologue
    names = list(progs.steps)
    return Prologue(names.index(main), names.index(pre),
                    tuple((progs.layout[r].base, progs.layout[r].size) for r in regions))


def stream_spec(params, progs) -> StreamSpec:
    """The stream ports of an ``on_chip`` core with ``streams``: z then u in, x then the
    diagonal of P out (the square-root form's P_diag, the sums of S's rows' squares)."""
    lay, n = progs.layout, params.n
    x = lay["x"]
    if params.form == "sqrt":  # the variances, which the square-root form computes from S
        var = tuple(lay["P_diag"](i) for i in range(n))
    else:
        var = tuple(lay["P"](i, i) for i in range(n))
    ins = tuple(f"z[{i}]" for i in range(params.m)) + tuple(f"u[{i}]" for i in range(params.nu))
    return StreamSpec(lay["z"].base, ins, tuple(x(i) for i in range(n)) + var,
                      tuple(f"x[{i}]" for i in range(n)) + tuple(f"P[{i},{i}]" for i in range(n)),
                      StreamSpec.field_bits_of(params.fmt.width))
