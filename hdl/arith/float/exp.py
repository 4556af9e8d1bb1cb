"""Floating-point exponential ``e**x``, faithfully rounded, one operation per clock."""

from __future__ import annotations

from types import SimpleNamespace

from amaranth.hdl import Array, C, Cat, Mux, Signal, Value
from amaranth.lib.wiring import In, Out

from .exp_plan import CHUNK, exp_plan
from .format import FloatFormat
from .mul import LUT_ROWS, partial_products, sum_partial_products
from .round import ROUND_BOUNDARIES, FloatUnit, prepare_exponent, round_pack, unpack
from .timing import (StagePlans, block_ram_delay, carry_delay, dsp_delay, lut_delay, prepare_delay,
                     round_delays, shifter_delay)

__all__ = ["FloatExp"]


def _trim(terms, drop: int) -> list:
    """``(value, weight)`` terms of a sum whose bits below ``drop`` will be dropped, less the
    lowest term's bits that would pass through to them untouched (below every other term):
    no carry comes out of those, so they only make unused logic."""
    terms = sorted(((Value.cast(v), w) for v, w in terms), key=lambda t: t[1])
    while terms:
        (value, weight), rest = terms[0], terms[1:]
        cut = min([drop] + [w for _, w in rest]) - weight
        if cut <= 0:
            break
        terms = rest if cut >= len(value) else sorted([(value[cut:], weight + cut)] + rest, key=lambda t: t[1])
    return terms


def _add_terms(terms, drop: int = 0) -> Value:
    """``sum(value << weight)`` of ``(value, weight)`` pairs (its bits from ``drop`` up are the
    ones used), added pairwise in order of weight (a balanced tree); below the higher term of
    a pair the lower one's bits pass through."""
    terms = _trim(terms, drop)
    while len(terms) > 1:
        paired = []
        for (lo, at_lo), (hi, at_hi) in zip(terms[0::2], terms[1::2]):
            shift = at_hi - at_lo
            paired.append((Cat(lo, C(0, shift - len(lo)), hi) if shift >= len(lo)
                           else Cat(lo[:shift], lo[shift:] + hi), at_lo))
        terms = paired + terms[len(paired) * 2:]
    value, weight = terms[0]
    return Cat(C(0, weight), value) if weight else value


def _constant_product(cuts, name, x, entries, shifted: bool, drop: int = 0) -> Value:
    """A product of ``x`` by a constant, from tables: ``entries(i, j)`` for the ``i``-th
    :data:`~.exp_plan.CHUNK`-bit slice ``j`` of ``x`` (one LUT level), at weight ``CHUNK * i``
    if ``shifted`` else 0, summed (:func:`_add_terms`; its bits from ``drop`` up used)."""
    terms = []
    for i in range(0, len(x), CHUNK):
        part = x[i:i + CHUNK]
        values = [entries(i // CHUNK, j) for j in range(1 << len(part))]
        width = max(max(values).bit_length(), 1)
        terms.append((Array(C(v, width) for v in values)[part], i if shifted else 0))
    terms = [(cuts.wire(f"{name}{k}", value), weight) for k, (value, weight) in enumerate(_trim(terms, drop))]
    return _add_terms(terms, drop)


def _adder_levels(terms: int) -> int:
    """Adders deep of a pairwise sum of ``terms`` values."""
    return (terms - 1).bit_length()


def _product_delays(width_a: int, width_b: int) -> tuple[float, float]:
    """Delays of :func:`~.mul.partial_products` (multiplier blocks, or LUT rows summed four at
    a time when both operands are narrow) and of :func:`~.mul.sum_partial_products` (about a
    lane per block, added pairwise)."""
    width = width_a + width_b
    if max(width_a, width_b) <= LUT_ROWS:
        return lut_delay(1) + 2 * carry_delay(width), _adder_levels(-(-min(width_a, width_b) // 4)) * carry_delay(width)
    lanes = -(-width_a // 18) * -(-width_b // 17) + 1
    return dsp_delay(), _adder_levels(lanes) * carry_delay(width)


class FloatExp(FloatUnit):
    """``e**x``, faithfully rounded: the result is one of the two floats around ``e**x``
    (an error below one unit in the last place), correctly rounded for 98 to 99.9 % of inputs.

    Algorithm (widths and constants per format from :func:`~.exp_plan.exp_plan`, whose
    docstring lists them; ``p`` is the precision, ``G`` the working bits, ``p + 4`` in the
    named formats):

    1. Range reduction (Cody and Waite, in fixed point). ``X = floor(|x| 2**F)`` (``F``, from
       ``G`` to ``G + 2`` fraction bits) by a right shift of the significand; ``|x| >= 2**I``
       (``I`` the least with ``2**I`` above ``0.7 (emax + 1)`` and ``0.7 (bias + m)``) only
       selects overflow or zero. ``k = round(X / ln 2)`` from the top ``I + 4`` bits of ``X`` times
       ``1 / ln 2`` to ``I + 4`` bits, a constant product made of 16-entry tables (one per 4
       bits of the variable, one LUT4 per bit) and adders; ``|r| = |x - k ln 2| < 0.44``.
       ``r = +-(X - k ln 2)`` is computed modulo 1 in ``F`` bits: ``k ln 2`` comes from one
       such table per 4 bits of ``k`` holding ``j 16**i ln 2`` modulo 1, each entry rounded.
    2. ``e**r = e**A e**Z``: the top 8 bits of ``r`` (fewer in narrow formats) index a table
       of ``e**A`` rounded to ``G`` bits (a ROM, which synthesis may put in a block RAM
       when a register follows it); ``Z`` (the rest, ``0 <= Z < 2**-8``) goes into ``Q ~
       e**Z - 1``, its Taylor polynomial (degree 1, ``Q = Z``, in binary16, bfloat16 and
       narrower formats; 3 in binary32; 6 in binary64) in Horner form, each step's product
       as narrow as its weight allows (``Z`` floored, the product floored);
       ``y = T + T Q`` with ``T`` floored to ``G - 5`` bits in the product (``T Q < 2**-7``).
       The first Horner step multiplies by a constant (shifts and adds), the others by
       multiplier blocks and LUT rows as :class:`~.mul.FloatMul` does.
    3. ``e**x ~ y 2**k`` with ``y`` in ``[0.6, 1.7)``: ``y``'s top bit picks one of two
       exponents prepared during the polynomial, and the shared rounding stage
       (:func:`~.round.round_pack`, under a constant leading one) rounds once to nearest, at
       the subnormal position when ``y 2**k < 2**emin``, with the sticky bit set for every
       ``x != 0`` (``e**x`` is irrational there, so always inexact).

    Error bound: every truncation and rounding contributes a rational upper bound (the
    reduced argument's ``(2 + slices) / 2`` units of ``2**-F``, the table's half unit, each
    Horner step's floors and the Taylor remainder weighted by the powers of ``Z`` they meet,
    the product's floor, the sticky bit); :func:`~.exp_plan.exp_plan` adds them and picks
    the fewest work bits for which the relative error of ``y 2**k`` is below
    ``2**-(p+1)`` (binary32: ``2**-25.07``). Rounding that to nearest gives one of the two
    floats around ``e**x``: the error is under half the spacing above and a quarter of it
    below a power of two. The bound is also held below the distance from ``x`` to ``ln`` of
    the overflow threshold at the floats on either side of it, so the result overflows
    exactly when ``e**x`` rounded to nearest would. The golden model
    (:mod:`kfgen.sim.fpu.exp_model`) reproduces this arithmetic bit for bit; the exact
    reference (:mod:`kfgen.sim.fpu.exp_exact`) checks faithfulness, exhaustively in
    binary16 and bfloat16.

    Results and flags: ``e**(+-0) = 1`` exactly, no flag; every other finite ``x`` raises NX;
    a result at or above the overflow threshold is ``+inf`` with OF|NX; a result below
    ``2**emin`` is rounded at the subnormal position, through the subnormals down to ``+0``,
    with UF|NX when it is tiny after rounding (with ``ftz``, flushed to ``+0`` with UF|NX,
    and subnormal ``x`` read as zero: ``1`` exactly); ``e**+inf = +inf`` and ``e**-inf =
    +0``, exact; a NaN gives the canonical NaN, with NV if it is signalling.

    Parameters
    ----------
    fmt : FloatFormat or str
        Operand and result format (default ``binary32``).
    subnormals : "ieee" or "ftz"
    stages : int or None
        Register stages, the latency in cycles, from 0 to one per boundary of the datapath
        (binary32: 18), placed to balance the stages by the delay model of :mod:`.timing`.
        ``None`` is the fewest stages whose logic fits 100 MHz on an ECP5 by that model.

    Members
    -------
    i_valid : In(1)
    i_a : In(fmt.width)
        ``x``.
    o_valid : Out(1)
        ``i_valid`` delayed by ``latency`` cycles.
    o_y : Out(fmt.width)
        ``e**x``.
    o_flags : Out(5)
        NX, UF, OF, DZ, NV from bit 0 (DZ never).

    Raises
    ------
    ValueError
        On a bad format, subnormal mode or stage count.

    Latency ``stages`` cycles; one operation per clock.
    """

    def __init__(self, fmt: FloatFormat | str = FloatFormat(), *, subnormals: str = "ieee",
                 stages: int | None = None):
        super().__init__(fmt, subnormals, stages, lambda f: {
            "i_valid": In(1), "i_a": In(f.width),
            "o_valid": Out(1), "o_y": Out(f.width), "o_flags": Out(5),
        })

    # -- the datapath's boundaries and their delays -------------------------------------------
    @staticmethod
    def _polynomial(plan):
        """``(name, z_bits, bits, const, constant_operand)`` of each Horner product before
        ``Q``'s: ``h<j>`` for ``H_j`` and ``w`` for ``W``."""
        out = []
        for n, (z_bits, bits, const, _) in enumerate(plan.steps):
            j = plan.degree - 1 - n
            out.append(("w" if j == 1 else f"h{j}", z_bits, bits, const, n == 0))
        return out

    def stage_plans(self, fmt, subnormals):
        plan = exp_plan(fmt)
        p, I, F, G, a = fmt.precision, plan.int_bits, plan.frac_bits, plan.work_bits, plan.index_bits
        x_slices = -(-(I + plan.k_frac) // CHUNK)
        k_slices = len(plan.ln2_tables)
        exponent = carry_delay(plan.k_bits + 2) + lut_delay(1)  # +-k, the forced values
        segments = [
            ("in", 0.0),
            ("unpack", lut_delay(1) + carry_delay(fmt.exp_bits + 2) + lut_delay(1)),
            ("align", shifter_delay(I + F)),
            ("k", lut_delay(1) + _adder_levels(x_slices) * carry_delay(I + plan.k_frac + plan.inv_ln2_bits)),
            ("kln2", max(lut_delay(1) + _adder_levels(k_slices) * carry_delay(F), exponent)),
            ("r", max(lut_delay(1) + carry_delay(F), carry_delay(plan.k_bits + 3) + prepare_delay(fmt, True))),
        ]
        # The table of e**A is read after "r", beside the first Horner step (a constant product,
        # whose register becomes the table's own when a synthesis tool makes it a block RAM: T
        # then passes to the next register, unused until T Q). For degree 1 T Q follows at
        # once, so the table has two boundaries of its own: the register after the lookup and
        # one more after a block RAM's slow clock-to-out.
        rom = lut_delay(max(1, a - 3))  # LUT4s, then the slice's wide-function multiplexers
        h_width = plan.coeff_top.bit_length()
        for name, z_bits, bits, const, constant in self._polynomial(plan):
            if constant:
                rows = bin(plan.coeff_top).count("1")
                add = _adder_levels(rows) * carry_delay(z_bits - a + h_width)
                segments.append((name, max(add + (carry_delay(bits) if const else 0.0), rom)))
            else:
                pp, add = _product_delays(z_bits - a, h_width)
                segments += [(f"{name}.pp", pp), (name, add + (carry_delay(bits) if const else 0.0))]
            h_width = _step_width(plan, name)
        if plan.degree > 1:
            pp, add = _product_delays(plan.q_z_bits - a, h_width)
            segments += [("q.pp", pp), ("q", add + carry_delay(plan.q_bits))]
        else:
            segments += [("table", rom), ("table.out", block_ram_delay())]
        pp, add = _product_delays(plan.t_bits + 1, plan.q_bits - a + 1)
        segments += [("tq.pp", pp), ("tq", add), ("y", carry_delay(G + 1) + lut_delay(1))]
        shift, *rest = round_delays(fmt, G + 1, True, leading_one=True, prepared=True)
        segments += list(zip(ROUND_BOUNDARIES + ("out",), [shift + lut_delay(1)] + rest))
        plans = StagePlans(segments)
        return plans, plans.default()

    # -- the datapath ---------------------------------------------------------------------------
    def datapath(self, m, cuts):
        fmt, plan = self.fmt, exp_plan(self.fmt)
        p, I, F, G, a = fmt.precision, plan.int_bits, plan.frac_bits, plan.work_bits, plan.index_bits
        q_frac = plan.k_frac
        v = cuts("in", a=self.i_a)
        x = unpack(fmt, v.a, self.subnormals)
        # X's right shift from the top of I + F bits, I - 1 - e, from the biased exponent; the
        # compares beside the subtraction. |x| >= 2**I (a negative shift) only decides k; past
        # I + F places X is zero.
        span, corner = I + F, I - 1 + fmt.bias
        # (In a format whose largest finite |x| is below 2**I, never.)
        big = x.biased > corner if corner < fmt.exp_max_field - 1 else C(0, 1)
        right = (C(corner) - x.biased)[:span.bit_length()]
        if corner - span > 0:
            right = Mux(x.biased < corner - span, span, right)
        v = cuts("unpack", sig=x.sig, sign=x.sign, big=big, right=Mux(big, 0, right),
                 nonzero=~x.is_zero, is_nan=x.is_nan, is_inf=x.is_inf & ~x.sign,
                 is_zero=x.is_inf & x.sign, invalid=x.is_snan)
        specials = dict(sign=v.sign, big=v.big, nonzero=v.nonzero, is_nan=v.is_nan,
                        is_inf=v.is_inf, is_zero=v.is_zero, invalid=v.invalid)

        fixed = cuts.wire("fixed", Cat(C(0, span - p), v.sig) >> v.right)
        v = cuts("align", top=fixed[F - q_frac:], low=fixed[:F], **specials)
        specials = {key: getattr(v, key) for key in specials}

        # k = round(X / ln 2): the top bits times 1/ln 2, the half for the rounding in the
        # lowest slice's table.
        shift = q_frac + plan.inv_ln2_bits
        k_sum = _constant_product(cuts, "k_table", v.top,
                                  lambda i, j: j * plan.inv_ln2 + (1 << (shift - 1) if i == 0 else 0),
                                  shifted=True, drop=shift)
        v = cuts("k", k=k_sum[shift:shift + plan.k_bits], low=v.low, **specials)
        specials = {key: getattr(v, key) for key in specials}

        # k ln 2 modulo 1; beside it, the exponent +-k (or a forced one).
        k_ln2 = _constant_product(cuts, "kln2_table", v.k, lambda i, j: plan.ln2_tables[i][j], shifted=False)
        k_signed = Mux(v.sign, -v.k, v.k)
        k_signed = cuts.wire("k_signed", Mux(v.big, Mux(v.sign, plan.k_under, plan.k_over), k_signed))
        specials = {key: value for key, value in specials.items() if key != "big"}
        v = cuts("kln2", k_ln2=k_ln2[:F], low=v.low, k_signed=k_signed, **specials)
        specials = {key: getattr(v, key) for key in specials if key != "sign"}

        # r = +-(X - k ln 2) modulo 1. Beside it, the rounding stage's exponent for both places
        # of y's leading one: 2**k (y >= 1) and 2**(k - 1).
        minuend, subtrahend = Mux(v.sign, v.k_ln2, v.low), Mux(v.sign, v.low, v.k_ln2)
        r = cuts.wire("r", (minuend - subtrahend)[:F])
        width = G + 1
        exp_hi, exp_lo = (prepare_exponent(cuts, fmt, None, width, room=v.k_signed - (fmt.emin + d))
                          for d in (0, 1))
        carried = dict(exp_hi=exp_hi, exp_lo=exp_lo, **specials)
        v = cuts("r", index=r[F - a:], z=r[:F - a], **carried)
        table = cuts.wire("exp_table", Array(C(t, G + 1) for t in plan.table)[v.index])
        v = SimpleNamespace(t=table, **{key: value for key, value in vars(v).items() if key != "index"})

        def keep():
            return {key: getattr(v, key) for key in carried}

        def z_floor(bits):  # Z floored to `bits` fraction bits
            return v.z[F - bits:] if bits < F else v.z

        # Q ~ e**Z - 1 by Horner.
        h, h_bits = C(plan.coeff_top, max(1, plan.coeff_top.bit_length())), plan.coeff_top_bits
        for name, z_bits, bits, const, constant in self._polynomial(plan):
            zz = z_floor(z_bits)
            drop = z_bits + h_bits - bits
            if constant:
                prod = _add_terms([(zz, i) for i in range(len(h)) if plan.coeff_top >> i & 1], drop)
            else:
                v = cuts(f"{name}.pp", **_named(name, partial_products(zz, v.h), drop), z=v.z, t=v.t, **keep())
                prod = sum_partial_products(_products(v, name), len(zz) + len(h))
            result = prod[drop:] if const == 0 else const + prod[drop:]
            v = cuts(name, h=result[:_step_width(plan, name)], z=v.z, t=v.t, **keep())
            h, h_bits = v.h, bits
        if plan.degree == 1:
            v = cuts("table", z=v.z, t=v.t, **keep())
            v = cuts("table.out", z=v.z, t=v.t, **keep())
            q = z_floor(plan.q_bits)
        else:
            zz = z_floor(plan.q_z_bits)
            drop = plan.q_z_bits + h_bits - plan.q_bits
            v = cuts("q.pp", **_named("q", partial_products(zz, v.h), drop), z=v.z, t=v.t, **keep())
            prod = sum_partial_products(_products(v, "q"), len(zz) + len(h))
            q = z_floor(plan.q_bits) + prod[drop:]
            q = q[:plan.q_bits - a + 1]  # Q < 2**(1 - a)
            v = cuts("q", q=q, t=v.t, **keep())
            q = v.q

        # y = T + floor(T_t Q): in [0.6, 1.7), G fraction bits.
        t_t = v.t[G - plan.t_bits:]
        drop = plan.t_bits + plan.q_bits - G
        v = cuts("tq.pp", **_named("tq", partial_products(t_t, q), drop), t=v.t, **keep())
        prod = sum_partial_products(_products(v, "tq"), len(t_t) + len(q))
        v = cuts("tq", tq=prod[drop:], t=v.t, **keep())
        y = cuts.wire("y", (v.t + v.tq)[:G + 1])
        top = y[G]
        # The significand under y's leading one, and the denormalising shift of its place
        # (the rest of the exponent is picked after the register, as FloatMul does).
        v = cuts("y", frac=Mux(top, y[:G], Cat(C(0, 1), y[:G - 1])), top=top,
                 right=Mux(top, v.exp_hi.right, v.exp_lo.right), **keep())
        exp = Signal(exp_hi.shape(), name="exponent_picked")
        m.d.comb += exp.right.eq(v.right)
        for field in ("room", "below", "cap"):
            m.d.comb += getattr(exp, field).eq(Mux(v.top, getattr(v.exp_hi, field), getattr(v.exp_lo, field)))
        return round_pack(cuts, fmt, sign=C(0, 1), exp=exp, sig=Cat(v.frac, C(1, 1)), sticky=v.nonzero,
                          is_nan=v.is_nan, is_inf=v.is_inf, is_zero=v.is_zero, invalid=v.invalid,
                          subnormals=self.subnormals)


def _step_width(plan, name: str) -> int:
    """Bits of the Horner value ``name`` computes (its bound from the plan)."""
    for step_name, (_, _, _, largest) in zip(
            ["w" if plan.degree - 1 - n == 1 else f"h{plan.degree - 1 - n}" for n in range(len(plan.steps))],
            plan.steps):
        if step_name == name:
            return max(1, largest.bit_length())
    raise KeyError(name)


def _named(name: str, products: dict, drop: int) -> dict:
    """:func:`~.mul.partial_products` of one product whose bits below ``drop`` are dropped,
    trimmed by :func:`_trim` and renamed ``<name>_pp<k>_<weight>`` so several share a boundary."""
    terms = _trim([(value, int(key.rpartition("_")[2])) for key, value in products.items()], drop)
    return {f"{name}_pp{k}_{weight}": value for k, (value, weight) in enumerate(terms)}


def _products(v, name: str) -> SimpleNamespace:
    """The partial products of ``name`` from a boundary's namespace, as
    :func:`~.mul.sum_partial_products` reads them."""
    prefix = f"{name}_"
    return SimpleNamespace(**{key[len(prefix):]: value for key, value in vars(v).items()
                              if key.startswith(prefix)})
