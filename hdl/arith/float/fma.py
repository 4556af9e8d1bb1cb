"""Fused multiply-add ``a * b + c`` with a single rounding, one operation per clock."""

from __future__ import annotations

from amaranth.hdl import C, Cat, Mux
from amaranth.lib.wiring import In, Out

from .format import FloatFormat
from .round import ROUND_BOUNDARIES, FloatUnit, prepare_exponent, round_pack, unpack

__all__ = ["FloatFMA"]

_R = ROUND_BOUNDARIES  # round.shift, round.round, round.select


class FloatFMA(FloatUnit):
    """``a * b + c`` computed exactly and rounded once, to nearest even.

    The exact ``2p``-bit product (``p`` = precision) sits at a fixed place in a frame of
    ``F = L + 3p + 4`` bits; the addend is shifted right from the top of the frame to its place
    relative to the product, its lost bits folded into the frame's lowest bit (a sticky bit
    that makes a borrow come out right). From the bottom: the sticky bit, ``L - 1`` zeros, the
    product, three zeros, ``p`` bits for an addend above the product, and the carry. An addend
    more than three places above the product stays at the top: the product is then wholly
    below the round bit, where only its being nonzero matters. The magnitude of the sum or
    difference goes to :func:`~.round.round_pack`, which counts the leading zeros a
    cancellation leaves and rounds.

    ``L`` keeps the addend's lost bits below the round bit when the product has leading
    zeros: ``p + 4`` with subnormal operands (a subnormal multiplicand's product may be as
    small as 1), ``max(1, 6 - p)`` with ``ftz`` (products are then at least ``2**(2p - 2)``).

    Exact zero sums are ``+0`` unless both the product and ``c`` are negative; ``0 * inf``
    raises NV even when ``c`` is a quiet NaN, as RISC-V does.

    Parameters
    ----------
    fmt : FloatFormat or str
        Operand and result format (default ``binary32``).
    subnormals : "ieee" or "ftz"
    stages : int or None
        Register stages, 0 to 8: the latency in cycles. ``None`` is 6 (a guess at 100 MHz on
        ECP5 for binary32; registers before the multiplier, before the wide add, before the
        normalisation, before the normalising shifter, before the rounding increment, and at
        the output).

    Members
    -------
    i_valid : In(1)
    i_a, i_b, i_c : In(fmt.width)
    o_valid : Out(1)
        ``i_valid`` delayed by ``latency`` cycles.
    o_y : Out(fmt.width)
    o_flags : Out(5)
        NX, UF, OF, DZ, NV from bit 0.

    Raises
    ------
    ValueError
        On a bad format, subnormal mode or stage count.

    Latency ``stages`` cycles; one operation per clock.
    """

    PLANS = {
        0: (),
        1: ("out",),
        2: ("norm", "out"),
        3: ("add", "norm", "out"),
        4: ("mul", "add", "norm", "out"),
        5: ("mul", "add", "norm", _R[1], "out"),
        6: ("mul", "add", "norm", _R[0], _R[1], "out"),
        7: ("mul", "add", "norm", _R[0], _R[1], _R[2], "out"),
        8: ("in", "mul", "add", "norm", _R[0], _R[1], _R[2], "out"),
    }
    DEFAULT_STAGES = 6

    def __init__(self, fmt: FloatFormat | str = FloatFormat(), *, subnormals: str = "ieee",
                 stages: int | None = None):
        super().__init__(fmt, subnormals, stages, lambda f: {
            "i_valid": In(1), "i_a": In(f.width), "i_b": In(f.width), "i_c": In(f.width),
            "o_valid": Out(1), "o_y": Out(f.width), "o_flags": Out(5),
        })

    def datapath(self, m, cuts):
        fmt, p = self.fmt, self.fmt.precision
        low = p + 4 if self.subnormals == "ieee" else max(1, 6 - p)
        frame = low + 3 * p + 4
        v = cuts("in", a=self.i_a, b=self.i_b, c=self.i_c)
        a = unpack(fmt, v.a, self.subnormals)
        b = unpack(fmt, v.b, self.subnormals)
        c = unpack(fmt, v.c, self.subnormals)
        prod_sign = a.sign ^ b.sign
        prod_exp = cuts.wire("prod_exp", a.exp + b.exp + 1)  # weight of the product's top bit
        zero_inf = cuts.wire("zero_inf", a.is_zero & b.is_inf | a.is_inf & b.is_zero)
        prod_inf = cuts.wire("prod_inf", (a.is_inf | b.is_inf) & ~a.is_nan & ~b.is_nan & ~zero_inf)
        inf_inf = cuts.wire("inf_inf", prod_inf & c.is_inf & (prod_sign ^ c.sign))
        # Right shift of the addend from the top of the frame; at or above the top, or with a
        # zero product, the frame is anchored to the addend instead.
        shift = cuts.wire("shift", p + 3 + prod_exp - c.exp)
        at_top = cuts.wire("at_top", a.is_zero | b.is_zero | (shift < 0) & ~c.is_zero)
        shift = Mux(at_top, 0, Mux(shift > frame - 2, frame - 2, shift))
        v = cuts("mul", sig_a=a.sig, sig_b=b.sig, sig_c=c.sig,
                 shift=shift[:(frame - 2).bit_length()],
                 exp=Mux(at_top, c.exp + 1, prod_exp + p + 4),  # weight of the frame's top bit
                 prod_sign=prod_sign, c_sign=c.sign,
                 is_nan=a.is_nan | b.is_nan | c.is_nan | zero_inf | inf_inf,
                 is_inf=prod_inf | c.is_inf,
                 inf_sign=Mux(prod_inf, prod_sign, c.sign),
                 invalid=a.is_snan | b.is_snan | c.is_snan | zero_inf | inf_inf)

        exp = prepare_exponent(cuts, fmt, v.exp, frame)  # (beside the multiplier)
        product = Cat(C(0, low), v.sig_a * v.sig_b, C(0, p + 4))
        wide = Cat(C(0, frame - 2), C(0, frame - 2 - p), v.sig_c) >> v.shift
        addend = Cat(wide[:frame - 2].any(), wide[frame - 2:], C(0, 1))
        v = cuts("add", product=product, addend=addend, exp=exp, prod_sign=v.prod_sign,
                 c_sign=v.c_sign, is_nan=v.is_nan, is_inf=v.is_inf, inf_sign=v.inf_sign,
                 invalid=v.invalid)

        sub = v.prod_sign ^ v.c_sign
        diff = cuts.wire("diff", v.product - v.addend)
        negative = cuts.wire("negative", sub & diff[frame])
        total = Mux(sub, Mux(negative, v.addend - v.product, diff), v.product + v.addend)
        sign = Mux(v.is_inf, v.inf_sign, Mux(negative, v.c_sign, v.prod_sign))
        v = cuts("norm", total=total[:frame], exp=v.exp, sign=sign,
                 zero_sign=v.prod_sign & v.c_sign, is_nan=v.is_nan, is_inf=v.is_inf,
                 invalid=v.invalid)

        return round_pack(cuts, fmt, sign=v.sign, exp=v.exp, sig=v.total, zero_sign=v.zero_sign,
                          is_nan=v.is_nan, is_inf=v.is_inf, invalid=v.invalid,
                          subnormals=self.subnormals)
