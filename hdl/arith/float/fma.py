"""Fused multiply-add ``a * b + c`` with a single rounding, one operation per clock."""

from __future__ import annotations

from types import SimpleNamespace

from amaranth.hdl import C, Cat, Mux
from amaranth.lib.wiring import In, Out

from .format import FloatFormat
from .timing import carry_delay, dsp_delay, lut_delay, round_delays, shifter_delay, tree_levels
from .mul import ROW_GROUP, partial_products, product_sum_delay, sum_in_two, sum_partial_products
from .round import (ROUND_BOUNDARIES, ROUND_COUNT, ROUND_HALF, ROUND_UP, FloatUnit, leading_zeros, prepare_exponent,
                    round_pack, unpack)

__all__ = ["FloatFMA"]

_R = ROUND_BOUNDARIES  # round.shift, round.round, round.select
#: The boundary after the exponent adds (with the first half of the addend's trailing-zero
#: count), in the plans of 11 stages and more: the "mul" stage's logic in two.
EXP_CUT = "fma.exp"
#: The boundary after the first level of the partial products' adder tree, in the plans of 12
#: stages and more: the "add" stage's carry chains in two.
SUM_CUT = "fma.sum"


class FloatFMA(FloatUnit):
    """``a * b + c`` computed exactly and rounded once, to nearest even.

    The exact ``2p``-bit product (``p`` = precision, made as :class:`~.mul.FloatMul` makes
    it, from partial products) sits at a fixed place in a frame of
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
        Register stages, 0 to 10: the latency in cycles. ``None`` is 9 (registers before and
        after the multipliers, which run beside the addend's alignment; after the sum of their
        partial products, beside which the addend is inverted for a difference; after the wide
        adders, beside which the exponent side of the rounding is prepared; halfway through
        the leading-zero count over the ``F``-bit sum (104 bits); before the normalising
        shift, the rounding increment and the final select; and at the output). That is
        119-122 MHz on an ECP5-85 for binary32 (nextpnr seeds 1 to 3 at 125 MHz).

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
        3: ("mul.sum", "norm", "out"),
        4: ("mul", "mul.sum", "norm", "out"),
        5: ("mul", "mul.sum", "norm", _R[1], "out"),
        6: ("mul", "mul.sum", "add", "norm", _R[1], "out"),
        7: ("mul", "mul.sum", "add", "norm", _R[0], _R[1], "out"),
        8: ("mul", "mul.sum", "add", "norm", _R[0], _R[1], _R[2], "out"),
        9: ("mul", "mul.sum", "add", "norm", ROUND_COUNT, _R[0], _R[1], _R[2], "out"),
        10: ("in", "mul", "mul.sum", "add", "norm", ROUND_COUNT, _R[0], _R[1], _R[2], "out"),
        11: ("in", EXP_CUT, "mul", "mul.sum", "add", "norm", ROUND_COUNT, _R[0], _R[1], _R[2], "out"),
        12: ("in", EXP_CUT, "mul", "mul.sum", SUM_CUT, "add", "norm", ROUND_COUNT, _R[0], _R[1], _R[2], "out"),
        13: ("in", EXP_CUT, "mul", "mul.sum", SUM_CUT, "add", "norm", ROUND_COUNT, _R[0], _R[1], ROUND_UP, _R[2],
             "out"),
        14: ("in", EXP_CUT, "mul", "mul.sum", SUM_CUT, "add", "norm", ROUND_COUNT, _R[0], ROUND_HALF, _R[1],
             ROUND_UP, _R[2], "out"),
    }
    DEFAULT_STAGES = 9

    def __init__(self, fmt: FloatFormat | str = FloatFormat(), *, subnormals: str = "ieee",
                 stages: int | None = None):
        super().__init__(fmt, subnormals, stages, lambda f: {
            "i_valid": In(1), "i_a": In(f.width), "i_b": In(f.width), "i_c": In(f.width),
            "o_valid": Out(1), "o_y": Out(f.width), "o_flags": Out(5),
        })

    def stage_segments(self, fmt, subnormals):
        """In order: the exponent sum (beside the addend's trailing-zero count, whose first
        half goes with it); the addend's shift from it and their caps; the multiplier blocks beside the addend's
        alignment; the sum of the partial products; the adders over the frame with the
        exponent's preparation; the rounding, its leading-zero count cut in two."""
        p, e = fmt.precision, fmt.exp_bits
        low = p + 4 if subnormals == "ieee" else max(1, 6 - p)
        frame = low + 3 * p + 4
        shift, normalise, round_up, out = round_delays(fmt, frame, prepared=True)
        # The normalising shift over the whole frame (76 bits in binary32) measured 8.5 ns
        # (nextpnr, 11 and 13 stages): the model's shifter, fitted on significand-wide shifts,
        # is 35 % short for it. (Only --target-mhz reads this list.)
        normalise *= 1.35
        count = lut_delay(2 + tree_levels(frame))
        first = lut_delay(1 + tree_levels(frame) // 2)
        return [("in", 0.0),
                (EXP_CUT, lut_delay(1) + carry_delay(e + 3)),
                ("mul", carry_delay(e + 3) + lut_delay(2)),
                # beside the blocks: the LUT rows' selects and their sums in groups (as wide as
                # the product), measured the longest here at 14 stages (8.1 ns)
                ("mul.sum", max(dsp_delay(), shifter_delay(frame) + lut_delay(1),
                                lut_delay(1) + tree_levels(ROW_GROUP) * carry_delay(2 * p))),
                (SUM_CUT, min(product_sum_delay(p), carry_delay(2 * p))),
                ("add", product_sum_delay(p) - min(product_sum_delay(p), carry_delay(2 * p)) + lut_delay(1)),
                ("norm", carry_delay(2 * p + 1) + lut_delay(2)),
                (ROUND_COUNT, max(first, shift - count + first)),
                (_R[0], count - first),
                (ROUND_HALF, normalise / 2), (_R[1], normalise / 2),
                (ROUND_UP, round_up - lut_delay(3)), (_R[2], lut_delay(3)), ("out", out)]

    def datapath(self, m, cuts):
        fmt, p = self.fmt, self.fmt.precision
        low = p + 4 if self.subnormals == "ieee" else max(1, 6 - p)
        frame = low + 3 * p + 4
        v = cuts("in", a=self.i_a, b=self.i_b, c=self.i_c)
        a = unpack(fmt, v.a, self.subnormals)
        b = unpack(fmt, v.b, self.subnormals)
        c = unpack(fmt, v.c, self.subnormals)
        prod_sign = a.sign ^ b.sign
        zero_inf = cuts.wire("zero_inf", a.is_zero & b.is_inf | a.is_inf & b.is_zero)
        prod_inf = cuts.wire("prod_inf", (a.is_inf | b.is_inf) & ~a.is_nan & ~b.is_nan & ~zero_inf)
        inf_inf = cuts.wire("inf_inf", prod_inf & c.is_inf & (prod_sign ^ c.sign))
        # Right shift of the addend from the top of the frame, p + 3 + (ea + eb + 1) - ec (the
        # product's top bit weighs 2**(ea + eb + 1)), on biased exponents. At or above the top,
        # or with a zero product, the frame is anchored to the addend instead.
        # (Two adds deep: the constant goes with the addend's exponent.)
        offset = p + 4 - fmt.bias
        prod_biased = cuts.wire("prod_biased", a.biased + b.biased)
        flags = dict(is_nan=a.is_nan | b.is_nan | c.is_nan | zero_inf | inf_inf,
                     is_inf=prod_inf | c.is_inf,
                     inf_sign=Mux(prod_inf, prod_sign, c.sign),
                     invalid=a.is_snan | b.is_snan | c.is_snan | zero_inf | inf_inf)
        # From frame - 2 places on the addend is all sticky: a shift with a bit set above
        # those counting to frame - 2 becomes the largest shift they count to.
        bits = (frame - 2).bit_length()
        if cuts.chooses(EXP_CUT):
            # A stage of its own for the exponent adds, beside the first half of the addend's
            # trailing-zero count: the shift is then one subtract from registers.
            held = {}

            def exp_cut(values):
                r = cuts(EXP_CUT, **values, prod_biased=prod_biased, c_room=c.biased - offset,
                         c_biased=c.biased, sig_a=a.sig, sig_b=b.sig, sig_c=c.sig,
                         zero_ab=a.is_zero | b.is_zero, zero_c=c.is_zero, prod_sign=prod_sign,
                         c_sign=c.sign, **flags)
                held.update(vars(r))
                return {key: held[key] for key in values}

            tail = leading_zeros(cuts, cuts.wire("sig_c_reversed", c.sig[::-1]), "tz", cut=exp_cut)
            r = SimpleNamespace(**held)
            shift = cuts.wire("shift", r.prod_biased - r.c_room)
            at_top = cuts.wire("at_top", r.zero_ab | shift[-1] & ~r.zero_c)
            shift = Mux(at_top, 0, Mux(shift[bits:].any(), (1 << bits) - 1, shift[:bits]))
            prod_biased, c_biased, prod_sign, c_sign = r.prod_biased, r.c_biased, r.prod_sign, r.c_sign
            sig_a, sig_b, sig_c, zero_c = r.sig_a, r.sig_b, r.sig_c, r.zero_c
            flags = {key: getattr(r, key) for key in flags}
        else:
            shift = cuts.wire("shift", prod_biased - (c.biased - offset))
            at_top = cuts.wire("at_top", a.is_zero | b.is_zero | shift[-1] & ~c.is_zero)
            shift = Mux(at_top, 0, Mux(shift[bits:].any(), (1 << bits) - 1, shift[:bits]))
            # The addend's bits shifted out of the frame are nonzero when its lowest one is
            # among them: the sticky bit is a compare with its trailing zeros, beside the shifter.
            tail = leading_zeros(cuts, cuts.wire("sig_c_reversed", c.sig[::-1]), "tz")
            c_biased, c_sign, sig_a, sig_b, sig_c, zero_c = c.biased, c.sign, a.sig, b.sig, c.sig, c.is_zero
        v = cuts("mul", sig_a=sig_a, sig_b=sig_b, sig_c=sig_c, shift=shift,
                 tail=tail, c_nonzero=~zero_c,
                 # Room above emin of the frame's top bit: it weighs 2**(ec + 1) anchored to
                 # the addend, 2**(ea + eb + 1 + p + 4) to the product.
                 room=Mux(at_top, c_biased, prod_biased + offset),
                 prod_sign=prod_sign, c_sign=c_sign, **flags)

        # Beside the multipliers: the addend's alignment, from the top of the frame (bits
        # frame - 2 down to 1) with the sticky bit under it.
        aligned = Cat(C(0, frame - 2 - p), v.sig_c) >> v.shift
        sticky = v.c_nonzero & (v.tail + (frame - 2 - p) < v.shift)
        addend = Cat(sticky, aligned, C(0, 1))
        v = cuts("mul.sum", **partial_products(v.sig_a, v.sig_b), addend=addend, room=v.room,
                 sub=v.prod_sign ^ v.c_sign, prod_sign=v.prod_sign, c_sign=v.c_sign,
                 is_nan=v.is_nan, is_inf=v.is_inf, inf_sign=v.inf_sign, invalid=v.invalid)

        # Beside the sum of the partial products: the addend inverted for a difference; the
        # carry out of its bits under the product's, and its bits above the product's plus
        # one. The wide adders below then start from registers and carry over the product's
        # bits only.
        addend = cuts.wire("addend", Mux(v.sub, ~v.addend, v.addend))
        top = low + 2 * p  # the bits above the product's
        rest = dict(addend=addend, carry=v.sub & addend[:low].all(), above=addend[top:] + 1,
                    room=v.room, sub=v.sub, prod_sign=v.prod_sign, c_sign=v.c_sign,
                    is_nan=v.is_nan, is_inf=v.is_inf, inf_sign=v.inf_sign, invalid=v.invalid)
        if cuts.chooses(SUM_CUT):  # the partial products' adder tree in two stages
            product, rest = sum_in_two(cuts, SUM_CUT, v, 2 * p, rest)
        else:
            product = sum_partial_products(v, 2 * p)
        v = cuts("add", product=product, **rest)

        # Two adders from the same operands: the sum or the difference (the carry in under the
        # lowest bit) and, for a difference that comes out negative (no carry out: product <
        # addend), the difference minus one, whose complement is the difference the other way
        # round. Under the product's bits the first is the addend plus the carry in, the
        # second the addend; above them either is the addend, plus one after a carry.
        # Beside them: the exponent side of the rounding.
        def place(carry_in):
            middle = (Cat(carry_in, v.product) + Cat(carry_in, v.addend[low:top]))[1:]
            return Cat(middle[:-1], Mux(middle[-1], v.above, v.addend[top:]))

        either = cuts.wire("either", Cat((v.addend[:low] + v.sub)[:low], place(v.carry)))
        negative = cuts.wire("negative", v.sub & ~either[frame])
        total = Mux(negative, ~Cat(v.addend[:low], place(0))[:frame], either[:frame])
        sign = Mux(v.is_inf, v.inf_sign, Mux(negative, v.c_sign, v.prod_sign))
        exp = prepare_exponent(cuts, fmt, None, frame, room=v.room, marker=True)
        v = cuts("norm", total=total, exp=exp, sign=sign,
                 zero_sign=v.prod_sign & v.c_sign, is_nan=v.is_nan, is_inf=v.is_inf,
                 invalid=v.invalid)

        return round_pack(cuts, fmt, sign=v.sign, exp=v.exp, sig=v.total, zero_sign=v.zero_sign,
                          is_nan=v.is_nan, is_inf=v.is_inf, invalid=v.invalid,
                          subnormals=self.subnormals)
