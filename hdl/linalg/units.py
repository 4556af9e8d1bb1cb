"""The engine's executing units: a processing element (an FMA interleaving ``Lf``
accumulations) and the shared divider, square root and move unit.

Both take an instruction from their :class:`~.sequencer.InstructionStream` the cycle before
it starts (``fire``), read their operands at the start cycle ``t`` on the memory ports the
instruction names (data at ``t + R``, :data:`~.microcode.LANE_READ_LATENCY`) and write the result
at ``t + R + L`` after the last issue: the scheduler's machine, cycle for cycle.
"""

from __future__ import annotations

from amaranth.hdl import Cat, Const, Module, Mux, Signal
from amaranth.lib import data, wiring
from amaranth.lib.wiring import In, Out

from kfgen.hdl.arith.float.div import FloatDiv
from kfgen.hdl.arith.float.exp import FloatExp
from kfgen.hdl.arith.float.fma import FloatFMA
from kfgen.hdl.arith.float.sqrt import FloatSqrt
from kfgen.hdl.arith.float.trig import FloatAtan2, FloatCos, FloatSin

from . import isa
from .banks import ReadLane, WriteLane, addr_layout
from .isa import CHECK_BITS, Check
from .microcode import LANE_READ_LATENCY

__all__ = ["ProcessingElement", "SharedUnit", "faults", "HARDWARE", "WORDS"]


def faults(fmt, y, check):
    """``(pivot, nan)`` of result ``y`` under check code ``check`` (a :class:`~.isa.Check`), as
    :func:`kfgen.sim.linalg.exec.run` decides them: a pivot is bad when NaN, negative
    (``-0`` included) or ``+0``; a checked result when NaN or infinite."""
    w = fmt.width
    special, nan = _special(fmt, y)
    pivot = (check == int(Check.PIVOT)) & (nan | y[w - 1] | (y[:w - 1] == 0))
    return pivot, (check == int(Check.FINITE)) & special


def _special(fmt, y):
    """``(NaN or infinity, NaN)`` of the word ``y``."""
    w, f = fmt.width, fmt.frac_bits
    special = y[f:w - 1] == (1 << fmt.exp_bits) - 1
    return special, special & (y[:f] != 0)


def _advance(g, m, addr, stride):
    """``addr + stride`` in (bank, row) form: the bank wraps at most once."""
    out = Signal(addr_layout(g))
    s = Signal(g.bank_bits + 1)
    wrap = s >= g.banks
    m.d.comb += [
        s.eq(addr.bank + stride.bank),
        out.bank.eq(Mux(wrap, s - g.banks, s)),
        out.row.eq(addr.row + stride.row + wrap),
    ]
    return out


def _writeback_layout(g, mirror=True):
    addr = addr_layout(g)
    return data.StructLayout({"en": 1, "dst": addr, "pd0": 1, "check": CHECK_BITS,
                              **({"mirror": 1, "dst1": addr, "pd1": 1} if mirror else {})})


def _delay(m, wb, cycles, name):
    """``wb`` (a layout whose first field is ``en``) delayed by ``cycles`` registers: ``en``
    in registers that a reset (a halt) clears, the rest without reset, so that it maps to
    shift-register LUTs."""
    en, rest = wb.en, wb.as_value()[1:]
    for i in range(cycles):
        nxt_en = Signal(name=f"{name}_en_{i + 1}")
        nxt_rest = Signal(len(rest), name=f"{name}_{i + 1}", reset_less=True)
        m.d.sync += [nxt_en.eq(en), nxt_rest.eq(rest)]
        en, rest = nxt_en, nxt_rest
    out = Signal(wb.shape(), name=name)
    m.d.comb += out.eq(Cat(en, rest))
    return out


class _Unit(wiring.Component):
    """What every executing unit offers the engine: read and write lanes, the status."""

    def __init__(self, fmt, geometry, layout, reads):
        self._fmt, self._g = fmt, geometry
        self._mirror = "mirror" in layout.members
        super().__init__({
            "fire": In(1), "ins": In(layout),
            "rd": Out(ReadLane(geometry, fmt.width)).array(reads),
            "wr": Out(WriteLane(geometry, fmt.width)).array(2 if self._mirror else 1),
            "pivot": Out(1), "nan": Out(1), "flags": Out(5),
        })

    def _writeback(self):
        return Signal(_writeback_layout(self._g, self._mirror))

    def _write(self, m, wb, y):
        """Write ``y`` where ``wb`` (:func:`_writeback_layout`) says, and check it. Every
        write lane carries ``y``: the memory muxes one copy (``BankedMemory``'s groups)."""
        pivot, nan = faults(self._fmt, y, wb.check)
        m.d.comb += [
            self.wr[0].en.eq(wb.en), self.wr[0].addr.eq(wb.dst), self.wr[0].port.eq(wb.pd0),
            self.wr[0].data.eq(y),
            self.pivot.eq(wb.en & pivot), self.nan.eq(wb.en & nan),
        ]
        if self._mirror:
            m.d.comb += [self.wr[1].en.eq(wb.en & wb.mirror), self.wr[1].addr.eq(wb.dst1),
                         self.wr[1].port.eq(wb.pd1), self.wr[1].data.eq(y)]


class PeFMA(FloatFMA):
    """The PE's FMA: the default's stages moved one place towards the input, so that a
    register stands at its input (fed by the addend select and the operands' sign flip) and
    none at its output (the result feeds the addend select and the write lane's register,
    both registered). The same latency, bit for bit the same results; any other stage count
    is the FMA's own plan."""

    PLANS = {**FloatFMA.PLANS,
             FloatFMA.DEFAULT_STAGES: ("in", *FloatFMA.PLANS[FloatFMA.DEFAULT_STAGES][:-1])}


class ProcessingElement(_Unit):
    """A fused multiply-add whose output feeds its addend: ``Lf`` accumulations interleave,
    one term a cycle (the chapter's PE, without a FIFO: the scheduler spaces an
    accumulation's terms exactly ``Lf`` apart).

    The accumulations in flight live in a ring of ``Lf`` slots, one per phase of the cycle
    modulo ``Lf``; the slot at the head issues (reads ``a_k``, ``b_k``; advances both address
    generators) and goes to the tail. A new segment takes the head the cycle it starts (its
    phase is free: the scheduler placed it there). The addend of a first term is ``init``,
    read on the third lane the cycle before the start (and held a cycle), or ``-0``; any
    other term's is the FMA's output of the same phase, ``Lf`` cycles after the previous
    term. A term's operands reach the FMA ``R`` cycles after its issue.

    Parameters
    ----------
    fmt : FloatFormat
    geometry : microcode.Geometry
    layout : data.StructLayout
        The stream's instruction (:func:`~.sequencer.instruction_layout` of ``"fma"``).

    Members
    -------
    fire : In(1); ins : In(layout)
        From the PE's stream, the cycle before the instruction starts.
    rd : Out(ReadLane).array(3)
        ``a``, ``b`` and ``init``.
    wr : Out(WriteLane).array(2)
        The result and its mirror.
    pivot, nan : Out(1)
        A checked result fails, the cycle it is written.
    flags : Out(5)
        The FMA's IEEE flags of every term, the cycle it leaves the FMA.

    Latency: a result is written ``R + Lf`` cycles after its last term issues.
    """

    def __init__(self, fmt, geometry, layout, stages=None):
        self._stages = stages
        super().__init__(fmt, geometry, layout, 3)

    def elaborate(self, platform):
        m = Module()
        fmt, g = self._fmt, self._g
        m.submodules.fma = fma = PeFMA(fmt, stages=self._stages)
        lf = fma.latency
        ins = self.ins
        addr = addr_layout(g)
        wb_fields = ("dst", "pd0", "check", *(("mirror", "dst1", "pd1") if self._mirror else ()))
        slot = data.StructLayout({
            "active": 1, "rem": ins.count.shape(), "a": addr, "sa": addr, "b": addr, "sb": addr,
            "pa": 1, "pb": 1, "neg": 1, "first": 1, "init_en": 1, "last": 1,
            **{k: ins.shape().members[k] for k in wb_fields}})
        # the cycle before the start: the init read, and the new segment registered
        new = Signal(slot)
        m.d.comb += [self.rd[2].en.eq(self.fire & ins.first & ins.init_en),
                     self.rd[2].addr.eq(ins.init), self.rd[2].port.eq(ins.pi)]
        m.d.sync += new.active.eq(self.fire)
        with m.If(self.fire):
            m.d.sync += [new.rem.eq(ins.count)]
            m.d.sync += [getattr(new, k).eq(getattr(ins, k)) for k in
                         ("a", "sa", "b", "sb", "pa", "pb", "neg", "first", "init_en", "last",
                          *wb_fields)]
        # issue: the head of the ring, or the new segment
        ring = [Signal(slot, name=f"ring{i}") for i in range(lf)]
        head = Signal(slot)
        m.d.comb += head.eq(Mux(new.active, new, ring[0]))
        nxt = Signal(slot)
        m.d.comb += [
            nxt.eq(head),
            nxt.active.eq(head.active & (head.rem != 1)),
            nxt.rem.eq(head.rem - 1),
            nxt.first.eq(0),
            nxt.a.eq(_advance(g, m, head.a, head.sa)),
            nxt.b.eq(_advance(g, m, head.b, head.sb)),
        ]
        m.d.sync += [ring[i].eq(ring[i + 1]) for i in range(lf - 1)]
        m.d.sync += ring[-1].eq(nxt)
        m.d.comb += [
            self.rd[0].en.eq(head.active), self.rd[0].addr.eq(head.a), self.rd[0].port.eq(head.pa),
            self.rd[1].en.eq(head.active), self.rd[1].addr.eq(head.b), self.rd[1].port.eq(head.pb),
        ]
        # operands arrive R cycles after the issue: into the FMA
        issue = Signal(data.StructLayout({"en": 1, "neg": 1, "first": 1, "init_en": 1}))
        m.d.comb += [issue.en.eq(head.active), issue.neg.eq(head.neg), issue.first.eq(head.first),
                     issue.init_en.eq(head.init_en)]
        arrive = _delay(m, issue, LANE_READ_LATENCY, "arrive")
        valid, neg, first, init_en = arrive.en, arrive.neg, arrive.first, arrive.init_en
        init = Signal(fmt.width)
        m.d.sync += init.eq(self.rd[2].data)  # read the cycle before the first issue: held one
        wb0 = self._writeback()
        m.d.comb += [wb0.en.eq(head.active & head.last & (head.rem == 1)),
                     *(getattr(wb0, k).eq(getattr(head, k)) for k in wb_fields)]
        wb = _delay(m, wb0, LANE_READ_LATENCY, "operands")
        sign = Const(fmt.sign_mask, fmt.width)
        m.d.comb += [
            fma.i_valid.eq(valid),
            fma.i_a.eq(self.rd[0].data ^ Mux(neg, sign, 0)),
            fma.i_b.eq(self.rd[1].data),
            fma.i_c.eq(Mux(first, Mux(init_en, init, sign), fma.o_y)),
            self.flags.eq(Mux(fma.o_valid, fma.o_flags, 0)),
        ]
        self._write(m, _delay(m, wb, lf, "wb"), fma.o_y)
        return m


def max_word(fmt, a, b):
    """``max(a, b)`` of two ``fmt`` words as :class:`~.program.Max` defines it (the larger
    value, ``+0`` above ``-0``, ``a`` when equal, the canonical NaN for a NaN operand), and
    whether an operand was a NaN: sign-magnitude words compared as integers whose negative
    half is reversed."""
    w = fmt.width

    def key(x):  # monotonic in the value: negatives' magnitudes inverted, positives above
        return Mux(x[w - 1], ~x, x | Const(fmt.sign_mask, w))

    nan = _special(fmt, a)[1] | _special(fmt, b)[1]
    y = Mux(nan, fmt.canonical_nan, Mux(key(b)[:w] > key(a)[:w], b, a))
    return y, nan


def copysign_word(fmt, a, b):
    """``copysign(a, b)`` of two ``fmt`` words as :class:`~.program.CopySign` defines it:
    ``a``'s bits with ``b``'s sign bit (IEEE 754 ``copySign``, a bit operation: no flags)."""
    w = fmt.width
    return Cat(a[:w - 1], b[w - 1])


#: The arithmetic shared units' hardware, by :data:`~.isa.UNITS` name: ``(fmt, stages,
#: cycles_per_op) -> float unit`` (a component with ``i_valid``, ``i_a``[, ``i_b``],
#: ``o_valid``, ``o_y``, ``o_flags``, ``latency``).
HARDWARE = {
    "div": lambda fmt, stages, cycles_per_op: FloatDiv(fmt, stages=stages, cycles_per_op=cycles_per_op),
    "sqrt": lambda fmt, stages, cycles_per_op: FloatSqrt(fmt, stages=stages, cycles_per_op=cycles_per_op),
    "exp": lambda fmt, stages, cycles_per_op: FloatExp(fmt, stages=stages),
    "sin": lambda fmt, stages, cycles_per_op: FloatSin(fmt, stages=stages),
    "cos": lambda fmt, stages, cycles_per_op: FloatCos(fmt, stages=stages),
    "atan2": lambda fmt, stages, cycles_per_op: FloatAtan2(fmt, stages=stages),
}

#: The shared units without a pipeline (a move, a comparison), by :data:`~.isa.UNITS` name:
#: ``(fmt, *operand words) -> (result, nan or None)``, an Amaranth expression.
WORDS = {
    "copy": lambda fmt, a: (a, None),
    "max": max_word,
    "copysign": lambda fmt, a, b: (copysign_word(fmt, a, b), None),
}


class SharedUnit(_Unit):
    """The divider (``a / b``), the square root (``sqrt(a)``), the exponential (``exp(a)``),
    the move unit (``a``) or the comparator (``max(a, b)``): one issue every
    ``cycles_per_op`` cycles, operands read at the start ``t``, the result written at
    ``t + R + register + L`` (``L = 0`` for a move and a maximum).

    Parameters
    ----------
    kind : "div", "sqrt", "exp", "copy", "max", "copysign" or a trig unit
    fmt, geometry, layout, stages
        As :class:`ProcessingElement`; ``stages`` the unit's latency (``None``: its default).
    cycles_per_op : int
        The divider's or square root's initiation interval (1: pipelined; more: iterative,
        issued no more often, as the scheduler guarantees).
    register : int
        Registers (:data:`~.schedule.UNIT_REGISTER`) between the operands' arrival and an
        arithmetic unit's input, or behind a move's or maximum's result.

    Members
    -------
    As :class:`ProcessingElement`, with ``rd`` of two lanes (``a``, ``b``) for the divider and
    the comparator, one otherwise.
    """

    def __init__(self, kind, fmt, geometry, layout, stages=None, cycles_per_op=1, register=1):
        shared = [name for name in isa.UNITS if name in HARDWARE or name in WORDS]
        if kind not in shared:
            raise ValueError(f"kind must be {', '.join(shared[:-1])} or {shared[-1]}, not {kind!r}")
        self._unit = isa.UNITS[kind]
        self._kind, self._stages, self._per_op, self._reg = kind, stages, cycles_per_op, register
        super().__init__(fmt, geometry, layout, len(self._unit.operands))

    def _registered(self, m, wb, words, name):
        """``wb`` and ``words`` behind the unit's ``register`` registers (the words without
        reset: only ``wb.en`` says whether they mean anything)."""
        wb = _delay(m, wb, self._reg, f"{name}_wb")
        for i in range(self._reg):
            regs = [Signal.like(w, name=f"{name}{k}_{i + 1}", reset_less=True) for k, w in enumerate(words)]
            m.d.sync += [r.eq(w) for r, w in zip(regs, words)]
            words = regs
        return wb, words

    def elaborate(self, platform):
        m = Module()
        fmt, g, ins = self._fmt, self._g, self.ins
        new = Signal(ins.shape())
        new_en = Signal()
        m.d.sync += new_en.eq(self.fire)
        with m.If(self.fire):
            m.d.sync += new.eq(ins)
        for i, lane in enumerate(self.rd):
            m.d.comb += [lane.en.eq(new_en), lane.addr.eq(new.a if i == 0 else new.b),
                         lane.port.eq(new.pa if i == 0 else new.pb)]
        wb0 = self._writeback()
        m.d.comb += [wb0.en.eq(new_en), wb0.dst.eq(new.dst), wb0.pd0.eq(new.pd0), wb0.check.eq(new.check)]
        if self._mirror:
            m.d.comb += [wb0.mirror.eq(new.mirror), wb0.dst1.eq(new.dst1), wb0.pd1.eq(new.pd1)]
        wb = _delay(m, wb0, LANE_READ_LATENCY, "operands")  # the operands arrive
        operands = [lane.data for lane in self.rd]
        if self._kind in WORDS:  # a move or a comparison, in the result's register
            y, nan = WORDS[self._kind](fmt, *operands)
            if nan is None:
                wb, (y,) = self._registered(m, wb, [y], "result")
            else:
                wb, (y, nv) = self._registered(m, wb, [y, wb.en & nan], "result")
                m.d.comb += self.flags.eq(Mux(nv, 0b10000, 0))  # NV, as a comparison
            self._write(m, wb, y)
            return m
        unit = HARDWARE[self._kind](fmt, self._stages, self._per_op)
        m.submodules.unit = unit
        wb, operands = self._registered(m, wb, operands, "operand")
        m.d.comb += [unit.i_valid.eq(wb.en), unit.i_a.eq(operands[0])]
        if "b" in self._unit.operands:
            m.d.comb += unit.i_b.eq(operands[1])
        m.d.comb += self.flags.eq(Mux(unit.o_valid, unit.o_flags, 0))
        self._write(m, _delay(m, wb, unit.latency, "wb"), unit.o_y)
        return m
