# amaranth: UnusedElaboratable=no
# (FloatExp is made here only to read its latency.)
"""The engine's units added for the IMM: the exponential and the comparator, in Amaranth's
simulator against the golden executor word for word (special values included), and the
golden maximum against Python's float order."""

import dataclasses
import math
from types import SimpleNamespace

from kfgen.hdl.arith.float.exp import FloatExp
from kfgen.hdl.arith.float.format import FloatFormat
from kfgen.hdl.linalg.engine import Engine
from kfgen.hdl.linalg.program import Dot, Exp, Layout, Max, Program
from kfgen.hdl.linalg.schedule import schedule
from kfgen.sim.linalg.exec import max_value, to_words

from test_linalg_engine import TB, machine, simulate

FMT = FloatFormat.parse("binary32")
SPECIAL = [0.0, -0.0, 1.0, -1.0, 2.5, -2.5, math.inf, -math.inf, math.nan, 1e-40, -1e-40, 88.0, -104.0]


def test_max_value_is_the_float_order():
    words = to_words(FMT, SPECIAL)
    for a, wa in zip(SPECIAL, words):
        for b, wb in zip(SPECIAL, words):
            got, nan = max_value(FMT, wa, wb)
            if math.isnan(a) or math.isnan(b):
                assert (got, nan) == (FMT.canonical_nan, True)
                continue
            assert not nan
            want = b if b > a or (b == a == 0 and math.copysign(1, b) > math.copysign(1, a)) else a
            assert got == to_words(FMT, [want])[0], (a, b)


def test_exp_and_max_in_the_engine():
    """Max over every pair of special values and Exp of each, on P = 1, scheduled with the
    exponential's real latency; NaN in a checked result sets err_nan."""
    lay = Layout()
    v = lay.add("v", 1, len(SPECIAL), "bus")
    n = len(SPECIAL)
    mx = lay.add("mx", n, n)
    ex = lay.add("ex", 1, n)
    chk = lay.add("chk", 1, 1)
    one = lay.const("one", to_words(FMT, [1.0]))(0, 0)
    prog = Program("units", lay, FMT)
    for i in range(n):
        prog.emit(Exp(ex(0, i), v(0, i)))
        for j in range(n):
            prog.emit(Max(mx(i, j), v(0, i), v(0, j)))
    prog.emit(Dot(chk(0, 0), None, [(one, mx(8, 0), False)], "finite"))  # max(NaN, 0) = NaN
    mc = dataclasses.replace(machine(1, FMT), exp_latency=FloatExp(FMT).latency)
    dut = Engine({"units": schedule(prog, mc)})

    async def tb(ctx):
        t = TB(ctx, dut, SimpleNamespace(layout=lay, fmt=FMT, steps={"units": prog}))
        await t.put("v", SPECIAL)
        st = await t.step("units")
        assert st.nan and not st.pivot
        assert st.flags & 0b10000  # NV from the comparator's NaN operands

    simulate(dut, tb)


def test_copysign_in_the_engine():
    """CopySign (the square-root form's Householder sign) over every pair of special values,
    NaNs and signed zeros included, on P = 1: the magnitude of a with the sign bit of b,
    no flags, word for word against the golden executor."""
    from kfgen.hdl.linalg.program import CopySign
    lay = Layout()
    v = lay.add("v", 1, len(SPECIAL), "bus")
    n = len(SPECIAL)
    cs = lay.add("cs", n, n)
    prog = Program("signs", lay, FMT)
    for i in range(n):
        for j in range(n):
            prog.emit(CopySign(cs(i, j), v(0, i), v(0, j)))
    dut = Engine({"signs": schedule(prog, machine(1, FMT))})

    async def tb(ctx):
        t = TB(ctx, dut, SimpleNamespace(layout=lay, fmt=FMT, steps={"signs": prog}))
        await t.put("v", SPECIAL)
        st = await t.step("signs")  # the hardware's memory equals the golden executor's
        assert not (st.nan or st.pivot or st.flags)
        words = to_words(FMT, SPECIAL)  # (the values' words: a -0 read as a float loses its sign)
        sign = 1 << 31
        for i, a in enumerate(words):
            for j, b in enumerate(words):
                assert t.gold[cs(i, j)] == (a & ~sign) | (b & sign), (SPECIAL[i], SPECIAL[j])

    simulate(dut, tb)
