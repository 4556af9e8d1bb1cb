"""Floating-point multiplication, one operation per clock."""

from __future__ import annotations

import math
from types import SimpleNamespace

from amaranth.hdl import C, Cat, Mux, Signal, Value
from amaranth.lib.wiring import In, Out

from ..multiply import sum_rows
from .format import FloatFormat
from .timing import (carry_delay, dsp_delay, lut_delay, prepare_delay, round_delays, shifter_delay,
                     tree_levels)
from .round import (ROUND_BOUNDARIES, FloatUnit, leading_zeros, prepare_exponent, round_pack,
                    unpack)

__all__ = ["FloatMul", "product_rows", "partial_products", "sum_partial_products", "product_sum_delay"]

_R = ROUND_BOUNDARIES  # round.shift, round.round, round.select

#: The largest unsigned product one multiplier block takes whole on both families we build
#: for: ECP5's MULT18X18D multiplies 18 x 18 bits, a 7-series DSP48E1 25 x 18 signed (24 x 17
#: unsigned). ``a`` is cut in slices of the first width, ``b`` of the second.
DSP_SLICES = (18, 17)

#: The top slice of an operand (the remainder of its cut, or the whole operand) is multiplied
#: in LUTs, row by row, when it has at most this many bits: both top slices when their rows
#: come to no more, otherwise the narrower. Binary32 (24 = 18 + 6 and 17 + 7) takes two
#: DSP blocks and six rows; binary64 (53 = 18 + 18 + 17 and 3 * 17 + 2) nine and two rows.
LUT_ROWS = 8

#: LUT rows summed into one partial product: two adders deep, no slower than a DSP block.
ROW_GROUP = 4


def _split(width_a: int, width_b: int):
    """``(end_a, end_b, rows_a, rows_b)``: ``a``'s bits below ``end_a`` times ``b``'s below
    ``end_b`` are multiplied in blocks; ``a``'s bits in ``rows_a`` select rows of all of ``b``,
    ``b``'s in ``rows_b`` rows of ``a``'s block bits."""
    size_a, size_b = DSP_SLICES
    cut_a = (width_a - 1) // size_a * size_a  # where the top slices begin
    cut_b = (width_b - 1) // size_b * size_b
    # The top slices that go to LUTs: the narrower first (a's on a tie), both if they fit.
    fits = sorted((rows, op) for rows, op in ((width_a - cut_a, "a"), (width_b - cut_b, "b"))
                  if rows <= LUT_ROWS)
    lut = {op for k, (_, op) in enumerate(fits) if sum(r for r, _ in fits[:k + 1]) <= LUT_ROWS}
    end_a = cut_a if "a" in lut else width_a
    if not end_a:
        # a is all rows, each of the whole of b: there are no blocks, so no block bits of b
        # (nor rows of b, which would take a's block bits).
        return 0, 0, range(width_a), range(0)
    end_b = cut_b if "b" in lut else width_b
    return end_a, end_b, range(end_a, width_a), range(end_b, width_b)


def product_rows(a, b) -> dict:
    """The LUT rows of :func:`partial_products`, selected, by name. Registered before the
    multipliers (with ``a`` and ``b``), they take the selects off the rows' adder path."""
    a, b = Value.cast(a), Value.cast(b)
    end_a, _, rows_a, rows_b = _split(len(a), len(b))
    return {**{f"row_a{i}": Mux(a[i], b, 0) for i in rows_a},
            **{f"row_b{j}": Mux(b[j], a[:end_a], 0) for j in rows_b}}


def partial_products(a, b, rows=None) -> dict:
    """Partial products of ``a * b`` (unsigned) by name, ``pp<k>_<weight>``.

    Every ``*`` product here fits one multiplier block of either family (:data:`DSP_SLICES`),
    so none is split by synthesis into blocks and an adder; the LUT rows (:data:`LUT_ROWS`)
    are summed in groups of :data:`ROW_GROUP`, from ``rows`` (a namespace holding
    :func:`product_rows`) if given, else selected here. Put a register boundary after them:
    the block outputs go straight into it, and their adds (:func:`sum_partial_products`)
    come after.
    """
    a, b = Value.cast(a), Value.cast(b)
    size_a, size_b = DSP_SLICES
    end_a, end_b, rows_a, rows_b = _split(len(a), len(b))
    rows = product_rows(a, b) if rows is None else vars(rows)
    terms = [(a[i:min(i + size_a, end_a)] * b[j:min(j + size_b, end_b)], i + j)
             for i in range(0, end_a, size_a) for j in range(0, end_b, size_b)]
    for name, span in (("row_a", rows_a), ("row_b", rows_b)):
        for g in range(0, len(span), ROW_GROUP):
            group = [rows[f"{name}{k}"] for k in span[g:g + ROW_GROUP]]
            # (as wide as the product it is, not as the adders' carries)
            terms.append((sum_rows(group)[:len(group[0]) + len(group)], span[g]))
    return {f"pp{k}_{weight}": value for k, (value, weight) in enumerate(terms)}


def product_sum_delay(precision: int) -> float:
    """The delay (:mod:`.timing`'s model) of the sum of a ``precision`` x ``precision``
    product's partial products (blocks and LUT rows, :func:`partial_products`): lanes of terms
    that do not overlap, added pairwise in a balanced tree of carry chains as wide as the
    product. Here, beside the products it measures, so that the delay model imports no unit."""
    terms = sorted((int(name.rpartition("_")[2]), len(Value.cast(value)))
                   for name, value in partial_products(Signal(precision), Signal(precision)).items()
                   if name.startswith("pp"))
    lanes: list[int] = []  # each lane's end
    for at, width in terms:
        free = next((i for i, end in enumerate(lanes) if end <= at), None)
        if free is None:
            lanes.append(at + width)
        else:
            lanes[free] = at + width
    levels = math.ceil(math.log2(len(lanes))) if len(lanes) > 1 else 0
    return levels * carry_delay(2 * precision)


def _add_above(lo, hi, shift: int):
    """``lo + (hi << shift)``, the adder only where the two overlap."""
    if shift >= len(lo):
        return Cat(lo, C(0, shift - len(lo)), hi)
    return Cat(lo[:shift], lo[shift:] + hi)


def sum_partial_products(v, width: int, cut=None):
    """The product from the partial products in namespace ``v``, ``width`` bits.

    Terms that do not overlap are concatenated into lanes (binary64's nine blocks and two
    rows make six), and the lanes added pairwise in order of weight, a balanced tree; below
    the higher term of a pair the lower one's bits pass through without an adder.

    ``cut``, if given, is called after the tree's first level with its terms (``(value,
    weight)`` pairs) and returns them as they come out of a pipeline boundary: the tree's
    carry chains in two stages.
    """
    terms = sorted(((Value.cast(value), int(name.rpartition("_")[2]))
                    for name, value in vars(v).items() if name.startswith("pp")),
                   key=lambda t: t[1])
    lanes = []  # [value, weight], each filled from its lowest term up
    for value, at in terms:
        lane = next((lane for lane in lanes if lane[1] + len(lane[0]) <= at), None)
        if lane is None:
            lanes.append([value, at])
        else:
            lane[0] = Cat(lane[0], C(0, at - lane[1] - len(lane[0])), value)
    terms = [tuple(lane) for lane in lanes]
    level = 0
    while len(terms) > 1 or cut is not None and level == 0:
        paired = [(_add_above(lo, hi, at_hi - at_lo), at_lo)
                  for (lo, at_lo), (hi, at_hi) in zip(terms[0::2], terms[1::2])]
        terms = paired + terms[len(paired) * 2:]
        level += 1
        if level == 1 and cut is not None:
            terms = cut(terms)
    value, at = terms[0]
    return Cat(C(0, at), value)[:width]


#: The boundary after the first level of the partial products' adder tree, in the plan of 9
#: stages: the "norm" stage's carry chains in two (as the FMA's ``fma.sum``).
LANES_CUT = "mul.lanes"


def sum_in_two(cuts, name: str, v, width: int, rest: dict):
    """:func:`sum_partial_products` with the boundary ``name`` after the adder tree's first
    level, registering ``rest`` (the datapath's other live values) beside the tree's terms;
    returns the product and ``rest`` as they come out of the boundary."""
    held = {}

    def cut(terms):
        r = cuts(name, **{f"lane{i}": t for i, (t, _) in enumerate(terms)}, **rest)
        held.update(vars(r))
        return [(held[f"lane{i}"], at) for i, (_, at) in enumerate(terms)]

    product = sum_partial_products(v, width, cut=cut)
    return product, {key: held[key] for key in rest}


class FloatMul(FloatUnit):
    """``a * b`` rounded to nearest even.

    A subnormal operand's significand is normalised first (its leading zeros counted, then
    shifted out, the exponent lowered to match), so the product of the two significands has
    its leading one in one of its top two bits; the top bit picks the alignment and one of
    two exponents prepared beforehand. The ``precision + 1`` bits under the leading one and a
    sticky bit for the rest go to :func:`~.round.round_pack` under a constant leading one, so
    the rounder builds no leading-zero count and no left shift: only the right shift of a
    product below ``2**emin``. A zero operand gives a special zero.

    The product is the sum of :func:`partial_products`: blocks of at most 18 x 17 bits, which
    one MULT18X18D or DSP48E1 takes whole, and a few LUT rows (binary32: two blocks and six
    rows; binary16: one block; binary64: nine blocks and two rows). The rows are selected
    beside the operands' normalising shift and registered with the operands; the block
    outputs go straight into the register after the multipliers, and the sum comes after.

    Parameters
    ----------
    fmt : FloatFormat or str
        Operand and result format (default ``binary32``).
    subnormals : "ieee" or "ftz"
        With ``ftz`` there are no subnormal operands to normalise (the registers at that
        boundary stay, the count and the shifters go).
    stages : int or None
        Register stages, 0 to 8: the latency in cycles. ``None`` is 7 (about 130 MHz on an
        ECP5-85 for binary32, 126 MHz at worst over three placer seeds): registers before the
        operands' normalising shift, before and after the multipliers, after their sum,
        after the denormalising shift, before the final selects, and at the output.

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
        2: ("mul.sum", "out"),
        3: ("mul", "norm", "out"),
        4: ("mul", "norm", _R[1], "out"),
        5: ("mul", "mul.sum", "norm", _R[1], "out"),
        6: ("subnorm", "mul", "mul.sum", "norm", _R[1], "out"),
        7: ("subnorm", "mul", "mul.sum", "norm", _R[1], _R[2], "out"),
        8: ("in", "subnorm", "mul", "mul.sum", "norm", _R[1], _R[2], "out"),
        9: ("in", "subnorm", "mul", "mul.sum", LANES_CUT, "norm", _R[1], _R[2], "out"),
    }
    DEFAULT_STAGES = 7

    def __init__(self, fmt: FloatFormat | str = FloatFormat(), *, subnormals: str = "ieee",
                 stages: int | None = None):
        super().__init__(fmt, subnormals, stages, lambda f: {
            "i_valid": In(1), "i_a": In(f.width), "i_b": In(f.width),
            "o_valid": Out(1), "o_y": Out(f.width), "o_flags": Out(5),
        })

    def stage_segments(self, fmt, subnormals):
        """In order: the operands' leading-zero counts (ieee) beside the exponent sum; their
        normalising shifts and the LUT rows' selects; the multiplier blocks beside the
        exponents' preparation; the sum of the partial products with the top bit's selects;
        the rounding under a constant leading one."""
        p, e = fmt.precision, fmt.exp_bits
        ieee = subnormals == "ieee"
        return [("in", 0.0),
                ("subnorm", lut_delay(1) + max(lut_delay(2 + tree_levels(p)) if ieee else 0.0,
                                               carry_delay(e + 2))),
                ("mul", lut_delay(1) + (max(shifter_delay(p), carry_delay(e + 3)) if ieee else 0.0)),
                ("mul.sum", max(dsp_delay(), prepare_delay(fmt))),
                (LANES_CUT, min(product_sum_delay(p), carry_delay(2 * p))),
                ("norm", product_sum_delay(p) - min(product_sum_delay(p), carry_delay(2 * p)) + lut_delay(2)),
                *zip(_R + ("out",), round_delays(fmt, p + 1, leading_one=True, prepared=True))]

    def datapath(self, m, cuts):
        fmt, p = self.fmt, self.fmt.precision
        normalise = self.subnormals == "ieee"
        v = cuts("in", a=self.i_a, b=self.i_b)
        a = unpack(fmt, v.a, self.subnormals)
        b = unpack(fmt, v.b, self.subnormals)
        zero_inf = cuts.wire("zero_inf", a.is_zero & b.is_inf | a.is_inf & b.is_zero)
        zeros = {}
        if normalise:
            zeros = {"lz_a": leading_zeros(cuts, a.sig, "lz_a"),
                     "lz_b": leading_zeros(cuts, b.sig, "lz_b")}
        # The product's top bit weighs 2**(ea + eb + 1): its room above emin is
        # ea + eb + 1 - emin, the biased exponents' sum less the bias.
        v = cuts("subnorm", sig_a=a.sig, sig_b=b.sig, room=a.biased + b.biased - fmt.bias,
                 **zeros, sign=a.sign ^ b.sign,
                 is_nan=a.is_nan | b.is_nan | zero_inf,
                 is_inf=a.is_inf | b.is_inf,
                 is_zero=a.is_zero | b.is_zero,
                 invalid=a.is_snan | b.is_snan | zero_inf)

        sig_a, sig_b, room = v.sig_a, v.sig_b, v.room
        if normalise:
            sig_a, sig_b = (sig_a << v.lz_a)[:p], (sig_b << v.lz_b)[:p]
            room = room - (v.lz_a + v.lz_b)
        sig_a, sig_b = cuts.wire("norm_a", sig_a), cuts.wire("norm_b", sig_b)
        # Past the rows' selection only the block bits of the significands are read.
        end_a, end_b, _, _ = _split(p, p)
        v = cuts("mul", sig_a=sig_a[:end_a], sig_b=sig_b[:end_b], **product_rows(sig_a, sig_b), room=room,
                 sign=v.sign, is_nan=v.is_nan, is_inf=v.is_inf, is_zero=v.is_zero,
                 invalid=v.invalid)

        # Both significands have their top bit set (a zero operand gives a special zero), so
        # the product's leading one is one of its top two bits: the exponent is prepared for
        # both, and the top bit picks.
        width = p + 2
        exp_hi, exp_lo = (prepare_exponent(cuts, fmt, None, width, room=v.room - k)
                          for k in (0, 1))
        blocks_a, blocks_b = (Cat(x, C(0, p - len(x))) for x in (v.sig_a, v.sig_b))  # rows read the rest
        v = cuts("mul.sum", **partial_products(blocks_a, blocks_b, rows=v), exp_hi=exp_hi,
                 exp_lo=exp_lo, sign=v.sign, is_nan=v.is_nan, is_inf=v.is_inf,
                 is_zero=v.is_zero, invalid=v.invalid)

        if cuts.chooses(LANES_CUT):  # the partial products' adder tree in two stages
            rest = {k: x for k, x in vars(v).items() if not k.startswith("pp")}  # all but the terms
            total, rest = sum_in_two(cuts, LANES_CUT, v, 2 * p, rest)
            v = SimpleNamespace(**rest)
        else:
            total = sum_partial_products(v, 2 * p)
        # With a zero below: the significand under the leading one and the sticky bit. Of
        # the exponent, only the denormalising shift is picked here; the top bit picks the
        # rest after the register, beside that shift (less load on the adders' last carry).
        product = cuts.wire("product", Cat(C(0, 1), total))
        top, low = cuts.wire("top", product[2 * p]), p - 1
        v = cuts("norm", frac=Mux(top, product[low:2 * p], product[low - 1:2 * p - 1]),
                 sticky=product[:low - 1].any() | top & product[low - 1],
                 right=Mux(top, v.exp_hi.right, v.exp_lo.right), top=top, exp_hi=v.exp_hi,
                 exp_lo=v.exp_lo, sign=v.sign, is_nan=v.is_nan, is_inf=v.is_inf,
                 is_zero=v.is_zero, invalid=v.invalid)
        exp = Signal(exp_hi.shape(), name="exponent_picked")
        m.d.comb += exp.right.eq(v.right)
        for field in ("room", "below", "cap"):
            m.d.comb += getattr(exp, field).eq(Mux(v.top, getattr(v.exp_hi, field),
                                                   getattr(v.exp_lo, field)))

        # A constant leading one: the rounder's leading-zero count and left shift fold away.
        return round_pack(cuts, fmt, sign=v.sign, exp=exp, sig=Cat(v.frac, C(1, 1)),
                          sticky=v.sticky, is_nan=v.is_nan, is_inf=v.is_inf, is_zero=v.is_zero,
                          invalid=v.invalid, subnormals=self.subnormals)
