"""The linear-algebra engine: runs scheduled step programs from its program store, cycle for
cycle as :mod:`.schedule` planned them, on its banked operand memory.

::

  start/step ─► sequencer ─► InstructionStream pe0 .. pe{P-1}, div, sqrt, copy (ROMs)
                   │                 │ fire + instruction (registers), the cycle before the start
                   │                 ▼
                   │      ProcessingElement x P  SharedUnit div / sqrt / copy
                   │         3 read, 2 write       2|1 read, 1 write lane (2: mirrors)
                   │                 │ ▲          each lane names its bank port (scheduled)
                   │                 ▼ │  lane registers, OR crossbar, RAM, data registers
  bus port  ───────┼──────────► BankedMemory    (the bus's lanes take the ports left free)
                   │            dual-port RAM banks, constants initialised
                   ▼
         busy / done / err_pivot / err_nan / flags

Every path starts and ends at a register or a block RAM within a short distance: the fetch
decides an issue from registers, the units issue from registers, the crossbar is an OR of
registered requests, and a read's word is registered behind the RAM.
"""

from __future__ import annotations

from amaranth.hdl import Array, C, Module, ResetInserter, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from . import isa
from .banks import BankedMemory
from .microcode import Microcode, compile_steps
from .sequencer import InstructionStream, instruction_layout
from .units import ProcessingElement, SharedUnit

__all__ = ["program_roms", "Engine", "OVERHEAD", "overhead"]

#: Cycles a step takes beyond its schedule: ``start``'s register, the streams' lead to the
#: step's cycle 0 (:attr:`InstructionStream.LEAD`), the last write's lane register and
#: ``done``'s register, less the cycle of ``start``. A machine with ``fetch_register`` takes
#: one more (:func:`overhead`).
OVERHEAD = 1 + InstructionStream.LEAD + 1


def overhead(mc) -> int:
    """:data:`OVERHEAD` on machine ``mc``: a cycle more with its program store's fetch register."""
    return OVERHEAD + mc.fetch_register


def _stream_layout(code: Microcode, img):
    """The instruction word of stream ``img`` (no ``mirror`` and ``dst1`` when no instruction
    of it writes a second address: one write lane)."""
    mirror = any(w["mirror"] for w in img.words)
    return instruction_layout(img.unit, code.geometry, code.widths, mirror)


def program_roms(code: Microcode) -> dict:
    """Stream name (``pe0``..., then the shared units) -> (words, bits a word) of the ROM the
    engine of ``code`` builds for it: the program store as built, every step in each ROM."""
    return {name: (InstructionStream.rom_depth(img), _stream_layout(code, img).size)
            for name, img in code.streams.items()}


class Engine(wiring.Component):
    """The engine of ``steps`` (schedules of one machine, one memory layout and format).

    A step starts when ``start`` is high while idle (``step`` names it); ``busy`` rises the
    next cycle and ``done`` is high for one cycle :meth:`cycles` clock edges after the one
    that sampled ``start`` (the schedule's length plus :func:`overhead`), when ``busy`` has
    fallen. ``start`` while busy is ignored.

    Faults: a checked pivot that is NaN, negative or zero sets ``err_pivot``; a NaN or
    infinity in a result checked ``finite`` sets ``err_nan``. Neither stops the step: it runs
    to its end (the same length, so nothing can hang, and the memory then holds exactly
    what :func:`kfgen.sim.linalg.exec.run` leaves, NaNs included), and the core is idle
    after ``done``. The error bits, and ``flags`` (the OR of every FMA, division and square
    root's IEEE flags NX UF OF DZ NV), clear the cycle after a start and are otherwise held.

    The bus port reads and writes the memory, one read and one write a cycle: ``mem_rdata``
    holds the word at ``mem_raddr`` of two cycles before (read latency 2,
    :data:`~.banks.BUS_READ_LATENCY`: the block RAM and the register behind it) when
    ``mem_rok`` was high with it. The engine's lanes come first: while busy a bus read is
    served only where the step leaves its bank a port (``mem_rok``; else the reader
    retries), and a bus write may be lost (the bus front end refuses them). A bus read is
    not served either in a cycle in which the step writes its bank, or the bus its word: the
    block RAM leaves a word written in the cycle of its read undefined, and the retry reads
    the new word. Constants are in the memory from configuration; nothing resets the memory.

    Parameters
    ----------
    steps : dict of str to schedule.Schedule
        The step programs, scheduled; ``step`` is an index into their order.

    Members
    -------
    start : In(1)
    step : In(range(len(steps)))
    halt : In(1)
        Soft reset: the engine is idle the next cycle, nothing more is written (the memory
        keeps what the step wrote so far), ``done`` does not rise. The status is kept.
    busy, done : Out(1)
    err_pivot, err_nan : Out(1)
    flags : Out(5)
    mem_raddr : In(range(size)); mem_rdata : Out(width); mem_rok : Out(1)
    mem_waddr : In(range(size)); mem_wdata : In(width); mem_we : In(1)
    """

    def __init__(self, steps):
        if not steps:
            raise ValueError("steps must name at least one scheduled step")
        self._names = list(steps)
        self._scheds = list(steps.values())
        prog = self._scheds[0].program
        self._fmt, self._layout = prog.fmt, prog.layout
        self._mc = self._scheds[0].machine
        self._code = compile_steps(self._scheds)
        w, size = self._fmt.width, self._layout.size
        super().__init__({
            "start": In(1), "step": In(range(max(2, len(steps)))), "halt": In(1),
            "busy": Out(1), "done": Out(1), "err_pivot": Out(1), "err_nan": Out(1),
            "flags": Out(5),
            "mem_raddr": In(range(size)), "mem_rdata": Out(w), "mem_rok": Out(1),
            "mem_waddr": In(range(size)), "mem_wdata": In(w), "mem_we": In(1),
        })

    @property
    def program_roms(self) -> dict:
        """:func:`program_roms` of this engine's microcode."""
        return program_roms(self._code)

    @property
    def step_names(self):
        return tuple(self._names)

    def cycles(self, step) -> int:
        """Clock edges from the one sampling ``start`` to the one after which ``done`` is
        high: the schedule's length plus :func:`overhead` (:data:`OVERHEAD`, a cycle more with
        the fetch register)."""
        k = self._names.index(step) if isinstance(step, str) else step
        return self._code.cycles[k] + overhead(self._mc)

    def elaborate(self, platform):
        m = Module()
        mc, fmt, code = self._mc, self._fmt, self._code
        g = code.geometry
        units = []
        # the soft reset, registered: it reaches every unit and stream a cycle later (a net of
        # thousands of loads, driven from a register); the memory drops what they ask for in
        # the meantime
        halt = Signal()
        m.d.sync += halt.eq(self.halt)
        for name, img in code.streams.items():
            layout = _stream_layout(code, img)
            stream = InstructionStream(img, layout, mc.fetch_register)
            m.submodules[f"{name}_stream"] = ResetInserter(halt)(stream)
            if img.unit == "fma":
                unit = ProcessingElement(fmt, g, layout, stages=mc.fma_latency)
            else:
                unit = SharedUnit(img.unit, fmt, g, layout, stages=isa.unit(img.unit).pipeline(mc),
                                  cycles_per_op=mc.interval(img.unit), register=mc.unit_register)
            m.submodules[name] = ResetInserter(halt)(unit)  # no write in flight
            m.d.comb += [unit.fire.eq(stream.fire), unit.ins.eq(stream.ins)]
            units.append((stream, unit))
        reads = [lane for _, u in units for lane in u.rd]
        writes = [lane for _, u in units for lane in u.wr]
        groups = [k for k, (_, u) in enumerate(units) for _ in u.wr]  # a unit's lanes carry one word
        m.submodules.memory = mem = BankedMemory(g, fmt.width, self._layout.initial_memory(),
                                                 len(reads) + 1, len(writes) + 1, groups + [len(units)])
        m.d.comb += mem.flush.eq(halt)
        for a, b in zip(reads, mem.rd):
            wiring.connect(m, a, b)
        for a, b in zip(writes, mem.wr):
            wiring.connect(m, a, b)
        bus_rd, bus_wr = mem.rd[-1], mem.wr[-1]
        m.d.comb += [
            bus_rd.en.eq(1),
            bus_rd.addr.bank.eq(self.mem_raddr % g.banks),
            bus_rd.addr.row.eq(self.mem_raddr // g.banks),
            self.mem_rdata.eq(bus_rd.data),
            self.mem_rok.eq(mem.rd_ok),
            bus_wr.en.eq(self.mem_we),
            bus_wr.addr.bank.eq(self.mem_waddr % g.banks),
            bus_wr.addr.row.eq(self.mem_waddr // g.banks),
            bus_wr.data.eq(self.mem_wdata),
        ]
        # the sequencer: start registered into the streams; count the step's cycles from the
        # one after start to the one its last write reaches the memory
        go = self.start & ~self.busy
        go_r = Signal()
        step = Signal.like(self.step)
        extra = overhead(mc)
        count = Signal(range(max(code.cycles) + extra - 1))
        pad = (1 << len(step)) - len(code.cycles)  # every step index covered
        last = Array(C(c + extra - 2, count.shape()) for c in code.cycles + code.cycles[-1:] * pad)
        m.d.sync += go_r.eq(go & ~self.halt)
        for stream, _ in units:
            m.d.comb += [stream.start.eq(go_r), stream.step.eq(step)]
        m.d.sync += self.done.eq(0)
        with m.If(self.halt):
            m.d.sync += self.busy.eq(0)
        with m.Elif(go):
            m.d.sync += [self.busy.eq(1), step.eq(self.step), count.eq(0)]
        with m.Elif(self.busy):
            m.d.sync += count.eq(count + 1)
            with m.If(count == last[step]):
                m.d.sync += [self.busy.eq(0), self.done.eq(1)]
        # the status clears a cycle after start (from go's register, not from the bus's
        # decode), before any unit can write, and gathers the units' faults while busy
        pivot = nan = flags = 0
        for _, u in units:
            pivot, nan, flags = pivot | u.pivot, nan | u.nan, flags | u.flags
        with m.If(go_r):
            m.d.sync += [self.err_pivot.eq(0), self.err_nan.eq(0), self.flags.eq(0)]
        with m.Elif(self.busy & ~self.halt):
            m.d.sync += [self.err_pivot.eq(self.err_pivot | pivot),
                         self.err_nan.eq(self.err_nan | nan),
                         self.flags.eq(self.flags | flags)]
        return m
