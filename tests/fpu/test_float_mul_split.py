"""The split of the floating-point significand product into DSP-block and LUT-row pieces."""

import numpy as np
import pytest
from amaranth.hdl import Module, Signal

from helpers import run_comb


@pytest.mark.parametrize("wa,wb", [(2, 2), (3, 8), (8, 8), (11, 11), (17, 17), (18, 24), (24, 24),
                                   (24, 48), (35, 20), (53, 53), (65, 65)])
def test_float_partial_products_sum_to_the_product(wa, wb):
    """The DSP-block/LUT-row split of the floating-point multipliers (binary16 11x11, binary32
    24x24, binary64 53x53, fma's wider operands) adds up to ``a * b``: extremes and random."""
    from types import SimpleNamespace

    from kfgen.hdl.arith.float.mul import partial_products, sum_partial_products

    m = Module()
    a, b = Signal(wa), Signal(wb)
    y = Signal(wa + wb)
    m.d.comb += y.eq(sum_partial_products(SimpleNamespace(**partial_products(a, b)), wa + wb))
    rng = np.random.default_rng(wa * 100 + wb)
    top_a, top_b = (1 << wa) - 1, (1 << wb) - 1
    vectors = [(0, 0), (top_a, top_b), (top_a, 1), (1, top_b), (1 << (wa - 1), 1 << (wb - 1))]
    vectors += [(int(rng.integers(0, 1 << wa, dtype=np.uint64)) if wa < 64 else int.from_bytes(rng.bytes(9)) & top_a,
                 int(rng.integers(0, 1 << wb, dtype=np.uint64)) if wb < 64 else int.from_bytes(rng.bytes(9)) & top_b)
                for _ in range(200)]
    got = run_comb(m, (a, b), (y,), vectors)
    assert [g[0] for g in got] == [x * z for x, z in vectors]
