"""Floating-point division ``a / b``: a radix-2 digit recurrence, pipelined or iterative.

The recurrence machinery here (:class:`RecurrenceUnit`, the register planner, the one-adder
add/subtract and the carry-free zero test) is shared with :mod:`.sqrt`, the other
digit-recurrence unit.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from amaranth.hdl import C, Cat, Mux, Signal, Value
from amaranth.lib.wiring import In, Out

from .format import FloatFormat
from .round import ROUND_BOUNDARIES, FloatUnit, leading_zeros, round_pack, unpack

__all__ = ["FloatDiv", "RecurrenceUnit", "StagePlans", "add_sub", "sum_is_zero",
           "lut_delay", "carry_delay", "tree_levels", "shifter_delay", "round_delays"]

# ---------------------------------------------------------------------------------------------
# Delay model for placing registers: ECP5 figures (ns, clock-to-output and routing included)
# for a LUT level and a carry chain, fitted to nextpnr's critical paths of binary32 units on
# an LFE5U-85F: a recurrence step ~5 ns whatever its width (routing dominates), two ~10 ns;
# the rounding increment to the overflow compare ~10 ns; a 32-bit leading-zero count with the
# compares after it ~13 ns, as are the exponent compare and the denormalising shift after it.
# Only the relative sizes matter for balancing the stages; the absolute ones set the default
# stage counts.
LUT_NS = 1.2
BUDGET_NS = 9.5  # a 100 MHz clock less a margin for placement


def lut_delay(levels: float) -> float:
    return LUT_NS * levels


def carry_delay(width: int) -> float:
    """An adder or comparator of ``width`` bits: entry LUT, carry chain, exit routing."""
    return 2.4 + 0.03 * width


def tree_levels(width: int, fan_in: int = 2) -> int:
    """Levels of a ``fan_in``-input tree over ``width`` bits (a reduction, a priority count)."""
    return max(1, math.ceil(math.log(max(width, 2), fan_in)))


def shifter_delay(width: int) -> float:
    """A barrel shifter over ``width`` bits (a 4:1 multiplexer takes a LUT and a PFUMX)."""
    return lut_delay(0.7 * tree_levels(width))


def round_delays(fmt: FloatFormat, width: int, denormalise: bool = True,
                 leading_one: bool = False) -> list[float]:
    """Logic before each of :data:`ROUND_BOUNDARIES` and ``"out"``, for a ``width``-bit
    significand (``leading_one``: its top bit is a constant one, no leading zeros to count).

    After the structure of :func:`~.round.round_pack`: the exponent's room above emin, then
    beside each other the denormalising right shift with its lost bits, and the leading-zero
    count capped at emin with the biased exponent; the normalising left shift; the rounding.
    """
    p, room = fmt.precision, carry_delay(fmt.exp_bits + 3) + lut_delay(2)
    count = lut_delay(0 if leading_one else tree_levels(width) + 1)
    shift_left = shifter_delay(width) + count + carry_delay(fmt.exp_bits + 3)
    if denormalise:
        right = p + 1
        shift_right = shifter_delay(width + right) + lut_delay(tree_levels(right, 4))
    else:
        shift_right = 0.0
    return [
        room + max(shift_left, shift_right),
        shifter_delay(width),
        # round-up decision, increment, exponent add, overflow compare
        lut_delay(1) + carry_delay(p + 1) + 2 * carry_delay(fmt.exp_bits + 2),
        # special-result selects (before "out")
        lut_delay(2),
    ]


class StagePlans(Mapping):
    """Register placements for every stage count of a straight-line datapath.

    ``segments`` lists ``(boundary, delay)`` in datapath order, ``delay`` being the logic
    between the previous boundary and this one. The last boundary (``"out"``) and those in
    ``forced`` always get a register, except in the all-combinational plan of zero stages
    (allowed when nothing else is forced). For a stage count, the longest stage (by the delay
    model) is made as short as possible: registers go as late as that bound allows, and any
    left over split the stages where that shortens them most. ``offset`` is added to the
    register count and boundaries in ``hidden`` are left out of the plans: an iterative core
    is a forced boundary whose registers the unit makes itself, ``offset + 1`` cycles of
    latency.

    A mapping ``stages -> tuple of boundaries`` (computed on demand), as
    :class:`~.round.FloatUnit` expects of ``PLANS``.
    """

    def __init__(self, segments, forced=(), offset=0, hidden=()):
        self._names = [name for name, _ in segments]
        self._hidden = set(hidden)
        self._delays = [float(d) for _, d in segments]
        self._forced = set(forced) | {self._names[-1]}
        self._offset = offset
        self._prefix = [0.0]
        for d in self._delays:
            self._prefix.append(self._prefix[-1] + d)
        n = len(self._names)
        # Without a forced register inside, zero stages (all combinational) is allowed too.
        self._lo = 0 if len(self._forced) == 1 and not offset else len(self._forced) + offset
        self._hi = n + offset
        self._bounds = sorted({self._prefix[j + 1] - self._prefix[i]
                               for i in range(n + 1) for j in range(i, n)})

    def __len__(self):
        return self._hi - self._lo + 1

    def __iter__(self):
        return iter(range(self._lo, self._hi + 1))

    def __contains__(self, stages):
        return isinstance(stages, int) and not isinstance(stages, bool) \
            and self._lo <= stages <= self._hi

    def _cost(self, i, j):
        """Delay of the stage between chosen boundaries ``i`` and ``j`` (``i = -1``: input)."""
        return self._prefix[j + 1] - self._prefix[i + 1]

    def _latest(self, bound):
        """Boundary indices chosen as late as ``bound`` allows (a longer single segment gets a
        stage of its own)."""
        chosen, last = [], -1
        for j, name in enumerate(self._names):
            if j + 1 < len(self._names) and name not in self._forced \
                    and self._cost(last, j + 1) <= bound:
                continue
            chosen.append(j)
            last = j
        return chosen

    def __getitem__(self, stages):
        if stages not in self:
            raise KeyError(stages)
        count = stages - self._offset
        if count == 0:
            return ()
        # The smallest bound met with at most ``count`` registers, by bisection.
        lo, hi = 0, len(self._bounds) - 1
        while lo < hi:
            mid = (lo + hi) // 2
            if len(self._latest(self._bounds[mid])) <= count:
                hi = mid
            else:
                lo = mid + 1
        chosen = self._latest(self._bounds[lo])
        while len(chosen) < count:
            chosen = self._split_longest(chosen)
        return tuple(self._names[j] for j in chosen if self._names[j] not in self._hidden)

    def _split_longest(self, chosen):
        best = None
        for k, j in enumerate(chosen):
            i = chosen[k - 1] if k else -1
            for c in range(i + 1, j):
                key = (max(self._cost(i, c), self._cost(c, j)) - self._cost(i, j), c)
                if best is None or key < best[0]:
                    best = (key, c)
        return sorted(chosen + [best[1]])

    def default(self, budget=BUDGET_NS):
        """The fewest stages that meet ``budget``, or the delay of a forced boundary's own
        segment if longer (an iterative core's cycle sets the clock: the logic around it
        need not be faster). A single segment over the bound gets a stage of its own."""
        index = {name: j for j, name in enumerate(self._names)}
        bound = max([budget] + [self._cost(index[n] - 1, index[n]) for n in self._forced])
        return len(self._latest(bound)) + self._offset


# ---------------------------------------------------------------------------------------------
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
    sticky bit and the shared rounding stage (``"round.*"``, ``"out"``).

    ``cycles_per_op == 1``: the steps are unrolled, each followed by a boundary
    ``"<op>.<i>"``. ``stages`` (0 to the number of boundaries) says how many registers, and
    :class:`StagePlans` where: the longest stage by the delay model is made as short as it can
    be. One operation per clock.

    ``cycles_per_op == K > 1``: one block of ``ceil(iterations / K)`` steps, its state in
    registers (``core_*``), runs K cycles per operation: the first cycle takes the operation
    through a multiplexer in front of the block, the K-th cycle's results are read by the
    stages after it while the next operation may enter. ``i_ready`` is high when the last
    accepted operation is K or more cycles back (it never depends on ``i_valid``); the stages
    before the core never stall, as operations enter them K cycles apart. ``stages`` is the
    whole latency, the K core cycles plus the registers before and after the core (at least
    ``"out"``): from ``K + 1`` to ``K + 8``. Without a ``stages``, the registers around the
    core are as few as keep their logic no slower than the block of steps (or 100 MHz): from
    ``K + 2`` for a long block to ``K + 7`` for one step a cycle. The clock is that of the
    block: about 5 ns a step on an ECP5.

    A subclass sets ``OP`` and writes :meth:`iterations`, :meth:`operands` (decode, up to
    ``"normalise"``), :meth:`first` (the state after the first step, sized for the core
    when iterative), :meth:`step`, :meth:`finish` (the raw result for
    :func:`~.round.round_pack`) and the delay estimates.
    """

    OP = ""

    def __init__(self, fmt, subnormals, stages, cycles_per_op, ports):
        fmt = FloatFormat.parse(fmt) if isinstance(fmt, str) else fmt
        if not isinstance(fmt, FloatFormat):
            raise ValueError(f"fmt must be a FloatFormat or a format name, not {fmt!r}")
        steps = self.iterations(fmt)
        if isinstance(cycles_per_op, bool) or not isinstance(cycles_per_op, int) \
                or not 1 <= cycles_per_op <= steps:
            raise ValueError(f"cycles_per_op must be an integer from 1 to {steps} for "
                             f"{self.OP} in {fmt.name}, not {cycles_per_op!r}")
        self._cycles = cycles_per_op
        self._per_cycle = -(-steps // cycles_per_op)
        self._steps = steps if cycles_per_op == 1 else self._per_cycle * cycles_per_op
        self.PLANS = self._plans(fmt, subnormals == "ieee")
        self.DEFAULT_STAGES = self.PLANS.default()
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

    def _plans(self, fmt, ieee):
        op = self.OP
        pre = [("in", 0.0)] + self.pre_delays(fmt, ieee)
        # (The sticky bit's zero test runs beside the rounding stage's exponent logic.)
        post = list(zip(ROUND_BOUNDARIES + ("out",),
                        round_delays(fmt, self._steps + 1, self.denormalise(fmt, ieee), True)))
        if self._cycles == 1:
            body = [(f"{op}.{i}", self.step_delay(fmt, i)) for i in range(1, self._steps + 1)]
            return StagePlans(pre + body + post)
        # The block of full-width steps after its input multiplexer.
        core = self._per_cycle * self.step_delay(fmt, self._steps) + lut_delay(1)
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
        if self._cycles == 1:
            for i in range(1, self._steps + 1):
                state = vars(cuts(f"{self.OP}.{i}", **self.step(state, fixed=False)))
        else:
            state, cuts.valid = self._core(m, state, cuts.valid)
        # (On wires: the rounding stage reads them many times over.)
        raw = {k: cuts.wire(f"{self.OP}_{k}", v) for k, v in self.finish(state).items()}
        return round_pack(cuts, fmt, subnormals=self.subnormals,
                          denormalise=self.denormalise(fmt, self.subnormals == "ieee"), **raw)

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

    def denormalise(self, fmt, ieee) -> bool:
        """Whether a result can be below ``2**emin`` (the rounding stage then shifts right)."""
        return True


class FloatDiv(RecurrenceUnit):
    """``a / b`` rounded to nearest even, by radix-2 non-restoring division.

    Subnormal operands are normalised first (leading-zero count and shift), so both
    significands ``ma, mb`` are in ``[2**(p-1), 2**p)`` (``p = fmt.precision``). The first
    step is ``r = ma - mb``; each of the ``p + 2`` further steps is one adder,
    ``r = 2r - mb`` after a nonnegative remainder and ``2r + mb`` after a negative one, and
    gives the quotient bit ``r >= 0`` (the bits of restoring division, without its
    multiplexer after the adder). The ``p + 3`` quotient bits hold the significand, a round
    bit and one more; the remainder (``r``, or ``r + mb`` when negative) is zero or not, the
    sticky bit, tested without a carry chain. The quotient, normalised by its first bit, goes
    through the shared rounding stage (:func:`~.round.round_pack`) with a constant leading
    one, so subnormal, overflowing and exact quotients all round as IEEE 754 says.

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
        logic fits 100 MHz on an ECP5 by the delay model: a register after every recurrence
        step (33 for binary32, 19 for binary16). Iterative: ``cycles_per_op + 1`` to
        ``cycles_per_op + 8``; ``None`` from ``cycles_per_op + 2`` (binary32, K <= 6) to
        ``+ 7`` (K = ``p + 2``). See :class:`RecurrenceUnit`.
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
    ``cycles_per_op``. On an LFE5U-85F a recurrence step takes about 5 ns, so the default
    keeps the recurrence above 100 MHz; the rounding stage sets the unit's Fmax.
    """

    OP = "div"

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
        return carry_delay(fmt.precision + 1) + lut_delay(1)  # and the exponent select

    def step_delay(self, fmt, i):
        # The remainder's sign fans out to every bit's add/subtract select.
        return lut_delay(2) + carry_delay(fmt.precision + 2)

    def operands(self, cuts, v):
        fmt, ieee = self.fmt, self.subnormals == "ieee"
        a = unpack(fmt, v.i_a, self.subnormals)
        b = unpack(fmt, v.i_b, self.subnormals)
        both_zero, both_inf = a.is_zero & b.is_zero, a.is_inf & b.is_inf
        is_nan = a.is_nan | b.is_nan | both_zero | both_inf
        v = cuts("unpack", a_sig=a.sig, b_sig=b.sig, exp=a.exp - b.exp,
                 a_zeros=leading_zeros(cuts, a.sig, "a_lz") if ieee else C(0, 1),
                 b_zeros=leading_zeros(cuts, b.sig, "b_lz") if ieee else C(0, 1),
                 sign=a.sign ^ b.sign, is_nan=is_nan,
                 is_inf=~is_nan & (a.is_inf | b.is_zero), is_zero=~is_nan & (a.is_zero | b.is_inf),
                 invalid=a.is_snan | b.is_snan | both_zero | both_inf,
                 divbyzero=b.is_zero & ~(a.is_zero | a.is_inf | a.is_nan))
        p = fmt.precision
        specials = {k: getattr(v, k) for k in ("sign", "is_nan", "is_inf", "is_zero", "invalid",
                                                  "divbyzero")}
        exp = v.exp - v.a_zeros + v.b_zeros
        return cuts("normalise", ma=(v.a_sig << v.a_zeros)[:p], mb=(v.b_sig << v.b_zeros)[:p],
                    exp=exp, exp_less=exp - 1, **specials)

    def first(self, cuts, v):
        p = self.fmt.precision
        r = (v.ma - v.mb)[:p + 1].as_signed()  # in (-mb, mb): p + 1 bits
        # The iterative core shifts the later bits in: its quotient register is full width.
        q = ~r[-1] if self._cycles == 1 else Cat(~r[-1], C(0, self._steps))
        # The first bit is the quotient's integer bit: with ma < mb it is zero, and the
        # quotient will be shifted up by one (see finish), which the exponent takes now.
        return dict(r=r, q=q, d=v.mb, exp=Mux(r[-1], v.exp_less, v.exp), sign=v.sign,
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
        # The quotient ma * 2**steps / mb is in (2**(steps-1), 2**(steps+1)); normalised here,
        # where its top bit is known from the first step, so that the rounding stage gets a
        # constant leading one and its leading-zero count folds away in synthesis. (The zero
        # shifted in at the bottom has the sticky bit below it, as the rounding stage allows:
        # there are three bits under the rounding point.)
        q = s["q"]
        sig = Cat(Mux(q[-1], q[:-1], Cat(C(0, 1), q[:-2])), C(1, 1))
        return dict(sign=s["sign"], exp=s["exp"], sig=sig, sticky=sticky,
                    is_nan=s["is_nan"], is_inf=s["is_inf"], is_zero=s["is_zero"],
                    invalid=s["invalid"], divbyzero=s["divbyzero"])
