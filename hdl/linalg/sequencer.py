"""The program store (one ROM per issuing unit) and its fetch: an instruction leaves its
stream the cycle before it starts."""

from __future__ import annotations

from amaranth.hdl import Array, C, Cat, Module, Mux, Signal, unsigned
from amaranth.lib import data, memory, wiring
from amaranth.lib.wiring import In, Out

from . import isa
from .banks import addr_layout
from .isa import CHECK_BITS

__all__ = ["instruction_layout", "InstructionStream"]


def instruction_layout(unit: str, geometry, widths, mirror: bool = True) -> data.StructLayout:
    """A stream's instruction word (fields of :mod:`.microcode`); without ``mirror`` (no
    instruction of the stream writes a second address) no ``mirror`` and ``dst1``."""
    addr = addr_layout(geometry)
    fields = {"delta": unsigned(widths["delta"]), "a": addr, "pa": 1, "b": addr, "pb": 1,
              "dst": addr, "pd0": 1, "check": CHECK_BITS}
    if mirror:
        fields.update({"dst1": addr, "pd1": 1, "mirror": 1})
    if unit == "fma":
        fields.update({"count": unsigned(widths["count"]), "sa": addr, "sb": addr, "neg": 1,
                       "first": 1, "init_en": 1, "init": addr, "pi": 1, "last": 1})
    if "b" not in isa.unit(unit).operands:
        del fields["b"], fields["pb"]
    return data.StructLayout(fields)


class InstructionStream(wiring.Component):
    """One unit's instructions: a ROM holding every step, and its fetch.

    ``start`` (one cycle, while the stream is idle) selects step ``step``; the step's cycle
    0 is :data:`LEAD` cycles after that one. An instruction whose step cycle is ``t``
    (``delta`` after the previous one's, the first's after cycle 0) leaves the stream at
    cycle ``t - 1``: ``fire`` is high and ``ins`` holds it. Both are registers.

    The fetch is pipelined so that no path runs from the ROM's output back to its address:
    the ROM (read latency 1) holds the next instruction but one, a register the next one,
    and a counter of the cycles since the last issue decides, from registers alone, when the
    next one leaves (instructions may leave on consecutive cycles).

    With ``fetch_register`` the fetch is a prefetch for a faster clock, and the lead a cycle
    longer (:attr:`lead`): the block RAM's word goes straight into a register (its
    clock-to-output is most of an ECP5 cycle at 125 MHz: the DP16KD's own output register
    is not inferred by Yosys), and then into a queue in front of the next instruction's
    register. The ROM reads its next word while the words read and not yet taken number
    fewer than :data:`PREFETCH`, counted in registers, so that the issue decision does not
    reach the block RAMs' enables either.

    Parameters
    ----------
    image : microcode.StreamImage
    layout : data.StructLayout
        :func:`instruction_layout` of the stream's unit.
    fetch_register : bool

    Members
    -------
    start : In(1)
    step : In(range(steps))
    fire : Out(1)
    ins : Out(layout)
        Valid while ``fire``.
    """

    #: Cycles from the one ``start`` is high in to the step's cycle 0: the ROM's first read,
    #: the next-instruction register, the issue decision and the output register.
    LEAD = 4

    #: With the fetch register: the words read ahead of the next instruction's register at
    #: most (the ROM's output, the register behind it and the queue), enough for an
    #: instruction every cycle.
    PREFETCH = 3

    #: With the fetch register: the most words a piece of the ROM holds (an ECP5 DP16KD is
    #: 512 words deep at its widest). A power of 2.
    ROM_PIECE = 512

    @property
    def lead(self) -> int:
        """Cycles from ``start`` to the step's cycle 0: :data:`LEAD`, a cycle more with the
        fetch register."""
        return self.LEAD + self._fetch_register

    @staticmethod
    def rom_depth(image) -> int:
        """Words of the ROM holding ``image`` (every step's instructions; one at least)."""
        return max(1, len(image.words))

    def __init__(self, image, layout, fetch_register: bool = False):
        self._image = image
        self._fetch_register = bool(fetch_register)
        steps = len(image.bases)
        super().__init__({"start": In(1), "step": In(range(max(2, steps))),
                          "fire": Out(1), "ins": Out(layout)})

    def elaborate(self, platform):
        m = Module()
        img = self._image
        layout = self.ins.shape()
        depth = self.rom_depth(img)
        words = [{k: v for k, v in w.items() if k in layout.members} for w in img.words] or [{}]
        if self._fetch_register:
            return self._prefetch(m, words)
        m.submodules.rom = rom = memory.Memory(shape=layout, depth=depth, init=words)
        rp = rom.read_port()
        bases, ends = self._step_table(depth)
        idx = Signal(range(depth + 1))  # the ROM's next read
        end = Signal(range(depth + 1))
        a_valid = Signal()  # the ROM's output is an instruction of the step not yet taken
        nxt = Signal(layout)  # the next instruction to leave
        nxt_valid = Signal()
        elapsed = Signal(layout.members["delta"])  # cycles since the last one left
        go = Signal()
        m.d.comb += go.eq(nxt_valid & (elapsed == nxt.delta))
        take = Signal()
        m.d.comb += take.eq((go | ~nxt_valid) & a_valid)
        m.d.sync += self.fire.eq(go)
        with m.If(go):
            m.d.sync += self.ins.eq(nxt)
        with m.If(self.start):
            m.d.comb += [rp.addr.eq(bases[self.step]), rp.en.eq(1)]
            m.d.sync += [idx.eq(bases[self.step] + 1), end.eq(ends[self.step]),
                         a_valid.eq(bases[self.step] != ends[self.step]), nxt_valid.eq(0)]
        with m.Else():
            m.d.comb += [rp.addr.eq(idx), rp.en.eq(take)]
            with m.If(take):
                m.d.sync += [nxt.eq(rp.data), idx.eq(idx + 1), a_valid.eq(idx != end)]
            with m.If(go | ~nxt_valid):
                m.d.sync += nxt_valid.eq(a_valid)
            # the first instruction counts from the cycle after it is taken; the others from
            # the cycle after the previous one left (after the last one, elapsed may wrap)
            m.d.sync += elapsed.eq(Mux(go, 1, Mux(nxt_valid, elapsed + 1, 0)))
        return m

    def _step_table(self, depth):
        """Each step's first and one-past-last ROM address, indexed by ``step``."""
        img = self._image
        pad = (1 << len(self.step)) - len(img.bases)  # every step index covered
        return (Array(C(b, range(depth + 1)) for b in img.bases + img.bases[-1:] * pad),
                Array(C(e, range(depth + 1)) for e in img.ends + img.ends[-1:] * pad))

    def _prefetch(self, m, words):
        """The fetch with its register behind the ROM (``fetch_register``). The ROM is in
        pieces of at most :data:`ROM_PIECE` words, each with its own register, so that no
        multiplexer of pieces sits between a block RAM and its register. ``go`` is a
        register here: it is computed a cycle ahead, with each queued word's delta of 0 or 1
        decoded as it joins the queue."""
        layout = self.ins.shape()
        size = len(words)
        bases, ends = self._step_table(size)
        idx = Signal(range(size + 1))  # the ROM's next read
        end = Signal(range(size + 1))
        nxt = Signal(layout)  # the next instruction to leave
        nxt_valid = Signal()
        elapsed = Signal(layout.members["delta"])  # cycles since the last one left
        go = Signal()
        depth = self.PREFETCH
        read = Signal()  # the ROM reads idx this cycle
        more = Signal()  # idx is a word of the step
        fresh = Signal()  # the ROM's output is a word read the cycle before
        # the pieces: piece k holds words k * ROM_PIECE on; each piece's output is registered
        # every cycle, and the piece of the word read is selected behind those registers
        pieces = -(-size // self.ROM_PIECE)
        addr = Signal(range(size))  # the address the ROM reads this cycle (idx < size when it reads)
        piece = addr >> (self.ROM_PIECE.bit_length() - 1)
        outs = []
        for k in range(pieces):
            chunk = words[k * self.ROM_PIECE:(k + 1) * self.ROM_PIECE]
            rom = memory.Memory(shape=layout, depth=len(chunk), init=chunk)
            m.submodules["rom" if pieces == 1 else f"rom{k}"] = rom
            rp = rom.read_port()
            out = Signal(layout, name="rom_word" if pieces == 1 else f"rom{k}_word")
            m.d.comb += [rp.addr.eq(addr), rp.en.eq(read & (piece == k))]
            m.d.sync += out.eq(rp.data)
            outs.append(out)
        word = outs[0]  # the word read two cycles before, from its piece's register
        if pieces > 1:
            which = [Signal(range(pieces), name=f"piece_{at}") for at in ("out", "word")]
            m.d.sync += [which[0].eq(piece), which[1].eq(which[0])]
            word = Signal(layout)
            m.d.comb += word.eq(Array(outs + outs[-1:] * ((1 << len(which[1])) - pieces))[which[1]])
        word_valid = Signal()
        queue = [Signal(layout, name=f"queue{i}") for i in range(depth)]  # queue[0] the oldest
        soon = [Signal(2, name=f"queue{i}_soon") for i in range(depth)]  # its delta is 0, 1
        word_soon = Cat(word.delta == 0, word.delta == 1)
        count = Signal(range(depth + 1))  # words in queue
        ahead = Signal(range(depth + 1))  # words read and not yet in nxt
        free = Signal()  # nxt leaves or is empty: it takes the oldest word this cycle
        load = Signal()
        m.d.comb += [free.eq(go | ~nxt_valid), load.eq(free & ((count != 0) | word_valid))]
        m.d.sync += self.fire.eq(go)
        with m.If(go):
            m.d.sync += self.ins.eq(nxt)
        with m.If(self.start):
            m.d.comb += [addr.eq(bases[self.step]), read.eq(1)]
            first = bases[self.step] != ends[self.step]
            m.d.sync += [idx.eq(bases[self.step] + 1), end.eq(ends[self.step]), fresh.eq(first),
                         more.eq(first & (bases[self.step] + 1 != ends[self.step])),
                         ahead.eq(first), word_valid.eq(0), count.eq(0), nxt_valid.eq(0), go.eq(0)]
        with m.Else():
            # ahead and idx are registers: the issue decision does not reach the ROM
            m.d.comb += [read.eq((ahead < depth) & more), addr.eq(idx)]
            with m.If(read):
                m.d.sync += [idx.eq(idx + 1), more.eq(idx + 1 != end)]
            m.d.sync += [fresh.eq(read), word_valid.eq(fresh), ahead.eq(ahead + read - load)]
            with m.If(free):
                m.d.sync += [nxt.eq(Mux(count != 0, queue[0], word)), nxt_valid.eq((count != 0) | word_valid)]
            # go a cycle ahead: the word nxt takes leaves at once (delta 0) when nxt was
            # empty, the cycle after (delta 1) when nxt leaves now; else nxt waits its delta
            new = Mux(count != 0, soon[0], word_soon) & Mux((count != 0) | word_valid, 3, 0)
            wait = (elapsed + 1)[:len(elapsed)] == nxt.delta
            m.d.sync += go.eq(Mux(go, new[1], Mux(nxt_valid, wait, new[0])))
            # the queue: the oldest leaves on load (unless it is word, the queue empty); word
            # joins at the tail unless it went straight into nxt
            pop = load & (count != 0)
            push = word_valid & ~(load & (count == 0))
            m.d.sync += count.eq(count + push - pop)
            tail = Signal.like(count)
            m.d.comb += tail.eq(count - pop)
            for i, entry in enumerate(queue):
                with m.If(push & (tail == i)):
                    m.d.sync += [entry.eq(word), soon[i].eq(word_soon)]
                if i + 1 < depth:
                    with m.Elif(pop):
                        m.d.sync += [entry.eq(queue[i + 1]), soon[i].eq(soon[i + 1])]
            m.d.sync += elapsed.eq(Mux(go, 1, Mux(nxt_valid, elapsed + 1, 0)))
        return m
