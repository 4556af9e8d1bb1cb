"""The linear Kalman filter core's parameters, layout, program sizes and cycles: each schedule
against max(multiply-adds / P, dependency chain), the figures at n = 16 against Vitis'."""

import pytest

from kfgen.hdl.describe import ParamError
from kfgen.hdl.kf.params import KfParams
from kfgen.hdl.kf.steps import programs, schedules
from kfgen.hdl.linalg.schedule import chain_bound

#: Measured ratios above 1.3 (cycles / max(FMAs / P, chain)), kept so that they cannot grow:
#: at n = 4 and P = 1 the two bounds are nearly equal (374 multiply-adds, a chain of 393), and
#: the one PE cannot overlap the work after K (Joseph's three products, 180 multiply-adds)
#: with the chain up to K.
KNOWN_MISSES = {(4, False, 1): 1.44}


@pytest.mark.parametrize("bad,param", [
    ({"states": 0}, "states"), ({"states": 256}, "states"), ({"measurements": 0}, "measurements"),
    ({"inputs": -1}, "inputs"), ({"inputs": True}, "inputs"), ({"pes": 0}, "pes"), ({"format": "binary128"}, "format"),
    ({"div_sqrt": "fast"}, "div_sqrt"), ({"steady_gain": 1}, "steady_gain"), ({"streams": "yes"}, "streams"),
    ({"address_width": 40}, "address_width"), ({"target_mhz": -5}, "target_mhz"), ({"irq": 0}, "irq"),
    ({"states": 40}, "states"),
])
def test_bad_parameters(bad, param):
    with pytest.raises(ParamError) as e:
        KfParams(**bad)
    assert e.value.param == param


def test_layout():
    """The buffer holds what software writes: P, Q, R for the full filter, K for the steady
    gain's, B and u with inputs only."""
    def bus(**kw):
        return [r.name for r in programs(KfParams(**kw)).layout.regions.values() if r.kind == "bus"]
    assert bus(inputs=1) == ["x", "P", "F", "B", "Q", "H", "R", "z", "u"]
    assert bus() == ["x", "P", "F", "Q", "H", "R", "z"]
    assert bus(inputs=2, steady_gain=True) == ["x", "F", "B", "H", "z", "u", "K"]


@pytest.mark.parametrize("n,m,nu", [(4, 2, 1), (16, 2, 1), (3, 1, 0)])
def test_steady_gain_multiply_adds(n, m, nu):
    """x = K z + G u + A x: n (n + nu + m) multiply-adds and n copies an iteration; the
    prologue's A = F - K (H F), G = B - K (H B): 2 m n (n + nu), once a write of F, B, H or K."""
    progs = programs(KfParams(states=n, measurements=m, inputs=nu, steady_gain=True))
    assert progs.iterate.fma_count == n * (n + nu + m)
    assert progs.iterate.units == {"fma", "copy"} and progs.iterate.count("copy") == n
    assert progs.gain.fma_count == 2 * m * n * (n + nu)
    assert progs.prologue == ("gain", "iterate", ("F", "B", "H", "K") if nu else ("F", "H", "K"))
    assert programs(KfParams(states=n, measurements=m, inputs=nu)).prologue is None


@pytest.mark.parametrize("n", [4, 16])
@pytest.mark.parametrize("steady", [False, True], ids=["full", "steady"])
def test_cycles_against_bounds(n, steady, capsys):
    """m = 2, nu = 1, binary32, the default divider: at P = 1, 2, 4 the iteration within 1.3x
    of max(FMAs / P, chain bound) (but :data:`KNOWN_MISSES`); at n = 16, P = 4 the
    microseconds at 100 MHz against Vitis' 0.55 ms."""
    rows = []
    for pes in (1, 2, 4):
        params = KfParams(states=n, measurements=2, inputs=1, pes=pes, steady_gain=steady)
        scheds = schedules(params)
        sched = scheds["iterate"]
        fma, chain = sched.program.fma_count, chain_bound(sched.program, sched.machine)
        ratio = sched.cycles / max(fma / pes, chain)
        assert ratio <= KNOWN_MISSES.get((n, steady, pes), 1.3), (pes, sched.cycles, fma, chain)
        rows.append(f"n={n} m=2 nu=1 {'steady' if steady else 'full'} P={pes}: {sched.cycles} cycles "
                    f"({sched.cycles / 100:.2f} us at 100 MHz), FMAs {fma}, chain {chain}, x{ratio:.2f}"
                    + (f"; prologue gain {scheds['gain'].cycles}" if steady else ""))
        if n == 16 and pes == 4:
            assert sched.cycles / 100 * 10 <= 550  # at least 10x Vitis' 0.55 ms
    with capsys.disabled():
        print("\n" + "\n".join(rows))
