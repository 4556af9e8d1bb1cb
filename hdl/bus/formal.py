"""Formal properties of the bus and stream ports, for SymbiYosys (``kfgen.gen.formal`` runs them).

These are checkers, not gateware of a core: each watches a component's ports and adds
``Assume`` statements for what its master (or stream source) must do, ``Assert`` statements for
what the component must do, and ``Cover`` statements so that a vacuous proof (assumptions
nothing can meet) shows up as an unreached cover. Everything here is written from the AXI4 and
AXI4-Stream rules (ARM IHI 0022, IHI 0051), not from the slave's code: the two meet at the
ports, except for the statement of the slave's registers that k-induction needs
(``Axi4Properties(state=...)``), which says what they must hold given the bursts seen.

- :class:`Axi4Properties`: the AXI4 slave's channels (handshakes, bursts, IDs, responses,
  per-beat response rules of the address map, bounded per-beat liveness).
- :class:`StreamProperties`: an AXI4-Stream port (transmitter or receiver rules).
- :class:`TransferCount`: no transfer lost or duplicated between an input and an output
  stream, and every input answered within a bound.
- :class:`SmallMap`: the smallest back end with every kind of word (a read-only constant, a
  read/write register with byte strobes, memory, holes) for the slave's own proofs.
"""

from __future__ import annotations

from amaranth.asserts import AnySeq
from amaranth.hdl import Assert, Assume, Cat, Const, Cover, Elaboratable, Fragment, Module, Mux, ResetSignal, Signal, unsigned
from amaranth.lib import data, memory, wiring
from amaranth.lib.wiring import In

from .axi4 import DATA_WIDTH, FULL_SIZE, Burst, Resp, WordBusSignature, axi4_slave_members

__all__ = ["Axi4Properties", "StreamProperties", "TransferCount", "SmallMap", "hold_rule",
           "stall_counter", "drive_any", "bounded_run", "SlaveHarness", "StreamHarness", "check_if"]


def check_if(enabled: bool):
    """``Assert`` when ``enabled``, else a statement maker that checks nothing (a checker's
    property group left out of a proof)."""
    return Assert if enabled else (lambda cond, message=None, src_loc_at=0: [])


def hold_rule(m: Module, valid, ready, payload, check, name: str, reset=None):
    """``valid`` high without ``ready`` stays high the next cycle with the same ``payload``:
    the transmitter's rule of every AXI channel. ``check`` is ``Assert`` (a port the design
    drives) or ``Assume`` (its master's). ``reset``: a reset of the port (the rule starts
    afresh after it, as after ARESETn)."""
    was_waiting = Signal(name=f"{name}_was_waiting")
    was = Signal(len(payload), name=f"{name}_was")
    m.d.sync += [was_waiting.eq(valid & ~ready & (~reset if reset is not None else 1)), was.eq(payload)]
    m.d.comb += check(~was_waiting | (valid & (payload == was)), f"{name}_held", src_loc_at=1)


def stall_counter(m: Module, waiting, name: str, bound: int):
    """Assert that ``waiting`` is never high for ``bound`` cycles in a row: bounded liveness
    (``waiting`` names a request outstanding while the master is ready for its answer)."""
    count = Signal(range(bound + 1), name=f"{name}_stall")
    m.d.sync += count.eq(Mux(waiting, Mux(count == bound, bound, count + 1), 0))
    m.d.comb += Assert(count < bound, f"{name}_within_{bound}")
    return count


class _Queue:
    """A shift-register FIFO of the checker's own (bursts accepted, not yet answered)."""

    def __init__(self, m: Module, name: str, layout, depth: int, check=Assert):
        self.depth = depth
        self.count = Signal(range(depth + 1), name=f"{name}_count")
        self.slots = [Signal(layout, name=f"{name}{i}") for i in range(depth)]
        self.head = self.slots[0]
        self.push = Signal(name=f"{name}_push")
        self.pop = Signal(name=f"{name}_pop")
        self.value = Signal(layout, name=f"{name}_in")
        self.full = self.count == depth
        self.empty = self.count == 0
        m.d.sync += self.count.eq(self.count + self.push - self.pop)
        after_pop = self.count - self.pop
        for i, slot in enumerate(self.slots):
            with m.If(self.push & (after_pop == i)):
                m.d.sync += slot.eq(self.value)
            if i + 1 < depth:
                with m.Elif(self.pop):
                    m.d.sync += slot.eq(self.slots[i + 1])
        # the checker's capacity: a design that keeps more in flight must raise ``depth``
        m.d.comb += [check(~(self.pop & self.empty), f"{name}_no_answer_without_request"),
                     check(~(self.push & ~self.pop & self.full), f"{name}_within_checker_depth")]


class Axi4Properties(Elaboratable):
    """The AXI4 slave rules on the flat ports ``s_axi_*`` of ``port`` (the slave, or a core
    that forwards them). The master's inputs must be driven by the harness (``AnySeq``); this
    checker constrains them.

    Assumed of the master: AW, W and AR hold VALID and their payload until READY.

    Asserted of the slave:

    - B and R hold VALID and their payload until READY.
    - W beats are taken only for an accepted AW (the slave waits for the address).
    - one B per burst, after its last W beat, with ``BID = AWID``; R beats ``ARLEN + 1`` per burst,
      ``RLAST`` on the last only, ``RID = ARID``; responses in request order; no response
      without a request (the queues below are the checker's record of the requests).
    - responses are OKAY or SLVERR. A burst the slave does not carry out (``AxSIZE`` other than
      4 bytes, WRAP or the reserved type, an INCR burst crossing 4 KB) answers SLVERR on every
      beat (R data 0) and on B. Otherwise each beat answers as ``read_ok(word address)`` or
      ``write_ok(word address, WSTRB, WDATA)`` says (evaluated in the beat's cycle), and a
      write burst's B is SLVERR exactly when one of its beats was.
    - bounded liveness, per beat: with RREADY high, a read outstanding gets a beat within
      ``r_bound`` cycles; with WVALID and BREADY high, a W beat of an accepted burst is taken
      within ``w_bound``; with BREADY high, a burst whose last beat was taken gets B within
      ``b_bound``.

    Covered: B OKAY and SLVERR, R OKAY and SLVERR, a multi-beat INCR read and write burst,
    a FIXED read burst, back-to-back R beats.

    ``groups`` selects the assertions: ``handshake``, ``reads`` (R's rules), ``writes`` (W's
    and B's), ``liveness``. ``state`` (the slave's write-channel registers, its
    :attr:`~kfgen.hdl.bus.axi4.Axi4Slave.formal_state` after elaboration) adds what they must
    hold given the bursts seen, which makes the write channel's rules provable by k-induction.
    """

    GROUPS = ("handshake", "reads", "writes", "liveness")

    def __init__(self, port, addr_width: int, id_width: int, *, depth: int = 4, read_ok=None,
                 write_ok=None, r_bound: int = 8, w_bound: int = 3, b_bound: int = 2,
                 groups=GROUPS, state=None):
        if not set(groups) <= set(self.GROUPS):
            raise ValueError(f"groups must be some of {self.GROUPS}, not {groups!r}")
        self._groups = frozenset(groups)
        self._port = port
        self._aw = addr_width
        self._idw = id_width
        self._depth = depth
        self._read_ok = read_ok
        self._write_ok = write_ok
        self._bounds = (r_bound, w_bound, b_bound)
        self._state = state  # the slave's write-channel registers, to tie the checker to them

    def _checker(self, group):
        """``Assert`` for a group this checker proves, else a statement that checks nothing."""
        return check_if(group in self._groups)

    def _read_state(self, m, reads, arq, r_beat):
        """What the slave's read registers must hold, given the bursts the checker has seen:
        the beats in flight (the R register, the skid queue, the back-end reads pending, oldest
        first) and the burst being issued, burst by burst against the checker's queue."""
        s, st, waw = self._sig, self._state, self._aw - 2
        slots = [dict(present=s("rvalid"), last=s("rlast"), id=s("rid"), resp=s("rresp"), data=s("rdata"))]
        slots += [dict(present=st.skid_count > i, last=e.last, id=e.id, resp=e.resp, data=e.data)
                  for i, e in enumerate(st.skid)]
        slots += [dict(present=q.valid, last=q.last, id=q.id, bad=q.bad) for q in reversed(st.pending)]

        def entry(index, field):
            value = getattr(arq.slots[0], field)
            for i, slot in enumerate(arq.slots[1:], 1):
                value = Mux(index == i, getattr(slot, field), value)
            return value

        width = range(len(slots) + arq.depth + 1)
        lasts = Const(0, width)  # bursts ended before this slot
        m.d.comb += [reads((st.skid_count == 0) | s("rvalid"), "r_state_skid_behind_r"),
                     reads(Mux(arq.empty, r_beat == 0, r_beat <= arq.head.len), "r_state_beat_count"),
                     # the slave issues a read only when its answer will find room: at most
                     # read latency + 1 answers in flight, the skid queue at most its depth
                     reads(sum((q.valid for q in st.pending), s("rvalid") + st.skid_count)
                           <= len(st.pending) + 1, "r_state_room_for_every_answer")]
        bursts = []  # each slot's burst: its index in the checker's queue
        for k, slot in enumerate(slots):
            before = Signal(width, name=f"r_slot{k}_burst")
            pos = Signal(9, name=f"r_slot{k}_beat")
            m.d.comb += before.eq(lasts)
            same = [other["present"] & (b == before) for other, b in zip(slots[:k], bursts)]
            m.d.comb += pos.eq(Mux(before == 0, r_beat, 0) + sum(same, Const(0, 9)))
            bursts.append(before)
            addr = Mux(entry(before, "fixed"), entry(before, "addr"), (entry(before, "addr") + pos)[:waw])
            bad = entry(before, "bad")
            checks = [before < arq.count, slot["id"] == entry(before, "id"),
                      slot["last"] == (pos == entry(before, "len"))]
            if "resp" in slot:
                ok = self._read_ok(addr) if self._read_ok else Const(1)
                checks += [slot["resp"] == Mux(bad | ~ok, Resp.SLVERR, Resp.OKAY), ~bad | (slot["data"] == 0)]
            else:
                checks += [slot["bad"] == bad]
            m.d.comb += reads(~slot["present"] | Cat(checks).all(), f"r_state_slot{k}_is_its_burst")
            lasts = lasts + (slot["present"] & slot["last"])
        issued = sum([slot["present"] & (b == lasts) for slot, b in zip(slots, bursts)], Const(0, 9))
        issued = issued + Mux(lasts == 0, r_beat, 0)
        active = Cat(arq.count == lasts + 1, st.r_id == entry(lasts, "id"),
                     st.r_left + issued == entry(lasts, "len"), st.r_bad == entry(lasts, "bad"),
                     st.r_fixed == entry(lasts, "fixed"),
                     st.r_addr == Mux(entry(lasts, "fixed"), entry(lasts, "addr"),
                                      (entry(lasts, "addr") + issued)[:waw])).all()
        m.d.comb += reads(Mux(st.r_active, active, arq.count == lasts), "r_state_the_burst_being_issued")

    def _sig(self, name):
        return getattr(self._port, f"s_axi_{name}")

    def _refused(self, addr, length, size, burst):
        """The slave's documented burst-level refusals, from the AXI4 rules."""
        page = addr[2:12] if self._aw >= 12 else addr[2:self._aw]
        last = page + length  # one bit wider: a carry leaves the 4 KB page (or the space)
        crosses = last[len(page):] != 0
        return ((size != FULL_SIZE) | (burst == Burst.WRAP) | (burst == 3)
                | ((burst == Burst.INCR) & crosses))

    def elaborate(self, platform):
        m = Module()
        s = self._sig
        waw = self._aw - 2
        idw = self._idw

        # ------------------------------------------------------------ the master's rules
        for ch, fields in (("aw", ("id", "addr", "len", "size", "burst", "lock", "cache", "prot")),
                           ("w", ("data", "strb", "last")),
                           ("ar", ("id", "addr", "len", "size", "burst", "lock", "cache", "prot"))):
            hold_rule(m, s(f"{ch}valid"), s(f"{ch}ready"), Cat(s(ch + f) for f in fields), Assume, f"{ch}_channel")
        # ------------------------------------------------------------ the slave's handshakes
        check = self._checker("handshake")
        hold_rule(m, s("bvalid"), s("bready"), Cat(s("bid"), s("bresp")), check, "b_channel")
        hold_rule(m, s("rvalid"), s("rready"), Cat(s("rid"), s("rdata"), s("rresp"), s("rlast")),
                  check, "r_channel")
        reads, writes = self._checker("reads"), self._checker("writes")

        burst = data.StructLayout({"id": idw, "len": 8, "addr": waw, "bad": 1, "fixed": 1})
        w_hs = s("wvalid") & s("wready")
        b_hs = s("bvalid") & s("bready")
        r_hs = s("rvalid") & s("rready")

        def accepted(q, ch):
            m.d.comb += [
                q.push.eq(s(f"{ch}valid") & s(f"{ch}ready")),
                q.value.id.eq(s(f"{ch}id")), q.value.len.eq(s(f"{ch}len")),
                q.value.addr.eq(s(f"{ch}addr")[2:]),
                q.value.bad.eq(self._refused(s(f"{ch}addr"), s(f"{ch}len"), s(f"{ch}size"),
                                             s(f"{ch}burst"))),
                q.value.fixed.eq(s(f"{ch}burst") == Burst.FIXED),
            ]

        def beat_addr(head, n):
            return Mux(head.fixed, head.addr, (head.addr + n)[:waw])

        # ------------------------------------------------------------ reads
        arq = _Queue(m, "arq", burst, self._depth, reads)
        accepted(arq, "ar")
        r_beat = Signal(8)
        r_addr = Signal(waw)
        m.d.comb += [arq.pop.eq(r_hs & s("rlast")), r_addr.eq(beat_addr(arq.head, r_beat))]
        with m.If(r_hs):
            m.d.sync += r_beat.eq(Mux(s("rlast"), 0, r_beat + 1))
        r_expect = Mux(arq.head.bad, Resp.SLVERR,
                       Mux(self._read_ok(r_addr), Resp.OKAY, Resp.SLVERR) if self._read_ok else Resp.OKAY)
        with m.If(s("rvalid")):
            m.d.comb += [
                reads(~arq.empty, "r_only_for_a_request"),
                reads(s("rid") == arq.head.id, "r_id_is_arid_in_order"),
                reads(s("rlast") == (r_beat == arq.head.len), "r_last_on_beat_arlen_plus_1"),
                reads(s("rresp") == r_expect, "r_resp_as_the_map_says"),
                reads(~arq.head.bad | (s("rdata") == 0), "r_refused_burst_reads_0"),
            ]

        if self._state is not None:
            self._read_state(m, reads, arq, r_beat)

        # ------------------------------------------------------------ writes
        awq = _Queue(m, "awq", burst, self._depth, writes)
        accepted(awq, "aw")
        bq = _Queue(m, "bq", data.StructLayout({"id": idw, "err": 1}), self._depth, writes)
        w_beat = Signal(8)
        w_erred = Signal()
        w_addr = Signal(waw)
        m.d.comb += w_addr.eq(beat_addr(awq.head, w_beat))
        beat_err = awq.head.bad
        if self._write_ok:
            beat_err = beat_err | ~self._write_ok(w_addr, s("wstrb"), s("wdata"))
        last = w_beat == awq.head.len
        m.d.comb += [
            writes(~w_hs | ~awq.empty, "w_only_after_its_aw"),
            awq.pop.eq(w_hs & last),
            bq.push.eq(w_hs & last), bq.value.id.eq(awq.head.id), bq.value.err.eq(w_erred | beat_err),
            bq.pop.eq(b_hs),
        ]
        with m.If(w_hs):
            m.d.sync += [w_beat.eq(Mux(last, 0, w_beat + 1)), w_erred.eq(~last & (w_erred | beat_err))]
        with m.If(s("bvalid")):
            m.d.comb += [
                writes(~bq.empty, "b_only_after_a_whole_burst"),
                writes(s("bid") == bq.head.id, "b_id_is_awid_in_order"),
                writes(s("bresp") == Mux(bq.head.err, Resp.SLVERR, Resp.OKAY),
                          "b_resp_slverr_iff_a_beat_erred"),
            ]
        if self._state is not None:
            # what the slave's write registers must hold, given the bursts the checker has
            # seen (the strengthening k-induction needs: with it the write channel's
            # properties hold in every reachable state, not only to a depth)
            st = self._state
            m.d.comb += [
                writes(awq.count == st.w_active, "w_state_one_burst_in_progress"),
                writes(bq.count == s("bvalid"), "w_state_one_b_pending"),
                writes(st.w_active | ((w_beat == 0) & ~w_erred), "w_state_idle_counters"),
                writes(~st.w_active | ((st.w_id == awq.head.id) & (st.w_left + w_beat == awq.head.len)
                                       & (st.w_addr == w_addr) & (st.w_bad == awq.head.bad)
                                       & (st.w_fixed == awq.head.fixed) & (st.w_erred == w_erred)),
                       "w_state_is_the_burst"),
            ]

        # ------------------------------------------------------------ bounded liveness
        if "liveness" in self._groups:
            r_bound, w_bound, b_bound = self._bounds
            stall_counter(m, ~arq.empty & s("rready") & ~r_hs, "r", r_bound)
            stall_counter(m, ~awq.empty & s("wvalid") & s("bready") & ~w_hs, "w", w_bound)
            stall_counter(m, ~bq.empty & s("bready") & ~b_hs, "b", b_bound)

        # ------------------------------------------------------------ covers
        multi = Signal()
        m.d.sync += multi.eq(r_hs & ~s("rlast"))  # the beat before was not the last
        m.d.comb += [
            Cover(b_hs & (s("bresp") == Resp.OKAY), "cover_b_okay"),
            Cover(b_hs & (s("bresp") == Resp.SLVERR), "cover_b_slverr"),
            Cover(r_hs & (s("rresp") == Resp.OKAY), "cover_r_okay"),
            Cover(r_hs & (s("rresp") == Resp.SLVERR), "cover_r_slverr"),
            Cover(r_hs & s("rlast") & multi & ~arq.head.fixed & ~arq.head.bad, "cover_r_incr_burst"),
            Cover(r_hs & s("rlast") & multi & arq.head.fixed & ~arq.head.bad, "cover_r_fixed_burst"),
            Cover(b_hs & (s("bresp") == Resp.OKAY) & multi_w(m, w_hs, last), "cover_w_incr_burst"),
        ]
        return m


def multi_w(m, w_hs, last):
    """High from a burst's last W beat, when that burst had more than one beat, to the next
    beat (for a cover)."""
    earlier = Signal(name="w_earlier_beat")
    seen = Signal(name="w_multi_beat_burst")
    with m.If(w_hs):
        m.d.sync += [earlier.eq(~last), seen.eq(last & earlier)]
    return seen


class StreamProperties(Elaboratable):
    """The AXI4-Stream transmitter rule on one port: TVALID, once high, stays high with the
    same payload until TREADY (``role="out"``: asserted of the design; ``"in"``: assumed of
    its source), except across ``reset`` (a soft reset of the core, where it has one). Also
    covers a transfer, and one after a cycle of backpressure."""

    def __init__(self, valid, ready, payload, role: str, name: str, reset=None):
        if role not in ("in", "out"):
            raise ValueError(f"role must be 'in' or 'out', not {role!r}")
        self._v, self._r, self._p, self._role, self._name = valid, ready, payload, role, name
        self._reset = reset

    def elaborate(self, platform):
        m = Module()
        hold_rule(m, self._v, self._r, self._p, Assert if self._role == "out" else Assume, self._name,
                  self._reset)
        stalled = Signal(name=f"{self._name}_stalled")
        m.d.sync += stalled.eq(self._v & ~self._r)
        m.d.comb += [Cover(self._v & self._r, f"cover_{self._name}_transfer"),
                     Cover(stalled & self._v & self._r, f"cover_{self._name}_after_backpressure")]
        return m


class TransferCount(Elaboratable):
    """No transfer lost or duplicated through a design: transfers out never exceed transfers in
    (no output without its input, none twice) and at most ``capacity`` are inside at once; and
    with the output's TREADY high, an input inside gets its output within ``bound`` cycles
    (bounded liveness; counted while the output's TREADY stays high)."""

    def __init__(self, in_hs, out_hs, out_ready, capacity: int, bound: int, name: str = "stream",
                 flush=None):
        self._in, self._out, self._ready = in_hs, out_hs, out_ready
        self._cap, self._bound, self._name = capacity, bound, name
        self._flush = flush  # a soft reset: the design drops what is inside (by its contract)

    def elaborate(self, platform):
        m = Module()
        inside = Signal(range(self._cap + 2), name=f"{self._name}_inside")
        m.d.sync += inside.eq(inside + self._in - self._out)
        if self._flush is not None:
            with m.If(self._flush):
                m.d.sync += inside.eq(0)
        m.d.comb += [
            Assert(~self._out | (inside != 0) | self._in, f"{self._name}_no_output_without_input"),
            Assert(inside <= self._cap, f"{self._name}_at_most_{self._cap}_inside"),
            Cover((inside == min(2, self._cap)) & self._out, f"cover_{self._name}_{min(2, self._cap)}_inside"),
        ]
        stall_counter(m, (inside != 0) & self._ready & ~self._out, self._name, self._bound)
        return m


class SmallMap(wiring.Component):
    """The smallest back end with every kind of word, for the slave's own proofs: word 0 a
    read-only constant (``ID_WORD``), word 1 a read/write register taking bytes by strobe,
    words 4..11 memory (byte strobes), every other word a hole (SLVERR both ways).
    Read latency ``read_latency``; ``r_wait`` is the harness's (``wait``), as a busy back end's
    would be."""

    ID_WORD = 0x4B46_0001
    MEM_BASE, MEM_WORDS = 4, 8

    def __init__(self, addr_width: int, read_latency: int = 1):
        self._lat = read_latency
        super().__init__({"bus": In(WordBusSignature(addr_width - 2, read_latency)), "wait": In(1)})

    @classmethod
    def readable(cls, word):
        return (word == 0) | (word == 1) | ((word >= cls.MEM_BASE) & (word < cls.MEM_BASE + cls.MEM_WORDS))

    @classmethod
    def writable(cls, word):
        return (word == 1) | ((word >= cls.MEM_BASE) & (word < cls.MEM_BASE + cls.MEM_WORDS))

    def elaborate(self, platform):
        m = Module()
        bus = self.bus
        m.submodules.mem = mem = memory.Memory(shape=unsigned(DATA_WIDTH), depth=self.MEM_WORDS, init=[])
        wr = mem.write_port(granularity=8)
        rd = mem.read_port()  # read latency 1
        reg = Signal(DATA_WIDTH)
        in_mem_r = (bus.r_addr >= self.MEM_BASE) & (bus.r_addr < self.MEM_BASE + self.MEM_WORDS)
        in_mem_w = (bus.w_addr >= self.MEM_BASE) & (bus.w_addr < self.MEM_BASE + self.MEM_WORDS)
        m.d.comb += [
            bus.r_wait.eq(self.wait),
            rd.addr.eq(bus.r_addr - self.MEM_BASE), rd.en.eq(bus.r_en & in_mem_r),
            wr.addr.eq(bus.w_addr - self.MEM_BASE),
            wr.en.eq(Mux(bus.w_en & in_mem_w, bus.w_strb, 0)),
            wr.data.eq(bus.w_data),
            bus.w_err.eq(~self.writable(bus.w_addr)),
        ]
        with m.If(bus.w_en & (bus.w_addr == 1)):
            for i in range(4):
                with m.If(bus.w_strb[i]):
                    m.d.sync += reg[8 * i:8 * i + 8].eq(bus.w_data[8 * i:8 * i + 8])
        from_mem, err, word = Signal(), Signal(), Signal(DATA_WIDTH)
        with m.If(bus.r_en):
            m.d.sync += [from_mem.eq(in_mem_r), err.eq(~self.readable(bus.r_addr)),
                         word.eq(Mux(bus.r_addr == 0, self.ID_WORD, reg))]
        r_data, r_err = Mux(from_mem, rd.data, word), err
        if self._lat == 2:
            d2, e2 = Signal(DATA_WIDTH), Signal()
            m.d.sync += [d2.eq(r_data), e2.eq(r_err)]
            r_data, r_err = d2, e2
        m.d.comb += [bus.r_data.eq(r_data), bus.r_err.eq(r_err)]
        return m


def drive_any(m: Module, port, members: dict):
    """Drive every input member of ``members`` on ``port`` from ``AnySeq`` (the free master)."""
    for name, member in members.items():
        if member.flow == In:
            sig = getattr(port, name)
            m.d.comb += sig.eq(AnySeq(len(sig)))


def bounded_run(m: Module, signal, limit: int, name: str):
    """Assume ``signal`` is never high more than ``limit`` cycles in a row (an environment's
    bounded stall)."""
    run = Signal(range(limit + 2), name=f"{name}_run")
    m.d.sync += run.eq(Mux(signal, run + 1, 0))
    m.d.comb += Assume(~signal | (run < limit), f"{name}_at_most_{limit}")



class SlaveHarness(Elaboratable):
    """The AXI4 slave front end (``slave_cls``, :class:`~kfgen.hdl.bus.axi4.Axi4Slave` or a
    mutant of it) on :class:`SmallMap`, its master free (``AnySeq``) under the AXI4 rules,
    the back end's read waits free but never more than two cycles in a row, and the slave's
    properties (``groups`` of :class:`Axi4Properties`) checked; with ``state``, also what its
    registers must hold (for k-induction; BMC needs it not)."""

    def __init__(self, slave_cls, read_latency: int = 1, groups=Axi4Properties.GROUPS,
                 addr_width: int = 16, id_width: int = 2, state: bool = False):
        self._cls, self._lat, self._groups, self._state = slave_cls, read_latency, groups, state
        self._aw, self._idw = addr_width, id_width

    def elaborate(self, platform):
        m = Module()
        dut = self._cls(self._aw, self._idw, self._lat)
        m.submodules.dut = Fragment.get(dut, platform)  # elaborated here: its state is visible
        m.submodules.back = back = SmallMap(self._aw, self._lat)
        wiring.connect(m, dut.bus, back.bus)
        drive_any(m, dut, axi4_slave_members(self._aw, self._idw))
        m.d.comb += back.wait.eq(AnySeq(1))
        bounded_run(m, back.wait, 2, "back_end_wait")
        m.d.comb += Assume(ResetSignal() == 0)  # from the reset state (the registers' init)
        # a read may wait 2 cycles in a row at the back end, then is issued and answered
        # read_latency + 1 cycles later: the R bound covers both
        m.submodules.props = Axi4Properties(
            dut, self._aw, self._idw, read_ok=SmallMap.readable,
            write_ok=lambda word, strb, wdata: SmallMap.writable(word), groups=self._groups,
            r_bound=self._lat + 5, state=dut.formal_state if self._state else None)
        return m


class StreamHarness(Elaboratable):
    """A stream core (``s_axis_*`` in, ``m_axis_*`` out, one output per input, in order) with
    its inputs free: ``s_axis`` under the transmitter rule, ``m_axis_tready`` anything. Checks
    the transmitter rule on ``m_axis``, that ``s_axis_tready`` does not wait for
    ``s_axis_tvalid`` (AXI4-Stream allows it; the cores promise it), and
    :class:`TransferCount` with ``capacity`` and ``bound`` (unless not ``count``)."""

    def __init__(self, dut, capacity: int, bound: int, count: bool = True):
        self._dut, self._cap, self._bound, self._count = dut, capacity, bound, count

    def elaborate(self, platform):
        m = Module()
        dut = self._dut
        m.submodules.dut = dut
        ins = {name: member for name, member in dut.signature.members.items() if member.flow == In}
        drive_any(m, dut, ins)
        m.d.comb += Assume(ResetSignal() == 0)
        in_payload = Cat(getattr(dut, n) for n in ins if n.startswith("s_axis_") and n != "s_axis_tvalid")
        outs = [n for n in dut.signature.members if n.startswith("m_axis_") and n not in ("m_axis_tvalid", "m_axis_tready")]
        out_payload = Cat(getattr(dut, n) for n in outs)
        m.submodules.s_axis = StreamProperties(dut.s_axis_tvalid, dut.s_axis_tready, in_payload, "in", "s_axis")
        m.submodules.m_axis = StreamProperties(dut.m_axis_tvalid, dut.m_axis_tready, out_payload, "out", "m_axis")
        if not self._count:  # the transmitter rules alone
            return m
        m.submodules.count = TransferCount(dut.s_axis_tvalid & dut.s_axis_tready,
                                           dut.m_axis_tvalid & dut.m_axis_tready, dut.m_axis_tready,
                                           self._cap, self._bound)
        return m
