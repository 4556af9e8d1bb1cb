"""The engine's unit table (:mod:`kfgen.hdl.linalg.isa`): every unit complete in every layer
that reads it, and the check codes spelled once."""

import pytest

from kfgen.hdl.linalg import isa
from kfgen.hdl.linalg.isa import Check
from kfgen.hdl.linalg.program import UNITS, Copy, Div, Dot, Exp, Max, Sqrt
from kfgen.hdl.linalg.schedule import Machine
from kfgen.hdl.linalg.units import HARDWARE, WORDS
from kfgen.sim.linalg.exec import GOLDEN


def test_every_unit_is_complete():
    """A unit has a golden operation (all but the FMA, whose accumulation the executor runs),
    and exactly one way to be built, a pipeline or a word (the FMA is the PEs'); the IR's unit
    names are the table's."""
    assert UNITS == tuple(isa.UNITS) and UNITS[0] == "fma"
    assert set(GOLDEN) == set(UNITS) - {"fma"}
    assert set(HARDWARE) | set(WORDS) <= set(UNITS)
    for name, u in isa.UNITS.items():
        assert u.name == name
        assert (name in HARDWARE) + (name in WORDS) == (0 if name == "fma" else 1), name
        assert u.latency is None or u.latency in Machine.__dataclass_fields__
        assert u.interval is None or u.interval in Machine.__dataclass_fields__


@pytest.mark.parametrize("op", [Dot(0, None, [(1, 2, False)]), Div(0, 1, 2), Max(0, 1, 2), Sqrt(0, 1), Exp(0, 1),
                                Copy(0, 1)])
def test_operations_match_their_unit(op):
    """Each operation reads as many operands as its unit's instruction carries lanes."""
    u = isa.unit(op.unit)
    assert len(op.reads) == len(u.operands) or isinstance(op, Dot)


def test_machine_timing_from_the_table():
    mc = Machine(1, 9, 32, 29, div_interval=26, exp_latency=7, sin_latency=79, sin_interval=79,
                 cos_latency=78, cos_interval=78, atan2_latency=55, atan2_interval=55)
    assert [mc.latency(u) for u in UNITS] == [9, 1 + 32, 1 + 29, 1, 1 + 7, 1, 1 + 79, 1 + 78, 1 + 55, 1]
    assert [mc.interval(u) for u in UNITS] == [1, 26, 1, 1, 1, 1, 79, 78, 55, 1]
    with pytest.raises(ValueError, match="no engine unit 'tan'"):
        mc.latency("tan")


def test_check_codes():
    assert [Check.of(v) for v in (None, "pivot", "finite", Check.PIVOT)] == [0, 1, 2, 1]
    assert isa.CHECK_BITS == 2
    assert Div(0, 1, 2, check="pivot").check is Check.PIVOT and Sqrt(0, 1).check is Check.NONE
    for bad in ("none", "nan", 1, True):
        with pytest.raises(ValueError, match="check must be"):
            Copy(0, 1, check=bad)
