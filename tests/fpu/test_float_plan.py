"""FloatUnit.plan: a unit's timing without constructing the unit, and a refused unit that
never exists (so Amaranth has no unused unit to warn about)."""

import gc
import warnings

import pytest
from amaranth.hdl import Fragment

from kfgen.hdl.arith.float.div import FloatDiv
from kfgen.hdl.arith.float.exp import FloatExp
from kfgen.hdl.arith.float.fma import FloatFMA
from kfgen.hdl.arith.float.sqrt import FloatSqrt


@pytest.mark.parametrize("cls,kw", [(FloatDiv, {"cycles_per_op": 26}), (FloatSqrt, {}), (FloatFMA, {}),
                                    (FloatExp, {"stages": 5})])
def test_plan_is_the_units_timing(cls, kw):
    plan = cls.plan("binary32", **kw)
    unit = cls("binary32", **kw)
    Fragment.get(unit, None)  # used
    assert plan == (unit.stages, unit.latency, unit.initiation_interval, unit.PLANS)


def test_plans_and_refusals_leave_no_unused_unit():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        FloatSqrt.plan("binary64", cycles_per_op=2)
        with pytest.raises(ValueError, match="stages must be"):
            FloatDiv("binary32", stages=-1)
        with pytest.raises(ValueError, match="cycles_per_op"):
            FloatSqrt("binary32", cycles_per_op=0)
        gc.collect()
