"""Floating-point multiplication, one operation per clock."""

from __future__ import annotations

from amaranth.lib.wiring import In, Out

from .format import FloatFormat
from .round import ROUND_BOUNDARIES, FloatUnit, prepare_exponent, round_pack, unpack

__all__ = ["FloatMul", "partial_products", "sum_partial_products"]

_R = ROUND_BOUNDARIES  # round.shift, round.round, round.select

#: Width of the slices of ``b`` the significand product is made of (an unsigned operand of an
#: 18-bit signed multiplier port).
PRODUCT_SLICE = 17


def partial_products(a, b) -> dict:
    """``a`` times 17-bit slices of ``b``, by name (``pp0``, ``pp17``...): each fits one
    DSP48E1 (25 x 18 signed) when ``a`` has at most 24 bits, so a binary32 product takes two.
    A register boundary after them keeps their adds (:func:`sum_partial_products`) apart."""
    return {f"pp{i}": a * b[i:i + PRODUCT_SLICE] for i in range(0, len(b), PRODUCT_SLICE)}


def sum_partial_products(v, width: int):
    """The product from the partial products in namespace ``v``, ``width`` bits."""
    return sum(value << int(name[2:]) for name, value in vars(v).items()
               if name.startswith("pp"))[:width]


class FloatMul(FloatUnit):
    """``a * b`` rounded to nearest even.

    The full ``2 * precision``-bit product of the significands (hidden bits included) goes
    to :func:`~.round.round_pack` unshortened: a subnormal operand leaves leading zeros that
    the rounder counts and shifts out, and a product below ``2**emin`` is shifted right there.
    The product is the sum of ``a``'s significand times 17-bit slices of ``b``'s (two
    DSP48E1 for binary32), with a register boundary between the multipliers and the sum.

    Parameters
    ----------
    fmt : FloatFormat or str
        Operand and result format (default ``binary32``).
    subnormals : "ieee" or "ftz"
    stages : int or None
        Register stages, 0 to 8: the latency in cycles. ``None`` is 6 (about 100 MHz on an
        ECP5-85 for binary32: registers before and after the multipliers, after their sum,
        before the normalising shift, before the rounding increment, and at the output).

    Members
    -------
    i_valid : In(1)
    i_a, i_b : In(fmt.width)
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
        3: ("norm", _R[1], "out"),
        4: ("mul", "norm", _R[1], "out"),
        5: ("mul", "norm", _R[0], _R[1], "out"),
        6: ("mul", "mul.sum", "norm", _R[0], _R[1], "out"),
        7: ("mul", "mul.sum", "norm", _R[0], _R[1], _R[2], "out"),
        8: ("in", "mul", "mul.sum", "norm", _R[0], _R[1], _R[2], "out"),
    }
    DEFAULT_STAGES = 6

    def __init__(self, fmt: FloatFormat | str = FloatFormat(), *, subnormals: str = "ieee",
                 stages: int | None = None):
        super().__init__(fmt, subnormals, stages, lambda f: {
            "i_valid": In(1), "i_a": In(f.width), "i_b": In(f.width),
            "o_valid": Out(1), "o_y": Out(f.width), "o_flags": Out(5),
        })

    def datapath(self, m, cuts):
        fmt = self.fmt
        v = cuts("in", a=self.i_a, b=self.i_b)
        a = unpack(fmt, v.a, self.subnormals)
        b = unpack(fmt, v.b, self.subnormals)
        zero_inf = cuts.wire("zero_inf", a.is_zero & b.is_inf | a.is_inf & b.is_zero)
        # The product's top bit weighs 2**(ea + eb + 1): its room above emin is
        # ea + eb + 1 - emin, the biased exponents' sum less the bias.
        v = cuts("mul", sig_a=a.sig, sig_b=b.sig, room=a.biased + b.biased - fmt.bias,
                 sign=a.sign ^ b.sign,
                 is_nan=a.is_nan | b.is_nan | zero_inf,
                 is_inf=a.is_inf | b.is_inf,
                 invalid=a.is_snan | b.is_snan | zero_inf)

        exp = prepare_exponent(cuts, fmt, None, 2 * fmt.precision, room=v.room)
        v = cuts("mul.sum", **partial_products(v.sig_a, v.sig_b), exp=exp, sign=v.sign,
                 is_nan=v.is_nan, is_inf=v.is_inf, invalid=v.invalid)

        product = sum_partial_products(v, 2 * fmt.precision)
        v = cuts("norm", product=product, exp=v.exp, sign=v.sign, is_nan=v.is_nan,
                 is_inf=v.is_inf, invalid=v.invalid)

        return round_pack(cuts, fmt, sign=v.sign, exp=v.exp, sig=v.product, is_nan=v.is_nan,
                          is_inf=v.is_inf, invalid=v.invalid, subnormals=self.subnormals)
