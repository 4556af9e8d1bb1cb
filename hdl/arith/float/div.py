"""Floating-point division ``a / b``: a radix-2 digit recurrence, pipelined or iterative.

The recurrence machinery here (:class:`RecurrenceUnit`, the one-adder add/subtract and the
carry-free zero test) is shared with :mod:`.sqrt`, the other digit-recurrence unit; the
registers are placed by the delay model of :mod:`.timing`.
"""

from __future__ import annotations

from amaranth.hdl import C, Cat, Mux, Signal, Value
from amaranth.lib.wiring import In, Out

from .format import FloatFormat
from .round import (ROUND_BOUNDARIES, FloatUnit, as_format, leading_zeros, prepare_exponent,
                    round_pack, unpack)
from .timing import (StagePlans, carry_delay, lut_delay, prepare_delay, round_delays,
                     shifter_delay, tree_levels)

__all__ = ["FloatDiv", "RecurrenceUnit", "add_sub", "sum_is_zero"]


def add_sub(x, y, sub):
    """``x - y`` if ``sub`` else ``x + y`` in one adder (``y`` inverted, carry in ``sub``).

    ``x`` signed or unsigned, ``y`` unsigned; the signed result is one bit wider than both.
    """
    x, y, sub = Value.cast(x), Value.cast(y), Value.cast(sub)
    w = max(len(x), len(y)) + 1
    xe = Cat(x, (x[-1] if x.shape().signed else C(0, 1)).replicate(w - len(x)))
    ye = Cat(y, C(0, w - len(y))) ^ sub.replicate(w)
    # A one below x meets the carry in below y: their sum carries ``sub`` into bit 0.
    return (Cat(C(1, 1), xe) + Cat(sub, ye))[1:w + 1].as_signed()


def sum_is_zero(a, b, width):
    """Whether ``a + b == 0`` modulo ``2**width``, without a carry chain.

    The sum is zero exactly when every bit's carry in is ``a ^ b`` and every carry out is
    ``a | b``; so ``a ^ b`` must equal ``(a | b) << 1`` bit for bit.
    """
    a, b = Value.cast(a)[:width], Value.cast(b)[:width]
    return (a ^ b) == Cat(C(0, 1), (a | b)[:width - 1])


class RecurrenceUnit(FloatUnit):
    """A digit-recurrence unit (:class:`FloatDiv`, :class:`~.sqrt.FloatSqrt`).

    The datapath: input boundary ``"in"``; operand decode and leading-zero count
    (``"unpack"``); the normalising shift (``"normalise"``); the recurrence's first step
    (``"<op>.0"``); ``iterations`` identical steps, one result bit each; then the remainder's
    sticky bit and the shared rounding stage (``"round.*"``, ``"out"``). The result's
    exponent (``exp`` in the state) is final after the first step, so its side of the rounding
    stage (:func:`~.round.prepare_exponent`) is computed during the recurrence and registered:
    the stages after the recurrence start from the denormalising shift.

    ``cycles_per_op == 1``: the steps are unrolled, each followed by a boundary
    ``"<op>.<i>"``; the exponent is prepared beside the last two. ``stages`` (0 to the number
    of boundaries) says how many registers, and :class:`~.timing.StagePlans` where: the
    longest stage by the delay model of :mod:`.timing` is made as short as it can be. One
    operation per clock.

    ``cycles_per_op == K > 1``: one block of ``ceil(iterations / K)`` steps, its state in
    registers (``core_*``), runs K cycles per operation: the first cycle takes the operation
    through a multiplexer in front of the block, the K-th cycle's results are read by the
    stages after it while the next operation may enter. ``i_ready`` is high when the last
    accepted operation is K or more cycles back (it never depends on ``i_valid``); the stages
    before the core never stall, as operations enter them K cycles apart. ``stages`` is the
    whole latency, the K core cycles plus the registers before and after the core (at least
    ``"out"``): from ``K + 1`` to ``K + 8``. The exponent stays in its core register for the K
    cycles, so the prepared one is registered beside the core without adding a cycle. Without
    a ``stages``, the registers around the core are as few as keep their logic no slower than
    the block of steps (or 100 MHz): from ``K + 2`` for a long block to ``K + 6`` for one step
    a cycle (``K + 7`` in binary64 division). The clock is that of the block: about 5 ns a
    step on an ECP5, so 100 MHz takes at most two steps a cycle.

    A subclass sets ``OP`` and writes :meth:`iterations`, :meth:`operands` (decode, up to
    ``"normalise"``), :meth:`first` (the state after the first step, sized for the core
    when iterative), :meth:`step`, :meth:`finish` (the raw result for
    :func:`~.round.round_pack`) and the delay estimates.
    """

    OP = ""
    #: State fields the steps shift left, dropping the top bit: the iterative core feeds them
    #: back unnamed, as no step reads the top bit of the value fed back.
    SHIFTED: tuple[str, ...] = ()

    def __init__(self, fmt, subnormals, stages, cycles_per_op, ports):
        fmt = as_format(fmt)
        steps = self.iterations(fmt)
        if isinstance(cycles_per_op, bool) or not isinstance(cycles_per_op, int) \
                or not 1 <= cycles_per_op <= steps:
            raise ValueError(f"cycles_per_op must be an integer from 1 to {steps} for "
                             f"{self.OP} in {fmt.name}, not {cycles_per_op!r}")
        self._cycles = cycles_per_op
        self._per_cycle = -(-steps // cycles_per_op)
        self._steps = steps if cycles_per_op == 1 else self._per_cycle * cycles_per_op
        extra = {"i_ready": Out(1)} if cycles_per_op > 1 else {}
        super().__init__(fmt, subnormals, stages, lambda f: {**ports(f), **extra})

    # -- parameters ---------------------------------------------------------------------------
    @classmethod
    def iterations(cls, fmt: FloatFormat) -> int:
        """Recurrence steps after the first (each gives one result bit)."""
        raise NotImplementedError

    @property
    def cycles_per_op(self) -> int:
        return self._cycles

    @property
    def initiation_interval(self) -> int:
        return self._cycles

    def stage_plans(self, fmt, subnormals):
        plans = self._plans(fmt, subnormals == "ieee")
        return plans, plans.default()

    def _plans(self, fmt, ieee):
        op = self.OP
        pre = [("in", 0.0)] + self.pre_delays(fmt, ieee)
        shift, *rest = round_delays(fmt, self._steps + 1, self.denormalise(fmt, ieee),
                                    leading_one=True, prepared=True)
        # The remainder's zero test runs beside the denormalising shift; its bit joins the lost
        # ones at the end.
        post = list(zip(ROUND_BOUNDARIES + ("out",), [max(shift, self.sticky_delay(fmt))] + rest))
        if self._cycles == 1:
            body = [self.step_delay(fmt, i) for i in range(1, self._steps + 1)]
            # The exponent is prepared beside the last two steps (see datapath).
            body[-2] = max(body[-2], carry_delay(fmt.exp_bits + 3))
            body[-1] = max(body[-1], prepare_delay(fmt, from_room=True))
            return StagePlans(pre + [(f"{op}.{i + 1}", d) for i, d in enumerate(body)] + post)
        # The block of full-width steps after its input multiplexer (and beside it the
        # prepared exponent's register).
        core = max(self._per_cycle * self.step_delay(fmt, self._steps) + lut_delay(1),
                   prepare_delay(fmt))
        return StagePlans(pre + [("core", core)] + post, forced=("core",),
                          offset=self._cycles - 1, hidden=("core",))

    # -- datapath -----------------------------------------------------------------------------
    def datapath(self, m, cuts):
        fmt = self.fmt
        if self._cycles > 1:
            cuts.valid = self._accept(m)
        v = cuts("in", **{name: getattr(self, name) for name in self.signature.members
                          if name.startswith("i_") and name not in ("i_valid", "i_ready")})
        state = self.first(cuts, self.operands(cuts, v))
        state = vars(cuts(f"{self.OP}.0", **state))
        width, denormalise = self._steps + 1, self.denormalise(fmt, self.subnormals == "ieee")
        if self._cycles == 1:
            # The exponent, set by the first step, is prepared for the rounding stage
            # (prepare_exponent) beside the last two steps, an add and then the compares: the
            # stages after the recurrence start from the denormalising shift.
            for i in range(1, self._steps + 1):
                state = self.step(state, fixed=False)
                if i == self._steps - 1:
                    state["exp"] = cuts.wire("room", state["exp"] - fmt.emin)
                elif i == self._steps:
                    state["exp"] = prepare_exponent(cuts, fmt, None, width, denormalise,
                                                    room=state["exp"])
                state = vars(cuts(f"{self.OP}.{i}", **state))
        else:
            state, cuts.valid = self._core(m, state, cuts.valid)
            # The exponent is held in the core for all its cycles, so the prepared one,
            # registered beside it, is ready by the last: no latency added.
            prepared = prepare_exponent(cuts, fmt, state["exp"], width, denormalise)
            held = Signal(prepared.shape(), name="core_exponent", reset_less=True)
            m.d.sync += held.eq(prepared)
            state = {**state, "exp": held}
        # (On wires: the rounding stage reads them many times over.)
        raw = {k: cuts.wire(f"{self.OP}_{k}", v) for k, v in self.finish(state).items()}
        return round_pack(cuts, fmt, subnormals=self.subnormals, denormalise=denormalise, **raw)

    def _accept(self, m):
        """``i_ready`` and the accepted-operation strobe: one operation per K cycles."""
        wait = Signal(range(self._cycles), name="accept_wait")
        accept = self.i_valid & self.i_ready
        m.d.comb += self.i_ready.eq(wait == 0)
        with m.If(accept):
            m.d.sync += wait.eq(self._cycles - 1)
        with m.Elif(wait != 0):
            m.d.sync += wait.eq(wait - 1)
        return accept

    def _core(self, m, state, start):
        """Run ``step`` ``per_cycle`` times a cycle for ``cycles_per_op`` cycles.

        ``state`` (sized for the whole recurrence by :meth:`first`) is taken when ``start`` is
        high; the registers hold the final state, and the returned valid is high, exactly
        ``cycles_per_op`` cycles later. Operations start at least that far apart (the
        ``i_ready`` handshake), so the last cycle's registers are read before they are reused.
        """
        regs = {k: Signal(Value.cast(v).shape(), name=f"core_{k}", reset_less=True)
                for k, v in state.items()}
        cur = {}
        for k in state:
            if k in self.SHIFTED:
                cur[k] = Mux(start, state[k], regs[k])
                continue
            cur[k] = Signal.like(regs[k], name=f"core_{k}_in")
            m.d.comb += cur[k].eq(Mux(start, state[k], regs[k]))
        for i in range(self._per_cycle):
            prev, cur = cur, {}
            for k, v in self.step(prev, fixed=True).items():
                if v is prev[k]:  # held for the whole operation (the divisor, the exponent...)
                    cur[k] = v
                else:  # back to the register's width between the steps
                    cur[k] = Signal.like(regs[k], name=f"core_{k}_{i + 1}")
                    m.d.comb += cur[k].eq(v)
        m.d.sync += [regs[k].eq(cur[k]) for k in regs]
        left = Signal(range(self._cycles + 1), name="core_left")
        with m.If(start):
            m.d.sync += left.eq(self._cycles)
        with m.Elif(left != 0):
            m.d.sync += left.eq(left - 1)
        return regs, left == 1

    # -- per-unit hooks -----------------------------------------------------------------------
    def pre_delays(self, fmt, ieee):
        """Logic before ``"unpack"``, ``"normalise"`` and ``"<op>.0"``."""
        p = fmt.precision
        # (The leading-zero count waits for the hidden bit, two LUTs from the exponent field.)
        return [("unpack", lut_delay(2 + (tree_levels(p) if ieee else 0))),
                ("normalise", (shifter_delay(p) if ieee else 0)
                 + carry_delay(fmt.exp_bits + 2)),
                (f"{self.OP}.0", self.first_delay(fmt))]

    def sticky_delay(self, fmt):
        """The remainder's zero test after the last step: a LUT a bit, their AND, the select by
        the remainder's sign."""
        return lut_delay(2 + tree_levels(self._steps + 1, 4))

    def denormalise(self, fmt, ieee) -> bool:
        """Whether a result can be below ``2**emin`` (the rounding stage then shifts right)."""
        return True


class FloatDiv(RecurrenceUnit):
    """``a / b`` rounded to nearest even, by radix-2 non-restoring division.

    Subnormal operands are normalised first (leading-zero count and shift), so both
    significands ``ma, mb`` are in ``[2**(p-1), 2**p)`` (``p = fmt.precision``). The first
    step gives the quotient's leading one: ``r = ma - mb``, or ``2 ma - mb`` a place lower
    when ``ma < mb``. Each of the ``p + 2`` further steps is one adder, ``r = 2r - mb``
    after a nonnegative remainder and ``2r + mb`` after a negative one, and gives the
    quotient bit ``r >= 0`` (the bits of restoring division, without its multiplexer after
    the adder). The ``p + 3`` quotient bits hold the significand, a round bit and one more;
    the remainder (``r``, or ``r + mb`` when negative) is zero or not, the sticky bit, tested
    without a carry chain. The quotient goes through the shared rounding stage
    (:func:`~.round.round_pack`) with a constant leading one, so subnormal, overflowing and
    exact quotients all round as IEEE 754 says.

    Special cases: a NaN operand gives the canonical NaN (NV if signalling); ``0/0`` and
    ``inf/inf`` the canonical NaN with NV; finite nonzero ``/ 0`` an infinity with DZ;
    ``inf / finite`` (zero included) an infinity, ``finite / inf`` and ``0 / nonzero`` a zero,
    all of sign ``sign(a) ^ sign(b)`` and without a flag.

    Parameters
    ----------
    fmt : FloatFormat or str
        Operand and result format (default ``binary32``).
    subnormals : "ieee" or "ftz"
    stages : int or None
        Register stages, the latency in cycles. Pipelined: 0 to ``p + 10`` (34 for
        binary32), registers placed to balance the stages. ``None`` is the fewest stages whose
        logic fits 100 MHz on an ECP5 by the delay model of :mod:`.timing`: a register after
        every recurrence step (32 for binary32, 17 for binary16, 62 for binary64; one or two
        fewer with ``ftz``). Iterative: ``cycles_per_op + 1`` to ``cycles_per_op + 8``;
        ``None`` from ``cycles_per_op + 2`` (binary32, K <= 8) to ``+ 6`` (K = ``p + 2``).
        See :class:`RecurrenceUnit`.
    cycles_per_op : int
        1 for one operation per clock (the recurrence unrolled), or K from 2 to ``p + 2``: one
        block of ``ceil((p + 2) / K)`` steps reused for K cycles, one operation accepted every
        K cycles.

    Members
    -------
    i_valid : In(1)
    i_ready : Out(1), only when ``cycles_per_op > 1``
        High when an operation is accepted this cycle (``i_valid & i_ready``); it does not
        depend on ``i_valid``.
    i_a, i_b : In(fmt.width)
    o_valid : Out(1)
        The accepted ``i_valid`` delayed by ``latency`` cycles.
    o_y : Out(fmt.width)
    o_flags : Out(5)
        NX, UF, OF, DZ, NV from bit 0.

    Raises
    ------
    ValueError
        On a bad format, subnormal mode, stage count or ``cycles_per_op``.

    Latency ``stages`` cycles from the accepting cycle to ``o_valid``; initiation interval
    ``cycles_per_op``. On an LFE5U-85F (nextpnr, median of three placer seeds) the default
    binary32 pipeline runs at about 125 MHz, binary16 at 140 and binary64 at 99; the
    rounding stage's denormalising shift and its lost bits set the Fmax, the recurrence
    steps (about 5 ns each) are faster. Iterative, the block of steps sets the clock: about
    100 MHz with two steps a cycle (binary32 K = 13), 128 MHz with one (K = 26).
    """

    OP = "div"
    SHIFTED = ("q",)

    def __init__(self, fmt: FloatFormat | str = FloatFormat(), *, subnormals: str = "ieee",
                 stages: int | None = None, cycles_per_op: int = 1):
        super().__init__(fmt, subnormals, stages, cycles_per_op, lambda f: {
            "i_valid": In(1), "i_a": In(f.width), "i_b": In(f.width),
            "o_valid": Out(1), "o_y": Out(f.width), "o_flags": Out(5),
        })

    @classmethod
    def iterations(cls, fmt):
        return fmt.precision + 2

    def first_delay(self, fmt):
        # The two subtracts side by side, then the selects by the first one's sign.
        return carry_delay(fmt.precision + 1) + lut_delay(1)

    def step_delay(self, fmt, i):
        # The remainder's sign fans out to every bit's add/subtract select.
        return lut_delay(2) + carry_delay(fmt.precision + 2)

    def operands(self, cuts, v):
        fmt, ieee = self.fmt, self.subnormals == "ieee"
        a = unpack(fmt, v.i_a, self.subnormals)
        b = unpack(fmt, v.i_b, self.subnormals)
        both_zero, both_inf = a.is_zero & b.is_zero, a.is_inf & b.is_inf
        is_nan = a.is_nan | b.is_nan | both_zero | both_inf
        # (The biases cancel: ea - eb is the difference of the exponent fields.)
        exp = cuts.wire("div_exp_diff", a.biased - b.biased)
        v = cuts("unpack", a_sig=a.sig, b_sig=b.sig, exp=exp, exp_less=exp - 1,
                 a_zeros=leading_zeros(cuts, a.sig, "a_lz") if ieee else C(0, 1),
                 b_zeros=leading_zeros(cuts, b.sig, "b_lz") if ieee else C(0, 1),
                 sign=a.sign ^ b.sign, is_nan=is_nan,
                 is_inf=~is_nan & (a.is_inf | b.is_zero), is_zero=~is_nan & (a.is_zero | b.is_inf),
                 invalid=a.is_snan | b.is_snan | both_zero | both_inf,
                 divbyzero=b.is_zero & ~(a.is_zero | a.is_inf | a.is_nan))
        p = fmt.precision
        specials = {k: getattr(v, k) for k in ("sign", "is_nan", "is_inf", "is_zero", "invalid",
                                                  "divbyzero")}
        # Both candidate exponents (see first) side by side, each a single add after the
        # leading-zero counts' difference.
        zeros = cuts.wire("div_zeros", v.b_zeros - v.a_zeros)
        return cuts("normalise", ma=(v.a_sig << v.a_zeros)[:p], mb=(v.b_sig << v.b_zeros)[:p],
                    exp=v.exp + zeros, exp_less=v.exp_less + zeros, **specials)

    def first(self, cuts, v):
        p = self.fmt.precision
        # The quotient's leading one: ma / mb is in [1, 2), or 2 ma / mb is, a place lower,
        # when ma < mb (which the exponent takes now). Either way r is in [0, mb): p + 1 bits.
        less = cuts.wire("div_less", (v.ma - v.mb)[p])
        r = Mux(less, Cat(C(0, 1), v.ma) - v.mb, v.ma - v.mb)[:p + 1].as_signed()
        # The quotient bits after the leading one, none yet. (The iterative core shifts them
        # in: its quotient register is full width.)
        q = C(0, 0 if self._cycles == 1 else self._steps)
        return dict(r=r, q=q, d=v.mb, exp=Mux(less, v.exp_less, v.exp), sign=v.sign,
                    is_nan=v.is_nan, is_inf=v.is_inf, is_zero=v.is_zero, invalid=v.invalid,
                    divbyzero=v.divbyzero)

    def step(self, s, fixed):
        r, d = s["r"], s["d"]
        neg = r[-1]
        # r stays in [-mb, mb): p + 1 bits.
        r = add_sub(Cat(C(0, 1), r).as_signed(), d, ~neg)[:len(r)].as_signed()
        return {**s, "r": r, "q": Cat(~r[-1], s["q"])}

    def finish(self, s):
        r, d, p = s["r"], s["d"], self.fmt.precision
        # The remainder is r, or r + mb (in [0, mb), so p bits) when r is negative.
        sticky = Mux(r[-1], ~sum_is_zero(r, d, p), r.any())
        # The quotient's leading one is a constant for the rounding stage: its leading-zero
        # count and left shift fold away in synthesis.
        sig = Cat(s["q"], C(1, 1))
        return dict(sign=s["sign"], exp=s["exp"], sig=sig, sticky=sticky,
                    is_nan=s["is_nan"], is_inf=s["is_inf"], is_zero=s["is_zero"],
                    invalid=s["invalid"], divbyzero=s["divbyzero"])
