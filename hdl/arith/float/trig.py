"""Floating-point ``sin``, ``cos`` and ``atan2``, faithfully rounded: iterative units (one
operation at a time, a fixed number of cycles each) built on a shift-and-add datapath.

The arithmetic and its constants are :mod:`.trig_plan`'s (read there for the algorithms and
the error budget); :mod:`kfgen.sim.fpu.trig_model` is the golden model, bit for bit.
"""

from __future__ import annotations

from amaranth.hdl import Array, C, Cat, Module, Mux, Signal, signed
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from .format import FLAG_NV, FLAG_NX, FLAG_UF, FloatFormat
from .round import (ROUND_BOUNDARIES, ROUND_COUNT, Cuts, FloatUnit, leading_zeros, prepare_exponent,
                    round_pack, unpack)
from .trig_plan import constant_word, trig_plan

__all__ = ["FloatSin", "FloatCos", "FloatAtan2"]


class _TrigUnit(FloatUnit):
    """The frame of the three units: parameters, the cycle counter and the output register.

    ``i_ready`` is high when the unit is idle; an operation accepted at cycle 0 (``i_valid &
    i_ready``) gives ``o_valid`` at cycle ``latency``, and the next can be accepted then
    (initiation interval = latency). ``stages`` may only be ``None`` or the latency.
    """

    ARITY = 1

    @classmethod
    def cycles(cls, fmt: FloatFormat) -> int:
        raise NotImplementedError

    def __init__(self, fmt: FloatFormat | str = FloatFormat(), *, subnormals: str = "ieee",
                 stages: int | None = None):
        operands = {"i_a": None, "i_b": None} if self.ARITY == 2 else {"i_a": None}
        super().__init__(fmt, subnormals, stages, lambda f: {
            "i_valid": In(1), "i_ready": Out(1), **{k: In(f.width) for k in operands},
            "o_valid": Out(1), "o_y": Out(f.width), "o_flags": Out(5)})

    def stage_plans(self, fmt, subnormals):
        """One stage count, the latency (and a ``ValueError`` for a format the plan refuses)."""
        latency = self.cycles(fmt)
        return {latency: ("out",)}, latency

    @property
    def initiation_interval(self) -> int:
        return self.latency

    def _frame(self, m: Module):
        """The counter (0: idle; 1 .. latency - 1: working) and the accept strobe."""
        cnt = Signal(range(self.latency + 1))
        accept = self.i_valid & self.i_ready
        m.d.comb += self.i_ready.eq(cnt == 0)
        with m.If(accept):
            m.d.sync += cnt.eq(1)
        with m.Elif(cnt == self.latency - 1):
            m.d.sync += cnt.eq(0)
        with m.Elif(cnt != 0):
            m.d.sync += cnt.eq(cnt + 1)
        return cnt, accept

    def _output(self, m, cnt, pick, direct, direct_word, direct_flags, sign, exp, sig):
        """``sig`` (LSB weight ``2**exp``, a nonzero inexact value) and ``sign`` registered at
        cycle ``pick``, then rounded by the shared rounding stage with a register at each of
        its :data:`ROUND_STAGES` boundaries, or ``direct_word``/``direct_flags`` if
        ``direct``; the result registered at cycle ``latency - 1``."""
        # the exponent's side of the rounding before the pick register (off the path through
        # the leading-zero count)
        prep = prepare_exponent(Cuts(m, (), C(1, 1)), self._fmt, exp + len(sig) - 1, len(sig), marker=True)
        v_sign, v_prep, v_sig = Signal(), Signal.like(prep, name="pick_exp"), Signal(len(sig), name="pick_sig")
        with m.If(cnt == pick):
            m.d.sync += [v_sign.eq(sign), v_prep.eq(prep), v_sig.eq(sig)]
        picked = Signal(name="picked")  # the pick register holds this operation's value
        m.d.sync += picked.eq(cnt == pick)
        cuts = Cuts(m, ROUND_STAGES, picked)
        word, flags = round_pack(cuts, self._fmt, sign=v_sign, exp=v_prep, sig=v_sig,
                                 sticky=C(1, 1), subnormals=self._subnormals)
        last = cuts.valid  # through the rounding's registers: cycle latency - 1
        m.d.sync += self.o_valid.eq(last)
        with m.If(last):
            m.d.sync += [self.o_y.eq(Mux(direct, direct_word, word)),
                         self.o_flags.eq(Mux(direct, direct_flags, flags))]


#: The rounding stage's boundaries that get a register (its leading-zero count, shift, round
#: and select): cycles after the pick register before the output register.
ROUND_STAGES = (ROUND_COUNT, *ROUND_BOUNDARIES)
#: Cycles from the pick register's cycle to the output register's, both counted.
TAIL = len(ROUND_STAGES) + 2


def _cordic(m, cnt, first, n, x, y, z, table, rotate: bool):
    """``n`` CORDIC steps from cycle ``first``, two cycles each (the shifted operands and the
    table's entry registered, then the sums), as :func:`kfgen.sim.fpu.trig_model._cordic`;
    returns the step counter ``i`` and the strobe of each step's second cycle."""
    i = Signal(range(n + 1), name="cordic_i")
    phase = Signal(name="cordic_phase")
    run = (cnt >= first) & (cnt < first + 2 * n)
    with m.If(cnt == first - 1):
        m.d.sync += [i.eq(0), phase.eq(0)]
    with m.Elif(run):
        m.d.sync += phase.eq(~phase)
    entries = tuple(table) + (0,) * ((1 << len(i)) - len(table))  # every index covered
    xs, ys, a, up = Signal.like(x, name="cordic_xs"), Signal.like(y, name="cordic_ys"), Signal(len(z)), Signal()
    with m.If(run & ~phase):
        m.d.sync += [xs.eq(x >> i), ys.eq(y >> i), a.eq(Array(C(v, len(z)) for v in entries)[i]),
                     up.eq(~z[-1] if rotate else y[-1])]
    second = run & phase
    with m.If(second):
        m.d.sync += i.eq(i + 1)
        with m.If(up):
            m.d.sync += [x.eq(x - ys), y.eq(y + xs), z.eq(z - a)]
        with m.Else():
            m.d.sync += [x.eq(x + ys), y.eq(y - xs), z.eq(z + a)]
    return i, second


class _FloatSinCos(_TrigUnit):
    """``sin(x)`` or ``cos(x)``, faithful (one of the two floats around the true value) over
    ``|x| < 2**range_bits`` (the whole range of binary16, bfloat16 and binary32; ``2**128``
    in wider formats), NaN with NV beyond it.

    Cycles (accepted at 0): 1 decodes, 2 reads the window of ``2/pi`` from a ROM (a block RAM:
    one entry per exponent) and 3 registers its word; 4 .. p + 3 multiply the significand by
    it, one bit a cycle (modulo 4 quarter turns); p + 4 .. p + 7 split off the quadrant and the
    reduced angle and normalise it; then ``iterations`` CORDIC rotations, two cycles each
    (beside them the product ``|f| pi/2`` of a tiny angle, one bit a step); then the rounding
    (the shared stage, a register at each of its boundaries) and the output register
    (binary32: 140 cycles).

    Results and flags: ``sin(+-0) = +-0`` and ``cos(+-0) = 1`` exactly; ``|x| < 2**-S``
    gives ``x`` (NX, UF for a subnormal) and 1 (NX); every other finite ``x`` raises NX; an
    infinity, a signalling NaN or ``|x|`` beyond the range give the canonical NaN with NV, a
    quiet NaN the canonical NaN. ``ftz``: subnormal ``x`` reads as a zero of its sign.
    """

    FN = "sin"

    @classmethod
    def cycles(cls, fmt):
        plan = trig_plan(fmt)
        return plan.p + 8 + 2 * plan.iterations + TAIL

    def elaborate(self, platform):
        m = Module()
        fmt, plan, sub = self._fmt, trig_plan(self._fmt), self._subnormals
        p, F, W, n = plan.p, plan.t_frac, plan.cordic_bits, plan.iterations
        cos = self.FN == "cos"
        cnt, accept = self._frame(m)
        a = Signal(fmt.width)
        with m.If(accept):
            m.d.sync += a.eq(self.i_a)

        # Cycle 1: decode, registered; the window's address. Cycle 2: the special results;
        # the window's read (its word registered in cycle 3, off the block RAM's slow
        # clock-to-out).
        x = unpack(fmt, a, sub)
        depth = len(plan.window)
        index = x.exp - (p - 1) - plan.e_low
        e = Signal(signed(fmt.exp_bits + 2), name="x_exp")  # (emin for a subnormal: below -S, never the main path)
        is_nan, is_snan, is_inf, is_zero, is_sub = (Signal(name=f"x_{k}") for k in ("nan", "snan", "inf", "zero", "sub"))
        sign_x, mbits, addr = Signal(), Signal(p), Signal(range(depth), name="window_addr")
        with m.If(cnt == 1):
            m.d.sync += [e.eq(x.exp), is_nan.eq(x.is_nan), is_snan.eq(x.is_snan), is_inf.eq(x.is_inf),
                         is_zero.eq(x.is_zero), is_sub.eq(x.is_sub), sign_x.eq(x.sign), mbits.eq(x.sig),
                         addr.eq(Mux((index >= 0) & (index < depth), index, 0))]
        one = C(fmt.bias << fmt.frac_bits, fmt.width)
        nan = C(fmt.canonical_nan, fmt.width)
        tiny = (e < -plan.tiny_bits) | is_sub
        out = e >= plan.range_bits
        if cos:
            special_word = Mux(is_nan | is_inf | out, nan, one)
            special_flags = Mux(is_nan, Mux(is_snan, FLAG_NV, 0), Mux(is_inf | out, FLAG_NV,
                                Mux(is_zero, 0, FLAG_NX)))
        else:
            special_word = Mux(is_nan | is_inf | out, nan, Mux(is_zero, Cat(C(0, fmt.width - 1), sign_x), a))
            special_flags = Mux(is_nan, Mux(is_snan, FLAG_NV, 0), Mux(is_inf | out, FLAG_NV,
                                Mux(is_zero, 0, FLAG_NX | Mux(is_sub, FLAG_UF, 0))))
        direct, d_word, d_flags = Signal(), Signal(fmt.width), Signal(5)
        with m.If(cnt == 2):
            m.d.sync += [direct.eq(is_nan | is_inf | is_zero | tiny | out), d_word.eq(special_word),
                         d_flags.eq(special_flags)]
        rom = m.submodules.window = Memory(shape=plan.acc_bits, depth=depth, init=plan.window)
        rd = rom.read_port()
        m.d.comb += rd.addr.eq(addr)
        window = Signal(plan.acc_bits, name="window_word")
        m.d.sync += window.eq(rd.data)

        # Cycles 4 .. p + 3: T = M * window mod 2**acc_bits, most significant bit of M first.
        acc = Signal(plan.acc_bits)
        reduce = (cnt >= 4) & (cnt < p + 4)
        with m.If(cnt == 1):
            m.d.sync += acc.eq(0)
        with m.If(reduce):
            m.d.sync += [acc.eq(Cat(C(0, 1), acc[:-1]) + Mux(mbits[-1], window, 0)),
                         mbits.eq(Cat(C(0, 1), mbits[:-1]))]

        # Cycles p + 4 .. p + 7: the quadrant and the reduced angle f, |f|, its leading zeros,
        # |f| normalised; the rotations' start.
        t = acc[p:]
        q = ((t[F - 1:] + 1)[1:3] + (1 if cos else 0))[:2]  # the quadrant (+1 for cos)
        f = Signal(signed(F), name="f")
        fa, lz = Signal(F, name="f_abs"), Signal(range(F + 1), name="f_lz")
        sin_r, r_sign, r_small = Signal(), Signal(), Signal()
        with m.If(cnt == p + 4):
            m.d.sync += [f.eq((t[:F] + (1 << (F - 1)))[:F] - (1 << (F - 1))), sin_r.eq(~q[0]),
                         r_sign.eq(q[1] ^ (0 if cos else sign_x))]
        with m.If(cnt == p + 5):
            m.d.sync += [fa.eq(Mux(f < 0, -f, f)[:F]), r_sign.eq(r_sign ^ (sin_r & f[-1]))]
        cuts = Cuts(m, (), C(1, 1))
        with m.If(cnt == p + 6):
            m.d.sync += [lz.eq(leading_zeros(cuts, fa, "f_lz")),
                         r_small.eq(sin_r & (fa < (1 << (F - plan.tiny_bits - 1))))]
        wide = W + 4
        cx, cy, cz = Signal(signed(wide)), Signal(signed(wide)), Signal(signed(wide))
        mul = Signal(plan.mul_bits)
        with m.If(cnt == p + 7):
            m.d.sync += [cx.eq(plan.inv_gain), cy.eq(0),
                         cz.eq(fa << (W - F) if W >= F else fa >> (F - W)),
                         mul.eq((fa << lz)[F - plan.mul_bits:F]), acc.eq(0)]

        # Cycles p + 8 .. p + 7 + 2n: the rotations; the product |f| pi/2 beside the first.
        i, second = _cordic(m, cnt, p + 8, n, cx, cy, cz, plan.atan_quarter, True)
        with m.If(second & (i < plan.mul_bits)):
            m.d.sync += [acc.eq(Cat(C(0, 1), acc[:-1]) + Mux(mul[-1], plan.pi_half_mul, 0)),
                         mul.eq(Cat(C(0, 1), mul[:-1]))]

        # Then: r (the small angle's product) or the CORDIC's y or x, rounded.
        width = max(2 * plan.mul_bits + 1, W + 2)
        value = Mux(r_small, acc[:2 * plan.mul_bits + 1], Mux(sin_r, cy[:W + 2], cx[:W + 2]))
        exp = Mux(r_small, C(-(2 * plan.mul_bits), signed(12)) - lz, C(-W, signed(12)))
        self._output(m, cnt, p + 8 + 2 * n, direct, d_word, d_flags, r_sign, exp,
                     Cat(value, C(0, width - len(value))))
        return m


class FloatSin(_FloatSinCos):
    __doc__ = _FloatSinCos.__doc__
    FN = "sin"


class FloatCos(_FloatSinCos):
    __doc__ = _FloatSinCos.__doc__
    FN = "cos"


class FloatAtan2(_TrigUnit):
    """``atan2(y, x)`` (``i_a`` is ``y``, ``i_b`` is ``x``), faithful over every pair of
    floats, in ``[-pi, pi]``.

    Cycles (accepted at 0): 1 and 2 decode and normalise both operands; 3 and 4 align them to
    the larger exponent (or, when ``x > 0`` and ``|y/x| < 2**-S``, load the division); then
    ``iterations`` vectoring CORDIC steps, two cycles each (beside them the restoring
    division, one quotient bit a step); then the rounding and the output register (binary32:
    113 cycles).

    Results and flags (IEEE 754-2019 9.2): ``atan2(+-0, +0 or x > 0) = +-0``, ``atan2(+-y,
    +inf) = +-0`` (finite ``y``), exactly; ``atan2(+-0, -0 or x < 0)`` and ``atan2(+-y,
    -inf)`` are ``+-pi``, ``atan2(+-y, +-0)`` and ``atan2(+-inf, finite)`` ``+-pi/2``,
    ``atan2(+-inf, +inf)`` ``+-pi/4``, ``atan2(+-inf, -inf)`` ``+-3pi/4``, each rounded to
    nearest with NX; every other result is inexact (NX, and UF when tiny); a NaN operand
    gives the canonical NaN, with NV if either is signalling.
    """

    ARITY = 2

    @classmethod
    def cycles(cls, fmt):
        return 5 + 2 * trig_plan(fmt).iterations + TAIL

    def elaborate(self, platform):
        m = Module()
        fmt, plan, sub = self._fmt, trig_plan(self._fmt), self._subnormals
        p, W, n, S = plan.p, plan.cordic_bits, plan.iterations, plan.tiny_bits
        cnt, accept = self._frame(m)
        ay, ax = Signal(fmt.width), Signal(fmt.width)
        with m.If(accept):
            m.d.sync += [ay.eq(self.i_a), ax.eq(self.i_b)]

        # Cycles 1, 2: classify; normalise the significands (a subnormal's leading one to the
        # top): the leading zeros, then the shift.
        y, x = unpack(fmt, ay, sub), unpack(fmt, ax, sub)
        cuts = Cuts(m, (), C(1, 1))
        ew = max(fmt.exp_bits + 2, (p + fmt.exp_bits).bit_length() + 2)
        regs = {}
        for name, v in (("y", y), ("x", x)):
            lz = Signal(range(p + 1), name=f"{name}_lz")
            regs[name] = (Signal(p, name=f"{name}_m"), Signal(signed(ew), name=f"{name}_e"))
            with m.If(cnt == 1):
                m.d.sync += [lz.eq(leading_zeros(cuts, v.sig, f"{name}_lz")), regs[name][0].eq(v.sig),
                             regs[name][1].eq(v.exp)]
            with m.If(cnt == 2):
                m.d.sync += [regs[name][0].eq((regs[name][0] << lz)[:p]), regs[name][1].eq(regs[name][1] - lz)]
        sy, sx = y.sign, x.sign

        def const(multiple):
            return Mux(sy, constant_word(fmt, multiple, 1), constant_word(fmt, multiple, 0))

        signed_zero = Cat(C(0, fmt.width - 1), sy)
        pi, pi2 = const((1, 0)), const((1, 1))
        special_word = Mux(y.is_nan | x.is_nan, C(fmt.canonical_nan, fmt.width),
                       Mux(y.is_zero, Mux(~sx, signed_zero, pi),
                       Mux(y.is_inf, Mux(x.is_inf, Mux(sx, const((3, 2)), const((1, 2))), pi2),
                       Mux(x.is_zero, pi2, Mux(~sx, signed_zero, pi)))))
        nan_flags = Mux(y.is_snan | x.is_snan, FLAG_NV, 0)
        special_flags = Mux(y.is_nan | x.is_nan, nan_flags,
                            Mux((y.is_zero | x.is_inf & ~y.is_inf) & ~sx, 0, FLAG_NX))
        special = y.is_nan | x.is_nan | y.is_zero | y.is_inf | x.is_zero | x.is_inf
        direct, d_word, d_flags, r_sign, neg_x = Signal(), Signal(fmt.width), Signal(5), Signal(), Signal()
        with m.If(cnt == 1):
            m.d.sync += [direct.eq(special), d_word.eq(special_word), d_flags.eq(special_flags),
                         r_sign.eq(sy), neg_x.eq(sx)]

        # Cycles 3, 4: the exponents' difference and the shifts; the division's operands, or
        # the CORDIC's vector aligned to the larger exponent.
        my, ey = regs["y"]
        mx, ex = regs["x"]
        shift_bits = max(1, (W + 1).bit_length())
        right_y, right_x = Signal(shift_bits + 1, name="right_y"), Signal(shift_bits + 1, name="right_x")
        small = Signal()
        d_exp = Signal(signed(ew + 2))

        def capped(amount):  # top - e, or W + 2 for every shift that leaves nothing
            return Mux(amount > W + 1, W + 2, amount[:shift_bits + 1])

        with m.If(cnt == 3):
            m.d.sync += [small.eq(~neg_x & (ey - ex < -S)), d_exp.eq(ey - ex - plan.div_bits),
                         right_y.eq(capped(Mux(ey > ex, 0, ex - ey))), right_x.eq(capped(Mux(ey > ex, ey - ex, 0)))]
        wide = W + 4
        cx, cy, cz = Signal(signed(wide)), Signal(signed(wide)), Signal(signed(wide))
        rem, quo = Signal(p + 1), Signal(plan.div_bits + 1)

        def align(mant, right):  # in [1, 2) at W fraction bits, shifted right
            return Mux(right > W + 1, 0, Cat(C(0, W - p + 1), mant) >> right[:shift_bits])

        A, B = align(my, right_y), align(mx, right_x)
        with m.If(cnt == 4):
            m.d.sync += [rem.eq(my), quo.eq(0), cx.eq(Mux(neg_x, A, B)), cy.eq(Mux(neg_x, B, A)),
                         cz.eq(Mux(neg_x, plan.pi_half, 0))]

        # Cycles 5 .. 4 + 2n: vectoring; the quotient's bits beside the first div_bits + 1 steps.
        i, second = _cordic(m, cnt, 5, n, cx, cy, cz, plan.atan_radians, False)
        with m.If(second & (i <= plan.div_bits)):
            fits = rem >= mx
            m.d.sync += [quo.eq(Cat(fits, quo[:-1])), rem.eq(Cat(C(0, 1), Mux(fits, rem - mx, rem)[:p]))]

        width = max(plan.div_bits + 1, W + 2)
        value = Mux(small, quo, cz[:W + 2])
        exp = Mux(small, d_exp, C(-W, signed(ew + 2)))
        self._output(m, cnt, 5 + 2 * n, direct, d_word, d_flags, r_sign, exp, Cat(value, C(0, width - len(value))))
        return m
