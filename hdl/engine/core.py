"""An engine core: the linear-algebra engine running a core's steps, its operand memory as
the buffer of an AXI4 slave, and the control and status registers beside it (the UKF and the
IMM are two).

::

  s_axi_* ─► Axi4Slave ─► word bus ─► Backend ─┬─ ID, CTRL, STATUS, IRQ_ENABLE ─► irq
                                               └─ buffer ◄─► Engine memory port
                                                             Engine(start, step, halt, ...)

The core's register and memory map (:mod:`kfgen.hdl.engine.regmap`) gives every offset and
field position used here. Bus rules beyond the map's (documented in the map and the
generated ``TOP.md``):

- **Reads are always answered.** While busy, a buffer read waits for a cycle in which the
  step leaves its memory bank a port and writes nothing to it (the engine's ``mem_rok``;
  the R channel then simply stalls, as AXI allows) and returns the word as it is then: a
  region the step does not write (``Q``, ``R``, ``z`` in ``sig_gen``, say) reads as
  written, one it writes reads some state of the step. Register reads (``STATUS`` above
  all) never wait.
- **Writes while busy**: buffer writes answer SLVERR and change nothing; the registers stay
  writable (``CTRL.reset`` stops a step, ``STATUS`` bits clear, ``IRQ_ENABLE`` changes). A
  write of ``CTRL`` with ``start`` set while busy answers SLVERR, changes nothing and sets
  ``STATUS.err_busy``.
- **Byte strobes**: registers take bytes whose strobe is set (their fields all sit in byte 0,
  so a write without ``WSTRB[0]`` changes nothing). The buffer takes whole bus words: a beat
  with every strobe set writes, a beat with none writes nothing (OKAY), any other strobe
  answers SLVERR and writes nothing (the engine's memory has no byte enables).
- **Two-word elements** (binary64, low half first): writing an element's low half only
  stores it in a holding register; writing its high half writes the element from the high
  half and the held low half. So software writes low then high, as a burst does; reads
  return the element as stored.
- **Timing**: the step starts on the clock edge that takes the W beat writing
  ``CTRL.start = 1``; counting that edge as the first, ``STATUS.done`` reads 1 after edge
  :meth:`Ukf.cycles` (the manifest's ``cycles``) and ``irq`` rises on the next edge.
"""

from __future__ import annotations

from dataclasses import dataclass

from amaranth.hdl import Cat, Const, Module, Mux, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from ..bus.axi4 import Axi4Slave, WordBusSignature, axi4_slave_members, forward
from ..linalg.banks import BUS_READ_LATENCY
from ..linalg.engine import Engine
from .regmap import BUS_ID_WIDTH

__all__ = ["EngineCore", "Backend", "StreamSpec"]

_EVENTS = ("done", "err_pivot", "err_nan", "err_busy")


@dataclass(frozen=True)
class StreamSpec:
    """AXI4-Stream ports of an engine core, for a design without a processor.

    One ``s_axis`` transfer carries the elements written to the buffer from element address
    ``in_base`` on (``in_names`` name them, element 0 in the lowest bits), each in a field
    of ``field_bits`` (the format's width rounded up to whole bytes, the rest zero). Taking
    it, the core writes them (one a cycle), starts step ``step`` (the engine's index) and,
    when the step is done, reads the elements at ``out_addrs`` into one ``m_axis`` transfer
    (``out_names``, the same field layout), ``m_axis_tuser`` = {err_nan, err_pivot} of that
    step. ``s_axis_tready`` is low from a transfer until its result has gone out, and while
    a step started from the bus runs."""

    in_base: int
    in_names: tuple
    out_addrs: tuple
    out_names: tuple
    field_bits: int
    step: int = 0

    @property
    def in_width(self) -> int:
        return self.field_bits * len(self.in_names)

    @property
    def out_width(self) -> int:
        return self.field_bits * len(self.out_names)

    def latency(self) -> int:
        """Cycles from the edge that takes the ``s_axis`` transfer (counted) to the first
        after which ``m_axis_tvalid`` is high, less the step's own cycles: the writes, the
        start, the step's end, and the reads of the result (read latency 2)."""
        return len(self.in_names) + len(self.out_addrs) + 4

    @staticmethod
    def field_bits_of(width: int) -> int:
        return (width + 7) // 8 * 8

    def fields(self) -> dict[str, list[tuple[str, int]]]:
        """``s_axis``/``m_axis`` -> (name, lsb) of each field, element 0 in the lowest bits."""
        return {port: [(name, i * self.field_bits) for i, name in enumerate(names)]
                for port, names in (("s_axis", self.in_names), ("m_axis", self.out_names))}


@dataclass(frozen=True)
class Prologue:
    """A step that runs by itself before another when its inputs have changed.

    A start of step ``main`` (an engine step index, from the bus or the stream ports) starts
    step ``pre`` instead when a buffer write has been accepted into any of ``elements``
    (``(first element, count)`` ranges) since ``pre`` last ran to its end, and after reset
    (a soft reset too); ``pre``'s end starts ``main`` in the same cycle, so the two take
    ``cycles(pre) + cycles(main)`` from the start's W beat. STATUS.busy stays high between
    them; ``done`` (and the stream ports) see only ``main``'s end; ``pre``'s faults set
    ``err_pivot``/``err_nan`` when it ends. ``pre`` started by itself runs as any step does
    (and is then not run again before ``main``)."""

    main: int
    pre: int
    elements: tuple

    @classmethod
    def of(cls, progs) -> Prologue | None:
        """The prologue of a core's programs (their ``steps``, ``layout`` and ``prologue``:
        ``(pre, main, regions)`` by name, or ``None``), or ``None``."""
        if progs.prologue is None:
            return None
        pre, main, regions = progs.prologue
        names = list(progs.steps)
        return cls(names.index(main), names.index(pre),
                   tuple((progs.layout[r].base, progs.layout[r].size) for r in regions))


def stream_members(spec: StreamSpec) -> dict:
    """The AXI4-Stream ports of ``spec``, named as cocotbext-axi's ``AxiStreamBus.from_prefix``
    and Vivado's interface inference expect them."""
    return {"s_axis_tvalid": In(1), "s_axis_tready": Out(1), "s_axis_tdata": In(spec.in_width),
            "m_axis_tvalid": Out(1), "m_axis_tready": In(1), "m_axis_tdata": Out(spec.out_width),
            "m_axis_tuser": Out(2)}


class Backend(wiring.Component):
    """Registers and buffer of an engine core behind the word bus (:class:`WordBusSignature`),
    driving ``engine``'s control inputs and memory port.

    Parameters
    ----------
    params
        The core's parameters (``fmt`` and ``irq`` used here).
    engine : Engine
        The engine of ``params``' step programs (its memory is the buffer, from word 0).
    rmap : RegisterMap
        The core's map. ``CTRL.step`` names the engine's steps in order, with consecutive
        values from any first one; without that field the engine has one step. Every ``ro``
        memory answers writes with SLVERR.

    Members
    -------
    bus : In(WordBusSignature(address_width - 2, BUS_READ_LATENCY))
        Read latency :data:`~kfgen.hdl.linalg.banks.BUS_READ_LATENCY` (2): the buffer's word
        is registered behind the block RAM.
    irq : Out(1)
        ``(STATUS & IRQ_ENABLE) != 0`` for the event bits, a register (0 without ``irq``).
    """

    def __init__(self, params, engine: Engine, rmap, stream: StreamSpec | None = None,
                 prologue: Prologue | None = None):
        self._params, self._engine = params, engine
        self._map = rmap
        self._prologue = prologue
        self._stream = stream
        ctrl = self._map["CTRL"]
        self._f_step = next((f for f in ctrl.fields if f.name == "step"), None)
        if self._f_step is not None:
            if engine.step_names != tuple(v.name for v in self._f_step.values):
                raise ValueError("CTRL.step's values must name the engine's steps in its order")
            values = [v.value for v in self._f_step.values]
            if values != list(range(values[0], values[0] + len(values))):
                raise ValueError("CTRL.step's values must be consecutive")
        elif len(engine.step_names) != 1:
            raise ValueError("an engine of several steps needs a CTRL.step field")
        members = {"bus": In(WordBusSignature(self._map.address_width - 2, BUS_READ_LATENCY)), "irq": Out(1)}
        if stream is not None:
            members.update(stream_members(stream))
        super().__init__(members)

    def elaborate(self, platform):
        m = Module()
        bus, eng, rmap, p = self.bus, self._engine, self._map, self._params
        width = p.fmt.width
        words = rmap.memories[0].words
        base = rmap.buffer_base // 4  # buffer's first bus word; a power of two
        kb = base.bit_length() - 1
        elements = sum(mem.elements for mem in rmap.memories)
        read_only = [((mem.offset - rmap.buffer_base) // mem.element_size, mem.elements)
                     for mem in rmap.memories if mem.access == "ro"]  # (first element, elements)
        regs = {r.name: r.offset // 4 for r in rmap.registers}
        ctrl, status = rmap["CTRL"], rmap["STATUS"]
        f_start, f_reset, f_step = ctrl.field("start"), ctrl.field("reset"), self._f_step
        f_busy = status.field("busy")
        lsb = {e: status.field(e).lsb for e in _EVENTS}

        def buffer_at(addr):
            """(in the buffer, element, half) of a word address."""
            inside = addr[kb:] == 1
            index = addr[:kb]
            element = index[words - 1:] if words == 2 else index
            return inside & (element < elements), element, index[0] if words == 2 else 0

        # ------------------------------------------------------------- state
        step = Signal(f_step.width if f_step else 1)
        sticky = {e: Signal(name=f"status_{e}") for e in _EVENTS}
        enable = {e: Signal(name=f"irq_enable_{e}") for e in _EVENTS}
        # the engine as the rest sees it: with a prologue, busy from the start of pre to the
        # end of main, and done only at main's end
        pro = self._prologue
        if pro is None:
            eng_busy, eng_done, want_start, want_step = eng.busy, eng.done, eng.start, eng.step
        else:
            chained = Signal(name="prologue_chained")  # pre is running as main's prologue
            eng_busy, eng_done = eng.busy | chained, eng.done & ~chained
            # a start from the bus or the streams, before the prologue's say
            want_start, want_step = Signal(name="want_start"), Signal.like(eng.step, name="want_step")
        busy = eng_busy
        if self._stream is not None:  # a measurement in from s_axis to its result on m_axis
            streaming = Signal(name="stream_active")
            busy = eng_busy | streaming

        # ------------------------------------------------------------- writes
        w_buf, w_elem, w_half = buffer_at(bus.w_addr)
        wd, ws = bus.w_data, bus.w_strb
        byte0 = bus.w_en & ws[0]
        is_reg = {name: bus.w_addr == word for name, word in regs.items()}
        do_reset = byte0 & is_reg["CTRL"] & wd[f_reset.lsb]
        do_start = byte0 & is_reg["CTRL"] & wd[f_start.lsb] & ~do_reset
        refused_start = do_start & busy
        new_step = wd[f_step.lsb:f_step.msb + 1] if f_step else 0
        whole = ws == 0xF
        buf_err = ~w_buf | busy
        for lo_e, count in read_only:
            buf_err = buf_err | ((w_elem >= lo_e) & (w_elem < lo_e + count))
        buf_err = buf_err | ((ws != 0) & ~whole)
        reg_err = ~(is_reg["CTRL"] | is_reg["STATUS"] | is_reg.get("IRQ_ENABLE", 0)) | refused_start
        m.d.comb += bus.w_err.eq(Mux(w_buf, buf_err, reg_err))

        # buffer: the engine's write lane; two-word elements hold the low half until the high
        lo = Signal(32) if words == 2 else None
        buf_we = bus.w_en & w_buf & ~buf_err & whole
        m.d.comb += [eng.mem_waddr.eq(w_elem)]
        if words == 2:
            with m.If(buf_we & ~w_half):
                m.d.sync += lo.eq(wd)
            m.d.comb += [eng.mem_we.eq(buf_we & w_half), eng.mem_wdata.eq(Cat(lo, wd)[:width])]
        else:
            m.d.comb += [eng.mem_we.eq(buf_we), eng.mem_wdata.eq(wd[:width])]

        # control: start (the step in the same write), soft reset
        first = f_step.values[0].value if f_step else 0  # CTRL.step of the engine's step 0
        known, index = new_step < first + len(eng.step_names), new_step
        if first:
            known, index = known & (new_step >= first), new_step - first
        m.d.comb += [want_start.eq(do_start & ~busy & known), want_step.eq(index), eng.halt.eq(do_reset)]
        with m.If(byte0 & is_reg["CTRL"] & ~refused_start):
            m.d.sync += step.eq(new_step)

        # status: events set by the engine and by a refused start, cleared by w1c or reset
        now = {"done": eng_done, "err_pivot": eng.done & eng.err_pivot, "err_nan": eng.done & eng.err_nan,
               "err_busy": refused_start}
        clear = {e: byte0 & is_reg["STATUS"] & wd[lsb[e]] for e in _EVENTS}
        seen = {e: Signal(name=f"status_{e}_now") for e in _EVENTS}  # STATUS as read this cycle
        for e in _EVENTS:
            m.d.comb += seen[e].eq(sticky[e] | now[e])
            m.d.sync += sticky[e].eq(~do_reset & (now[e] | (sticky[e] & ~clear[e])))
        if "IRQ_ENABLE" in regs:
            irq_reg = rmap["IRQ_ENABLE"]
            with m.If(byte0 & is_reg["IRQ_ENABLE"]):
                m.d.sync += [enable[e].eq(wd[irq_reg.field(e).lsb]) for e in _EVENTS]
            m.d.sync += self.irq.eq(~do_reset & Cat(seen[e] & enable[e] for e in _EVENTS).any())

        # ------------------------------------------------------------- reads (latency 2)
        r_buf, r_elem, r_half = buffer_at(bus.r_addr)
        # a read waits for the memory anywhere in the buffer's window (a hole past the last
        # region waits too, then answers SLVERR): the window is a few address bits, the
        # buffer's end a comparison, and the front end's issue follows this
        m.d.comb += [eng.mem_raddr.eq(r_elem), bus.r_wait.eq((bus.r_addr[kb:] == 1) & ~eng.mem_rok)]

        def pack(bits):
            """A 32-bit word of {lsb: value}."""
            word = Signal(32)
            for at, v in bits.items():
                m.d.comb += word[at:at + len(v)].eq(v)
            return word

        id_value = sum(f.reset << f.lsb for f in rmap["ID"].fields)
        values = {
            "ID": id_value & 0xFFFF_FFFF,
            "ID_HI": id_value >> 32,
            "CTRL": pack({f_step.lsb: step} if f_step else {}),
            "STATUS": pack({f_busy.lsb: busy, **{lsb[e]: seen[e] for e in _EVENTS}}),
        }
        if "IRQ_ENABLE" in regs:
            irq_reg = rmap["IRQ_ENABLE"]
            values["IRQ_ENABLE"] = pack({irq_reg.field(e).lsb: enable[e] for e in _EVENTS})
        reg_words = {regs["ID"]: "ID", regs["ID"] + 1: "ID_HI", regs["CTRL"]: "CTRL",
                     regs["STATUS"]: "STATUS"}
        if "IRQ_ENABLE" in regs:
            reg_words[regs["IRQ_ENABLE"]] = "IRQ_ENABLE"
        reg_data, from_buf, half, err = Signal(32), Signal(), Signal(), Signal()
        with m.If(bus.r_en):
            m.d.sync += [from_buf.eq(r_buf), half.eq(r_half)]
            with m.Switch(bus.r_addr):
                for word, name in reg_words.items():
                    with m.Case(word):
                        m.d.sync += [reg_data.eq(values[name]), err.eq(0)]
                with m.Default():  # the buffer, or a hole
                    m.d.sync += [reg_data.eq(0), err.eq(~r_buf)]
        # the memory's word comes from the register behind its block RAM (latency 2); the
        # registers' word is registered once more to meet it
        elem = eng.mem_rdata
        reg_r, from_buf_r, err_r = Signal(32), Signal(), Signal()
        m.d.sync += [reg_r.eq(reg_data), from_buf_r.eq(from_buf), err_r.eq(err)]
        buf_word = elem
        if words == 2:
            half_r = Signal()
            m.d.sync += half_r.eq(half)
            buf_word = Mux(half_r, elem[32:], elem[:32])
        # (a refused read's data is the front end's to zero)
        m.d.comb += [bus.r_data.eq(Mux(from_buf_r, buf_word, reg_r)), bus.r_err.eq(err_r)]
        if self._stream is not None:  # last: its memory accesses override the bus's
            self._stream_fsm(m, streaming, do_start, do_reset, kb, (want_start, want_step, eng_busy, eng_done))
        if pro is None:
            return m
        # the prologue: pre's inputs written since it last ended (or reset) make main's start
        # pre's, and pre's end main's start
        stale = Signal(init=1, name="prologue_stale")
        running_pre = Signal(name="prologue_running")  # pre is the engine's step
        hit = Const(0, 1)
        for first_e, count in pro.elements:
            hit = hit | ((w_elem >= first_e) & (w_elem < first_e + count))
        go_pre = want_start & (want_step == pro.main) & stale
        then_main = chained & eng.done
        m.d.comb += [eng.start.eq(want_start | then_main),
                     eng.step.eq(Mux(then_main, pro.main, Mux(go_pre, pro.pre, want_step)))]
        with m.If(eng.start & ~eng.busy):
            m.d.sync += running_pre.eq(eng.step == pro.pre)
        with m.If(go_pre):
            m.d.sync += chained.eq(1)
        with m.If(then_main):
            m.d.sync += chained.eq(0)
        with m.If(eng.done & running_pre):
            m.d.sync += [stale.eq(0), running_pre.eq(0)]
        with m.If(buf_we & hit):
            m.d.sync += stale.eq(1)
        with m.If(do_reset):  # a halted pre has not ended: main does not follow, pre runs again
            m.d.sync += [stale.eq(1), chained.eq(0), running_pre.eq(0)]
        return m

    def _stream_fsm(self, m, streaming, do_start, do_reset, kb, engine):
        """The stream ports (:class:`StreamSpec`): take a transfer, write its elements, start
        the step, read the result into ``m_axis``. Its memory accesses override the bus's
        (assigned after them): the bus's buffer writes answer SLVERR while it is active
        (``busy`` includes it) and its buffer reads wait while it reads."""
        spec, eng, bus = self._stream, self._engine, self.bus
        want_start, want_step, eng_busy, eng_done = engine  # the engine as the core sees it
        width, fb = self._params.fmt.width, spec.field_bits
        k_in, k_out = len(spec.in_names), len(spec.out_addrs)
        din = Signal(spec.in_width, name="stream_din")
        dout = Signal(spec.out_width, name="stream_dout")
        user = Signal(2, name="stream_user")
        count = Signal(range(max(k_in, k_out) + 1), name="stream_count")
        got = Signal(range(k_out + 1), name="stream_got")
        arriving = Signal(BUS_READ_LATENCY, name="stream_arriving")  # a read's word in flight
        m.d.sync += arriving.eq(Cat(Const(0, 1), arriving[:-1]))
        m.d.comb += [self.m_axis_tdata.eq(dout), self.m_axis_tuser.eq(user)]
        with m.If(arriving[-1]):  # the element read two cycles ago: in at the top
            m.d.sync += [dout.eq(Cat(dout[fb:], eng.mem_rdata[:width], Const(0, fb - width))),
                         got.eq(got + 1)]
        IDLE, LOAD, START, RUN, FETCH, OUT = range(6)
        state = Signal(range(6), name="stream_state")  # (an if-chain, not an FSM: no incomplete case)
        fetch_addr = Const(0, len(eng.mem_raddr))
        for j, a in enumerate(spec.out_addrs):
            fetch_addr = Mux(count == j, a, fetch_addr)
        with m.If(state == IDLE):
            m.d.comb += self.s_axis_tready.eq(~eng_busy & ~do_start)
            with m.If(self.s_axis_tvalid & ~eng_busy & ~do_start):
                m.d.sync += [din.eq(self.s_axis_tdata), count.eq(0), streaming.eq(1), state.eq(LOAD)]
        with m.Elif(state == LOAD):  # one element a cycle, from in_base on
            m.d.comb += [eng.mem_we.eq(1), eng.mem_waddr.eq(spec.in_base + count), eng.mem_wdata.eq(din[:width])]
            m.d.sync += [din.eq(din >> fb), count.eq(count + 1)]
            with m.If(count == k_in - 1):
                m.d.sync += state.eq(START)
        with m.Elif(state == START):
            m.d.comb += [want_start.eq(~do_reset), want_step.eq(spec.step)]
            m.d.sync += state.eq(RUN)
        with m.Elif(state == RUN):
            with m.If(eng_done):
                m.d.sync += [user.eq(Cat(eng.err_pivot, eng.err_nan)), count.eq(0), got.eq(0), state.eq(FETCH)]
        with m.Elif(state == FETCH):  # one read a cycle; the words arrive two cycles later
            with m.If(count < k_out):
                m.d.comb += eng.mem_raddr.eq(fetch_addr)
                m.d.sync += [count.eq(count + 1), arriving[0].eq(1)]
            m.d.comb += bus.r_wait.eq(bus.r_addr[kb:] == 1)
            with m.If(arriving[-1] & (got == k_out - 1)):
                m.d.sync += state.eq(OUT)
        with m.Else():  # OUT
            m.d.comb += self.m_axis_tvalid.eq(1)
            with m.If(self.m_axis_tready):
                m.d.sync += [streaming.eq(0), state.eq(IDLE)]
        with m.If(do_reset):  # a soft reset ends a measurement wherever it is
            m.d.sync += [streaming.eq(0), state.eq(IDLE)]


class EngineCore(wiring.Component):
    """An engine core: the linear-algebra engine of ``schedules`` behind an AXI4 slave with
    the registers and buffer of ``rmap`` (:class:`Backend`). The UKF and the IMM are two.

    Parameters
    ----------
    params
        The core's parameters (``fmt``, ``irq`` used here).
    rmap : RegisterMap
    schedules : dict of str to Schedule
        The engine's steps, in ``CTRL.step``'s order.

    Members
    -------
    s_axi_aw*, s_axi_w*, s_axi_b*, s_axi_ar*, s_axi_r*
        AXI4 slave, 32-bit data, ``address_width``-bit addresses, 4-bit IDs.
    irq : Out(1)
        Level, active high (without it when ``params.irq`` is false).

    ``latency`` and ``initiation_interval`` are ``None``: the core runs steps, and
    :meth:`cycles` says how long each takes.
    """

    latency = None
    initiation_interval = None

    def __init__(self, params, rmap, schedules, stream: StreamSpec | None = None,
                 prologue: Prologue | None = None):
        self._params = params
        self._prologue = prologue
        self._map = rmap
        self._schedules = schedules
        self._stream = stream
        self._engine = Engine(self._schedules)
        self._members = axi4_slave_members(self._map.address_width, BUS_ID_WIDTH)
        self._stream_members = stream_members(stream) if stream is not None else {}
        super().__init__({**self._members, **({"irq": Out(1)} if params.irq else {}), **self._stream_members})

    @property
    def prologue(self) -> Prologue | None:
        """The step run before another when its inputs have changed, or ``None``."""
        return self._prologue

    @property
    def stream(self) -> StreamSpec | None:
        """The stream ports' layout, or ``None`` (no stream ports)."""
        return self._stream

    @property
    def params(self):
        return self._params

    @property
    def regmap(self):
        return self._map

    @property
    def schedules(self) -> dict:
        return dict(self._schedules)

    @property
    def program_roms(self) -> dict:
        """The engine's program ROMs as built: stream name -> (words, bits a word)
        (:attr:`~kfgen.hdl.linalg.engine.Engine.program_roms`)."""
        return self._engine.program_roms

    def cycles(self, step: str) -> int:
        """Clock edges from the one taking the W beat of ``CTRL.start = 1`` (counted) to the
        first one after which ``STATUS.done`` reads 1 (the engine's own count, both ends
        included: the back end adds nothing)."""
        return self._engine.cycles(step)

    def elaborate(self, platform):
        m = Module()
        m.submodules.front = front = Axi4Slave(self._map.address_width, BUS_ID_WIDTH, BUS_READ_LATENCY)
        m.submodules.engine = self._engine
        m.submodules.back = back = Backend(self._params, self._engine, self._map, self._stream, self._prologue)
        wiring.connect(m, front.bus, back.bus)
        forward(m, self, front, self._members)
        forward(m, self, back, self._stream_members)
        if self._params.irq:
            m.d.comb += self.irq.eq(back.irq)
        return m
