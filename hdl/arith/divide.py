"""A pipelined restoring divider for Kalman gains: exact, rounded, saturated."""

from __future__ import annotations

from amaranth.hdl import Cat, Mux, unsigned

from .pipeline import Pipeline, Staged

__all__ = ["gain_divider"]


def gain_divider(pl: Pipeline, name: str, num: Staged, den: Staged, extra: int, width: int) -> Staged:
    """Rounded ``num * 2**(extra + width) / den``, saturated to ``width`` unsigned bits.

    ``extra`` aligns the operands' binary points (``num`` is shifted left for ``extra > 0``,
    ``den`` for ``extra < 0``). One quotient bit per stage, ``width + 1`` stages, then a
    round-half-up stage: latency ``width + 4`` cycles after the later operand, one result
    per clock. Mirrors :func:`kfgen.sim.castella.model.gain_divide`.
    """
    n = pl.reg(f"{name}_n", lambda x: x << max(extra, 0), num)
    d = pl.reg(f"{name}_d", lambda x: x << max(-extra, 0), den)
    over = pl.reg(f"{name}_over", lambda a, b: a >= b, n, d)
    rem = n  # below d unless ``over``; then the quotient is replaced by saturation
    bits = []
    for i in range(width + 1):
        two = pl.comb(f"{name}_two{i}", lambda x: x << 1, rem)
        if i == width:  # the last remainder is not needed, only its quotient bit
            bits.append(pl.reg(f"{name}_q{i}", lambda a, b: a >= b, two, d))
            break
        diff = pl.comb(f"{name}_diff{i}", lambda a, b: a - b, two, d)
        bits.append(pl.reg(f"{name}_q{i}", lambda x: ~x[-1], diff))
        rem = pl.reg(f"{name}_r{i}", lambda x, df: Mux(df[-1], x, df), two, diff, shape=d.sig.shape())
    quo = pl.comb(f"{name}_quo", lambda *b: Cat(*reversed(b)), *bits)
    top = (1 << width) - 1
    return pl.reg(name, lambda q, o: Mux(o, top, Mux(((q + 1) >> 1) > top, top, (q + 1) >> 1)),
                  quo, over, shape=unsigned(width))
