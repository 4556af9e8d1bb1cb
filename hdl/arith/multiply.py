"""A multiplier built from LUTs and carry chains: partial products summed by a pipelined tree.

On ECP5, Yosys maps ``*`` to a MULT18X18D without its internal registers, so every product
costs ~4 ns inside the DSP plus the routing to and from it, the slowest path of the Castella
core. For a narrow operand (a Kalman gain) the shift-and-add form is small and fast: one
adder level per pipeline stage. On Xilinx 7 series the DSP48E1 absorbs its input, product
and output registers, so :func:`dsp_multiply` gives the same product, with the same latency and
shape, as a ``*`` between registers that synthesis maps onto one DSP block.
"""

from __future__ import annotations

from amaranth.hdl import Const, Mux, Value

from .pipeline import Pipeline, Staged

__all__ = ["shift_add_multiply", "dsp_multiply", "sum_rows"]


def _levels(width: int) -> int:
    """Adder levels of :func:`shift_add_multiply`'s tree over ``width`` partial products."""
    return max(1, (width - 1).bit_length())


def _tree(terms: list, add) -> Value:
    """Pairwise sums, a level at a time (``add(u, v)``; a lone term goes on as it is)."""
    level = 0
    while len(terms) > 1 or level == 0:
        terms = [add(level, j, *terms[j:j + 2]) for j in range(0, len(terms), 2)]
        level += 1
    return terms[0]


def dsp_multiply(pl: Pipeline, name: str, a: Staged, b: Staged) -> Staged:
    """The product :func:`shift_add_multiply` gives (same value, shape and latency), as a ``*``
    that synthesis maps onto a DSP block with its registers: the operands registered (with
    three or more stages), the product registered, then output registers up to the latency.
    """
    width = len(a.sig)
    if a.sig.shape().signed:
        raise TypeError(f"{name}: the selecting operand must be unsigned")
    shape = _tree([Mux(a.sig[i], b.sig << i, 0) for i in range(width)],
                  lambda level, j, u, v=None: u if v is None else u + v).shape()
    levels = _levels(width)
    if levels >= 3:
        a = pl.reg(f"{name}_a", lambda x: x, a)
        b = b if isinstance(b.sig, Const) else pl.reg(f"{name}_b", lambda y: y, b)
    out = pl.reg(f"{name}_m", lambda x, y: x * y, a, b, shape=shape)
    for level in range(1 + (levels >= 3), levels):
        out = pl.reg(f"{name}_p{level}", lambda u: u, out)
    return out


def shift_add_multiply(pl: Pipeline, name: str, a: Staged, b: Staged) -> Staged:
    """``a * b`` for an unsigned ``a`` and any ``b`` (a signal or a constant), exactly.

    Partial products ``b << i`` selected by the bits of ``a`` are added pairwise, a level
    of the tree per stage: latency ``ceil(log2(len(a)))`` cycles (at least 1), one product
    per clock.
    """
    width = len(a.sig)
    if a.sig.shape().signed:
        raise TypeError(f"{name}: the selecting operand must be unsigned")
    terms = [pl.comb(f"{name}_pp{i}", lambda x, y, i=i: Mux(x[i], y << i, 0), a, b) for i in range(width)]
    return _tree(terms, lambda level, j, *pair: pl.reg(f"{name}_l{level}_{j // 2}",
                                                      (lambda u, v: u + v) if len(pair) == 2 else (lambda u: u),
                                                      *pair))


def sum_rows(rows) -> Value:
    """``sum(rows[i] << i)``: the second half of a shift-and-add product, combinational.

    ``rows`` are unsigned values, ``rows[i]`` being the multiplicand if bit ``i`` of the
    multiplier is set, else zero (selected by the caller, perhaps a register earlier). They
    are added pairwise in a balanced tree, ``ceil(log2(len(rows)))`` adders deep, in LUTs and
    carry chains: synthesis never maps this onto a DSP block as it does ``*``. The result is
    exact (wide enough for the sum).
    """
    # (value, weight of its bit 0): adjacent rows are paired, so a sum is only as wide as the
    # rows it spans.
    terms = [(Value.cast(row), i) for i, row in enumerate(rows)]
    while len(terms) > 1:
        paired = [(lo + (hi << (at_hi - at_lo)), at_lo)
                  for (lo, at_lo), (hi, at_hi) in zip(terms[0::2], terms[1::2])]
        terms = paired + terms[len(paired) * 2:]
    return terms[0][0]
