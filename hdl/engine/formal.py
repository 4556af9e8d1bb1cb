"""Formal properties of an engine core's register and memory map (``kfgen.gen.formal`` runs them).

The harness is the core as built (:class:`~kfgen.hdl.bus.axi4.Axi4Slave` in front of the
core's :class:`~kfgen.hdl.engine.core.Backend` and its map) with the engine replaced by
:class:`EngineModel`, which may do anything the engine's contract allows: a step ends after
any number of cycles with any fault bits, and while busy the step leaves the bus a read slot
whenever it likes (at least one in four cycles). So the properties hold for every program.

:class:`MapProperties` checks the map's rules where the front end meets the back end (the word
bus), written from the map's declaration (:class:`~kfgen.hdl.engine.regmap.RegisterMap`), not
from the back end's decoder:

- a read of a register or a memory region answers OKAY, of anything else SLVERR; register reads
  never wait;
- a write answers SLVERR, and changes nothing, on a hole, a read-only register or region, a
  buffer word while busy, a buffer word with a partial strobe, and ``CTRL`` with ``start`` while
  busy; the engine's memory is written exactly by the buffer writes that answer OKAY with
  every strobe set (the element and the value the bus carried);
- ``CTRL.start`` (write-1-pulse) starts the named step exactly when written with strobe 0,
  without ``reset``, while idle, naming a step; ``CTRL.reset`` halts exactly when written with
  strobe 0;
- STATUS, IRQ_ENABLE, CTRL.step and ID read what a model of the map says: each event bit set by
  its event (``done`` at a step's end, ``err_pivot``/``err_nan`` with it, ``err_busy`` by a
  refused start), cleared only by a write of 1 under strobe 0 (W1C) or by ``CTRL.reset``;
  ``busy`` the engine's; ``irq`` the OR of the enabled events, one cycle later.
"""

from __future__ import annotations

from amaranth.asserts import AnySeq
from amaranth.hdl import Assume, Cat, Const, Cover, Elaboratable, Fragment, Module, Mux, ResetSignal, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from ..bus.axi4 import Axi4Slave, axi4_slave_members
from ..bus.formal import Axi4Properties, StreamProperties, TransferCount, bounded_run, check_if, drive_any
from ..linalg.banks import BUS_READ_LATENCY
from .core import Backend, stream_members
from .regmap import BUS_ID_WIDTH

__all__ = ["EngineModel", "MapProperties", "EngineMapHarness", "EngineStreamHarness"]

_EVENTS = ("done", "err_pivot", "err_nan", "err_busy")


class EngineModel(wiring.Component):
    """Every behaviour the :class:`~kfgen.hdl.linalg.engine.Engine`'s contract allows, as seen
    from its control and memory ports: ``start`` while idle makes it busy the next cycle and
    clears the fault bits; a busy step ends after any number of cycles (``done`` high one
    cycle with ``busy`` low, the fault bits as they please); ``halt`` makes it idle without
    ``done``. Reads are granted (``mem_rok``) when idle and, while busy, at least once in
    ``slot`` cycles; their data are anything. Its memory writes are the harness's to check.
    With ``max_busy``, a step ends within that many cycles (what a bounded-liveness proof
    needs: the real steps end after :meth:`~kfgen.hdl.linalg.engine.Engine.cycles`)."""

    def __init__(self, step_names, size: int, width: int, slot: int = 4, max_busy: int | None = None):
        self._names = tuple(step_names)
        self._slot = slot
        self._max_busy = max_busy  # a step ends within this many cycles (for liveness)
        super().__init__({
            "start": In(1), "step": In(range(max(2, len(self._names)))), "halt": In(1),
            "busy": Out(1), "done": Out(1), "err_pivot": Out(1), "err_nan": Out(1), "flags": Out(5),
            "mem_raddr": In(range(size)), "mem_rdata": Out(width), "mem_rok": Out(1),
            "mem_waddr": In(range(size)), "mem_wdata": In(width), "mem_we": In(1),
        })

    @property
    def step_names(self):
        return self._names

    def elaborate(self, platform):
        m = Module()
        finish, rok = AnySeq(1), Signal()
        m.d.comb += [rok.eq(AnySeq(1)), self.mem_rok.eq(~self.busy | rok),
                     self.mem_rdata.eq(AnySeq(len(self.mem_rdata))), self.flags.eq(AnySeq(5))]
        bounded_run(m, self.busy & ~rok, self._slot - 1, "engine_read_slot")
        if self._max_busy is not None:
            bounded_run(m, self.busy, self._max_busy, "engine_step_length")
        m.d.sync += self.done.eq(0)
        with m.If(self.halt):
            m.d.sync += self.busy.eq(0)
        with m.Elif(self.start & ~self.busy):
            m.d.sync += [self.busy.eq(1), self.err_pivot.eq(0), self.err_nan.eq(0)]
        with m.Elif(self.busy & finish):
            m.d.sync += [self.busy.eq(0), self.done.eq(1), self.err_pivot.eq(AnySeq(1)),
                         self.err_nan.eq(AnySeq(1))]
        return m


class _Decode:
    """Word-address predicates from a map's declaration."""

    def __init__(self, rmap):
        self.rmap = rmap
        self.reg_words = {}
        for r in rmap.registers:
            for k in range(r.width // 32):
                self.reg_words[r.offset // 4 + k] = (r, k)
        self.buffer = rmap.buffer_base // 4

    def reg(self, word, name, k=0):
        r = self.rmap[name]
        return word == r.offset // 4 + k

    def any_reg(self, word):
        return Cat(word == w for w in self.reg_words).any()

    def memory(self, word, access=None):
        hits = [(word >= mem.offset // 4) & (word < mem.end // 4) for mem in self.rmap.memories
                if access is None or mem.access == access]
        return Cat(hits).any() if hits else Const(0)


class MapProperties(Elaboratable):
    """The map's rules (module docstring) on the word bus between ``front`` and ``back``, with
    ``engine`` the :class:`EngineModel` behind ``back``. Only for a core whose ``busy`` is the
    engine's (no stream ports, no prologue step), one bus word a buffer element."""

    GROUPS = ("rules", "model")

    def __init__(self, back: Backend, engine: EngineModel, rmap, width: int, groups=GROUPS):
        self._back, self._eng, self._map, self._width = back, engine, rmap, width
        self._groups = frozenset(groups)
        self.decode = _Decode(rmap)

    def write_refused(self, word, strb, wdata, busy):
        """SLVERR for a write beat of ``word`` with ``strb`` and ``wdata`` (the map's rules)."""
        d, rmap = self.decode, self._map
        start, reset = rmap["CTRL"].field("start"), rmap["CTRL"].field("reset")
        refused_start = strb[0] & wdata[start.lsb] & ~wdata[reset.lsb] & busy
        ok_regs = d.reg(word, "STATUS") | (d.reg(word, "IRQ_ENABLE") if "IRQ_ENABLE" in
                                           {r.name for r in rmap.registers} else Const(0))
        buffer_refused = busy | ((strb != 0) & (strb != 0xF)) | d.memory(word, "ro")
        return Mux(d.reg(word, "CTRL"), refused_start,
                   Mux(ok_regs, 0, Mux(d.memory(word), buffer_refused, 1)))

    def elaborate(self, platform):
        m = Module()
        rules, modelled = check_if("rules" in self._groups), check_if("model" in self._groups)
        bus, eng, rmap, d = self._back.bus, self._eng, self._map, self.decode
        busy = eng.busy
        ctrl, status = rmap["CTRL"], rmap["STATUS"]
        f_start, f_reset = ctrl.field("start"), ctrl.field("reset")
        f_step = next((f for f in ctrl.fields if f.name == "step"), None)
        has_irq = "IRQ_ENABLE" in {r.name for r in rmap.registers}
        wd, ws = bus.w_data, bus.w_strb
        to_ctrl = bus.w_en & d.reg(bus.w_addr, "CTRL") & ws[0]
        reset = to_ctrl & wd[f_reset.lsb]

        # ---------------------------------------------------------------- writes
        refused = self.write_refused(bus.w_addr, ws, wd, busy)
        m.d.comb += rules(~bus.w_en | (bus.w_err == refused), "w_err_as_the_map_says")
        base = self._map.buffer_base // 4
        takes = bus.w_en & d.memory(bus.w_addr, "rw") & ~busy & (ws == 0xF)
        m.d.comb += [
            rules(eng.mem_we == takes, "buffer_written_exactly_by_okay_whole_writes"),
            rules(~takes | ((eng.mem_waddr == bus.w_addr - base) & (eng.mem_wdata == wd[:self._width])),
                   "buffer_write_element_and_value"),
            rules(eng.halt == reset, "reset_exactly_under_strobe"),
        ]
        named = Const(1)
        step_value = Const(0)
        if f_step is not None:
            step_value = wd[f_step.lsb:f_step.msb + 1]
            values = [v.value for v in f_step.values]
            named = (step_value >= values[0]) & (step_value <= values[-1])
        starts = to_ctrl & wd[f_start.lsb] & ~wd[f_reset.lsb] & ~busy & named
        m.d.comb += rules((eng.start & ~eng.busy) == starts, "start_exactly_under_strobe_while_idle")
        if f_step is not None:
            m.d.comb += rules(~starts | (eng.step == step_value - f_step.values[0].value),
                               "start_names_the_step")

        # ---------------------------------------------------------------- the map's model
        lsb = {e: status.field(e).lsb for e in _EVENTS}
        now = {"done": eng.done, "err_pivot": eng.done & eng.err_pivot, "err_nan": eng.done & eng.err_nan,
               "err_busy": to_ctrl & wd[f_start.lsb] & ~wd[f_reset.lsb] & busy}
        clear = {e: bus.w_en & d.reg(bus.w_addr, "STATUS") & ws[0] & wd[lsb[e]] for e in _EVENTS}
        model = {e: Signal(name=f"model_{e}") for e in _EVENTS}
        for e in _EVENTS:
            m.d.sync += model[e].eq(~reset & (now[e] | (model[e] & ~clear[e])))
        seen = {e: model[e] | now[e] for e in _EVENTS}
        status_word = Signal(32)
        m.d.comb += status_word[status.field("busy").lsb].eq(busy)
        for e in _EVENTS:
            m.d.comb += status_word[lsb[e]].eq(seen[e])
        words = {}  # word address -> expected value in the cycle of the read's issue
        words[status.offset // 4] = status_word
        ident = sum(f.reset << f.lsb for f in rmap["ID"].fields)
        words[rmap["ID"].offset // 4] = Const(ident & 0xFFFF_FFFF, 32)
        words[rmap["ID"].offset // 4 + 1] = Const(ident >> 32, 32)
        step_model = Signal(f_step.width if f_step else 1)
        if f_step is not None:
            with m.If(to_ctrl & ~now["err_busy"]):
                m.d.sync += step_model.eq(step_value)
            ctrl_word = Signal(32)
            m.d.comb += ctrl_word[f_step.lsb:f_step.msb + 1].eq(step_model)
            words[ctrl.offset // 4] = ctrl_word
        else:
            words[ctrl.offset // 4] = Const(0, 32)
        if has_irq:
            irq_reg = rmap["IRQ_ENABLE"]
            enable = {e: Signal(name=f"model_enable_{e}") for e in _EVENTS}
            with m.If(bus.w_en & d.reg(bus.w_addr, "IRQ_ENABLE") & ws[0]):
                m.d.sync += [enable[e].eq(wd[irq_reg.field(e).lsb]) for e in _EVENTS]
            enable_word = Signal(32)
            for e in _EVENTS:
                m.d.comb += enable_word[irq_reg.field(e).lsb].eq(enable[e])
            words[irq_reg.offset // 4] = enable_word
            irq_model = Signal()
            m.d.sync += irq_model.eq(~reset & Cat(seen[e] & enable[e] for e in _EVENTS).any())
            m.d.comb += modelled(self._back.irq == irq_model, "irq_is_the_enabled_events")
            m.d.comb += Cover(self._back.irq, "cover_irq")

        # ---------------------------------------------------------------- reads
        expect_err = ~(d.any_reg(bus.r_addr) | d.memory(bus.r_addr))
        expect_word = Const(0, 32)
        is_modelled = Const(0)
        for word, value in words.items():
            expect_word = Mux(bus.r_addr == word, value, expect_word)
            is_modelled = is_modelled | (bus.r_addr == word)
        m.d.comb += rules(~bus.r_wait | ~d.any_reg(bus.r_addr), "register_reads_never_wait")
        line = [(Signal(name=f"read{i}_valid"), Signal(name=f"read{i}_err"), Signal(name=f"read{i}_known"),
                 Signal(32, name=f"read{i}_word")) for i in range(BUS_READ_LATENCY)]
        m.d.sync += [line[0][0].eq(bus.r_en), line[0][1].eq(expect_err), line[0][2].eq(is_modelled),
                     line[0][3].eq(expect_word)]
        for a, b in zip(line, line[1:]):
            m.d.sync += [x.eq(y) for x, y in zip(b, a)]
        valid, err, known, word = line[-1]
        m.d.comb += [
            rules(~valid | (bus.r_err == err), "r_err_as_the_map_says"),
            modelled(~(valid & known) | (bus.r_data == word), "registers_read_as_the_map_model_says"),
        ]
        # covers: each STATUS bit read as 1, a refused write, a start, a reset
        status_read = _read_of(m, bus, status.offset // 4)
        for e in ("busy",) + _EVENTS:
            m.d.comb += Cover(valid & status_read & bus.r_data[status.field(e).lsb], f"cover_status_{e}_read_as_1")
        m.d.comb += [Cover(bus.w_en & bus.w_err, "cover_write_refused"),
                     Cover(eng.start & ~eng.busy, "cover_step_started"),
                     Cover(eng.halt & eng.busy, "cover_step_halted")]
        return m


def _read_of(m, bus, word):
    """High when the read answered this cycle was of ``word`` (for a cover)."""
    line = [Signal(name=f"read_of_{word}_{i}") for i in range(BUS_READ_LATENCY)]
    m.d.sync += line[0].eq(bus.r_en & (bus.r_addr == word))
    for a, b in zip(line, line[1:]):
        m.d.sync += b.eq(a)
    return line[-1]


class EngineMapHarness(Elaboratable):
    """The core's AXI4 slave and back end on ``rmap`` with :class:`EngineModel` as the engine,
    the master free under the AXI4 rules; the AXI4 properties with the map's per-beat responses,
    and :class:`MapProperties`. ``slave_cls`` and ``backend_cls`` may be mutants."""

    def __init__(self, params, rmap, step_names, size, *, slave_cls=Axi4Slave, backend_cls=Backend,
                 groups=Axi4Properties.GROUPS, map_groups=MapProperties.GROUPS, state: bool = False):
        self._p, self._map, self._names, self._size = params, rmap, step_names, size
        self._slave_cls, self._backend_cls, self._groups = slave_cls, backend_cls, groups
        self._map_groups = map_groups
        self._state = state  # the slave's registers stated too (for k-induction)

    def elaborate(self, platform):
        m = Module()
        aw, width = self._map.address_width, self._p.fmt.width
        if self._p.fmt.width > 32:
            raise ValueError("the map harness takes one bus word an element (a format of at most 32 bits)")
        m.submodules.engine = eng = EngineModel(self._names, self._size, width)
        front = self._slave_cls(aw, BUS_ID_WIDTH, BUS_READ_LATENCY)
        m.submodules.front = Fragment.get(front, platform)  # elaborated here: its state is visible
        m.submodules.back = back = self._backend_cls(self._p, eng, self._map)
        wiring.connect(m, front.bus, back.bus)
        drive_any(m, front, axi4_slave_members(aw, BUS_ID_WIDTH))
        m.d.comb += Assume(ResetSignal() == 0)
        m.submodules.map = props = MapProperties(back, eng, self._map, width, self._map_groups)
        m.submodules.axi = Axi4Properties(
            front, aw, BUS_ID_WIDTH, groups=self._groups,
            read_ok=lambda w: props.decode.any_reg(w) | props.decode.memory(w),
            write_ok=lambda w, strb, wdata: ~props.write_refused(w, strb, wdata, eng.busy),
            r_bound=BUS_READ_LATENCY + 2 + 4, state=front.formal_state if self._state else None)
        return m


class EngineStreamHarness(Elaboratable):
    """An engine core with stream ports (and its prologue step, if any) on
    :class:`EngineModel`, whose steps end within ``step_bound`` cycles; the AXI4 master and
    the streams free under their rules. Checks the transmitter rule on ``m_axis``, one
    ``m_axis`` transfer per ``s_axis`` transfer (a soft reset by ``CTRL.reset`` drops the
    measurement inside, as documented), each within the stream latency plus two steps
    (a prologue and the main step), and the AXI4 slave's handshakes beside them (its other
    rules are :class:`EngineMapHarness`'s)."""

    def __init__(self, params, rmap, step_names, size, stream, prologue, *, backend_cls=Backend,
                 step_bound: int = 3, count: bool = True):
        self._count = count  # False: the transmitter rules alone
        self._p, self._map, self._names, self._size = params, rmap, step_names, size
        self._stream, self._prologue, self._cls, self._steps = stream, prologue, backend_cls, step_bound

    def elaborate(self, platform):
        m = Module()
        aw, width, spec = self._map.address_width, self._p.fmt.width, self._stream
        m.submodules.engine = eng = EngineModel(self._names, self._size, width, max_busy=self._steps)
        m.submodules.front = front = Axi4Slave(aw, BUS_ID_WIDTH, BUS_READ_LATENCY)
        m.submodules.back = back = self._cls(self._p, eng, self._map, spec, self._prologue)
        wiring.connect(m, front.bus, back.bus)
        drive_any(m, front, axi4_slave_members(aw, BUS_ID_WIDTH))
        drive_any(m, back, stream_members(spec))
        m.d.comb += Assume(ResetSignal() == 0)
        m.submodules.axi = Axi4Properties(front, aw, BUS_ID_WIDTH, groups=("handshake",))
        ctrl = self._map["CTRL"]
        bus = back.bus
        soft_reset = (bus.w_en & (bus.w_addr == ctrl.offset // 4) & bus.w_strb[0]
                      & bus.w_data[ctrl.field("reset").lsb])
        m.submodules.s_axis = StreamProperties(back.s_axis_tvalid, back.s_axis_tready, back.s_axis_tdata,
                                               "in", "s_axis")
        m.submodules.m_axis = StreamProperties(back.m_axis_tvalid, back.m_axis_tready,
                                               Cat(back.m_axis_tdata, back.m_axis_tuser), "out", "m_axis",
                                               reset=soft_reset)
        if not self._count:
            return m
        steps = 2 if self._prologue is not None else 1
        m.submodules.count = TransferCount(
            back.s_axis_tvalid & back.s_axis_tready, back.m_axis_tvalid & back.m_axis_tready,
            back.m_axis_tready, capacity=1, bound=spec.latency() + steps * (self._steps + 1) + 2,
            flush=soft_reset)
        return m
