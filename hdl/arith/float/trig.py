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
from .round import Cuts, FloatUnit, leading_zeros, round_pack, unpack
from .trig_plan import pi_floor, trig_plan

__all__ = ["FloatSin", "FloatCos", "FloatAtan2", "constant_word"]


def constant_word(fmt: FloatFormat, multiple: tuple[int, int], sign: int = 0) -> int:
    """``multiple[0] pi / 2**multiple[1]`` rounded to nearest in ``fmt`` with ``sign`` (the
    results of atan2's special operands): pi's bits from :func:`~.trig_plan.pi_floor`, and
    its infinite tail as a sticky bit."""
    from .exact import format_consts, round_magnitude
    k = format_consts(fmt)
    n = k.p + 8
    return round_magnitude(k, sign, pi_floor(n) * multiple[0], -n - multiple[1], True, False)[0]


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

    def _output(self, m, cnt, direct, direct_word, direct_flags, sign, exp, sig):
        """At the last cycle: ``direct_word``/``direct_flags`` if ``direct``, else ``sig``
        (LSB weight ``2**exp``, a nonzero inexact value) rounded; registered."""
        cuts = Cuts(m, (), C(1, 1))
        word, flags = round_pack(cuts, self._fmt, sign=sign, exp=exp + len(sig) - 1, sig=sig, sticky=C(1, 1),
                                 subnormals=self._subnormals)
        last = cnt == self.latency - 1
        m.d.sync += self.o_valid.eq(last)
        with m.If(last):
            m.d.sync += [self.o_y.eq(Mux(direct, direct_word, word)),
                         self.o_flags.eq(Mux(direct, direct_flags, flags))]


def _cordic_step(m, en, x, y, z, i, table, rotate: bool):
    """One CORDIC step (shifts by ``i``), as :func:`kfgen.sim.fpu.trig_model._cordic`."""
    up = ~z[-1] if rotate else y[-1]
    entries = tuple(table) + (0,) * ((1 << len(i)) - len(table))  # every index covered
    a = Array(C(v, len(z)) for v in entries)[i]
    xs, ys = x >> i, y >> i
    with m.If(en):
        with m.If(up):
            m.d.sync += [x.eq(x - ys), y.eq(y + xs), z.eq(z - a)]
        with m.Else():
            m.d.sync += [x.eq(x + ys), y.eq(y - xs), z.eq(z + a)]


class _FloatSinCos(_TrigUnit):
    """``sin(x)`` or ``cos(x)``, faithful (one of the two floats around the true value) over
    ``|x| < 2**range_bits`` (the whole range of binary16, bfloat16 and binary32; ``2**128``
    in wider formats), NaN with NV beyond it.

    Cycles (accepted at 0): 1 decodes and reads the window of ``2/pi`` from a ROM (a block
    RAM: one entry per exponent); 2 .. p + 1 multiply the significand by it, one bit a cycle
    (modulo 4 quarter turns); p + 2 splits off the quadrant and normalises the reduced angle;
    then ``iterations`` CORDIC rotations (beside them the product ``|f| pi/2`` of a tiny
    angle, one bit a cycle); the last rounds (the shared rounding stage) and registers.

    Results and flags: ``sin(+-0) = +-0`` and ``cos(+-0) = 1`` exactly; ``|x| < 2**-S``
    gives ``x`` (NX, UF for a subnormal) and 1 (NX); every other finite ``x`` raises NX; an
    infinity, a signalling NaN or ``|x|`` beyond the range give the canonical NaN with NV, a
    quiet NaN the canonical NaN. ``ftz``: subnormal ``x`` reads as a zero of its sign.
    """

    FN = "sin"

    @classmethod
    def cycles(cls, fmt):
        plan = trig_plan(fmt)
        return plan.p + plan.iterations + 4

    def elaborate(self, platform):
        m = Module()
        fmt, plan, sub = self._fmt, trig_plan(self._fmt), self._subnormals
        p, F, W, n = plan.p, plan.t_frac, plan.cordic_bits, plan.iterations
        cos = self.FN == "cos"
        cnt, accept = self._frame(m)
        a = Signal(fmt.width)
        with m.If(accept):
            m.d.sync += a.eq(self.i_a)

        # Cycle 1: decode; the window's address (its read data is there from cycle 2 on).
        x = unpack(fmt, a, sub)
        e = x.exp  # (emin for a subnormal: below -S in every format, so never the main path)
        one = C(fmt.bias << fmt.frac_bits, fmt.width)
        nan = C(fmt.canonical_nan, fmt.width)
        tiny = (e < -plan.tiny_bits) | x.is_sub
        out = e >= plan.range_bits
        if cos:
            special_word = Mux(x.is_nan | x.is_inf | out, nan, one)
            special_flags = Mux(x.is_nan, Mux(x.is_snan, FLAG_NV, 0), Mux(x.is_inf | out, FLAG_NV,
                                Mux(x.is_zero, 0, FLAG_NX)))
        else:
            special_word = Mux(x.is_nan | x.is_inf | out, nan, Mux(x.is_zero, Cat(C(0, fmt.width - 1), x.sign), a))
            special_flags = Mux(x.is_nan, Mux(x.is_snan, FLAG_NV, 0), Mux(x.is_inf | out, FLAG_NV,
                                Mux(x.is_zero, 0, FLAG_NX | Mux(x.is_sub, FLAG_UF, 0))))
        direct, d_word, d_flags, sign_x = Signal(), Signal(fmt.width), Signal(5), Signal()
        mbits = Signal(p)
        depth = len(plan.window)
        rom = m.submodules.window = Memory(shape=plan.acc_bits, depth=depth, init=plan.window)
        rd = rom.read_port()
        index = e - (p - 1) - plan.e_low
        m.d.comb += rd.addr.eq(Mux((index >= 0) & (index < depth), index, 0))
        with m.If(cnt == 1):
            m.d.sync += [direct.eq(x.is_nan | x.is_inf | x.is_zero | tiny | out), d_word.eq(special_word),
                         d_flags.eq(special_flags), sign_x.eq(x.sign), mbits.eq(x.sig)]

        # Cycles 2 .. p + 1: T = M * window mod 2**acc_bits, most significant bit of M first.
        acc = Signal(plan.acc_bits)
        reduce = (cnt >= 2) & (cnt < p + 2)
        with m.If(cnt == 1):
            m.d.sync += acc.eq(0)
        with m.If(reduce):
            m.d.sync += [acc.eq(Cat(C(0, 1), acc[:-1]) + Mux(mbits[-1], rd.data, 0)),
                         mbits.eq(Cat(C(0, 1), mbits[:-1]))]

        # Cycle p + 2: the quadrant and the reduced angle.
        t = acc[p:]
        kq = (t[F - 1:] + 1)[1:3]
        f = Signal(signed(F))
        m.d.comb += f.eq((t[:F] + (1 << (F - 1)))[:F] - (1 << (F - 1)))
        q = (kq + (1 if cos else 0))[:2]
        fa = Mux(f < 0, -f, f)[:F]
        sin_r = ~q[0]
        sign = q[1] ^ (0 if cos else sign_x) ^ (sin_r & f[-1])
        small = sin_r & (fa < (1 << (F - plan.tiny_bits - 1)))
        cuts = Cuts(m, (), C(1, 1))
        lz = leading_zeros(cuts, fa, "f_lz")
        top = (fa << lz)[F - plan.mul_bits:F]
        wide = W + 4
        cx, cy, cz = Signal(signed(wide)), Signal(signed(wide)), Signal(signed(wide))
        r_sign, r_small, r_sin, r_lz = Signal(), Signal(), Signal(), Signal(range(F + 1))
        mul = Signal(plan.mul_bits)
        split = cnt == p + 2
        with m.If(split):
            m.d.sync += [cx.eq(plan.inv_gain), cy.eq(0),
                         cz.eq(fa << (W - F) if W >= F else fa >> (F - W)),
                         r_sign.eq(sign), r_small.eq(small), r_sin.eq(sin_r), r_lz.eq(lz),
                         mul.eq(top), acc.eq(0)]

        # Cycles p + 3 .. p + 2 + n: the rotations; the product |f| pi/2 in the first ones.
        i = Signal(range(n + 1))
        with m.If(split):
            m.d.sync += i.eq(0)
        rotate = (cnt >= p + 3) & (cnt < p + 3 + n)
        with m.If(rotate):
            m.d.sync += i.eq(i + 1)
        _cordic_step(m, rotate, cx, cy, cz, i, plan.atan_quarter, True)
        with m.If(rotate & (i < plan.mul_bits)):
            m.d.sync += [acc.eq(Cat(C(0, 1), acc[:-1]) + Mux(mul[-1], plan.pi_half_mul, 0)),
                         mul.eq(Cat(C(0, 1), mul[:-1]))]

        # The last cycle: round r (the small angle's product) or the CORDIC's y or x.
        width = max(2 * plan.mul_bits + 1, W + 2)
        value = Mux(r_small, acc[:2 * plan.mul_bits + 1], Mux(r_sin, cy[:W + 2], cx[:W + 2]))
        exp = Mux(r_small, C(-(2 * plan.mul_bits), signed(12)) - r_lz, C(-W, signed(12)))
        self._output(m, cnt, direct, d_word, d_flags, r_sign, exp, Cat(value, C(0, width - len(value))))
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

    Cycles (accepted at 0): 1 decodes and normalises both operands; 2 aligns them to the
    larger exponent (or, when ``x > 0`` and ``|y/x| < 2**-S``, loads the division); then
    ``iterations`` vectoring CORDIC steps (beside them the restoring division, one quotient
    bit a cycle); the last rounds and registers.

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
        return trig_plan(fmt).iterations + 4

    def elaborate(self, platform):
        m = Module()
        fmt, plan, sub = self._fmt, trig_plan(self._fmt), self._subnormals
        p, W, n, S = plan.p, plan.cordic_bits, plan.iterations, plan.tiny_bits
        cnt, accept = self._frame(m)
        ay, ax = Signal(fmt.width), Signal(fmt.width)
        with m.If(accept):
            m.d.sync += [ay.eq(self.i_a), ax.eq(self.i_b)]

        # Cycle 1: classify; normalise the significands (a subnormal's leading one to the top).
        y, x = unpack(fmt, ay, sub), unpack(fmt, ax, sub)
        cuts = Cuts(m, (), C(1, 1))
        ew = max(fmt.exp_bits + 2, (p + fmt.exp_bits).bit_length() + 2)
        regs = {}
        for name, v in (("y", y), ("x", x)):
            lz = leading_zeros(cuts, v.sig, f"{name}_lz")
            regs[name] = (Signal(p, name=f"{name}_m"), Signal(signed(ew), name=f"{name}_e"))
            with m.If(cnt == 1):
                m.d.sync += [regs[name][0].eq((v.sig << lz)[:p]), regs[name][1].eq(v.exp - lz)]
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

        # Cycle 2: the division's operands, or the CORDIC's aligned vector.
        my, ey = regs["y"]
        mx, ex = regs["x"]
        d = Signal(signed(ew + 1))
        m.d.comb += d.eq(ey - ex)
        small = Signal()
        wide = W + 4
        cx, cy, cz = Signal(signed(wide)), Signal(signed(wide)), Signal(signed(wide))
        rem, quo = Signal(p + 1), Signal(plan.div_bits + 1)
        d_exp = Signal(signed(ew + 2))
        top = Mux(ey > ex, ey, ex)

        def align(mant, e):
            right = top - e  # >= 0
            v = Cat(C(0, W - p + 1), mant)  # in [1, 2) at W fraction bits
            return Mux(right > W + 1, 0, v >> right[:max(1, (W + 1).bit_length())])

        A, B = align(my, ey), align(mx, ex)
        with m.If(cnt == 2):
            m.d.sync += [small.eq(~neg_x & (d < -S)), d_exp.eq(d - plan.div_bits), rem.eq(my), quo.eq(0),
                         cx.eq(Mux(neg_x, A, B)), cy.eq(Mux(neg_x, B, A)), cz.eq(Mux(neg_x, plan.pi_half, 0))]

        # Cycles 3 .. 2 + n: vectoring; the quotient's bits in the first div_bits + 1.
        i = Signal(range(n + 1))
        with m.If(cnt == 2):
            m.d.sync += i.eq(0)
        run = (cnt >= 3) & (cnt < 3 + n)
        with m.If(run):
            m.d.sync += i.eq(i + 1)
        _cordic_step(m, run, cx, cy, cz, i, plan.atan_radians, False)
        with m.If(run & (i <= plan.div_bits)):
            fits = rem >= mx
            m.d.sync += [quo.eq(Cat(fits, quo[:-1])), rem.eq(Cat(C(0, 1), Mux(fits, rem - mx, rem)[:p]))]

        width = max(plan.div_bits + 1, W + 2)
        value = Mux(small, quo, cz[:W + 2])
        exp = Mux(small, d_exp, C(-W, signed(ew + 2)))
        self._output(m, cnt, direct, d_word, d_flags, r_sign, exp, Cat(value, C(0, width - len(value))))
        return m
