"""AXI4 slave front end (32-bit data, INCR and FIXED bursts at one beat per clock) in front of a
word-addressed back end with one read port and one write port.

The front end speaks AXI4; the back end (a register file, an operand memory, or both behind an
address decoder) only sees word reads and word writes and may refuse any of them. Nothing here
knows the address map.

Decisions, in the order a user of the port meets them:

- **Bursts.** INCR and FIXED are carried out beat by beat (FIXED repeats the start address, so a
  burst can poll a status word or fill a port register); WRAP, the reserved type 3, and any size
  other than 4 bytes (``AxSIZE != 2``: narrow or wider than the bus) answer SLVERR for every beat
  without touching the back end (writes dropped, reads return 0). ``AxLEN`` is taken as given
  (1..256 beats whatever the type); the write burst ends after ``AWLEN + 1`` beats, ``WLAST`` is
  not checked.
- **4 KB.** An INCR burst that would cross a 4 KB boundary (or the end of the address space, when
  it is smaller than 4 KB) breaks a master's rule; rather than guess where the master meant the
  later beats to go, the whole burst answers SLVERR and touches nothing, so the bug shows.
- **Unaligned start addresses** are legal AXI: beats address whole words (``AxADDR[1:0]`` is
  ignored), and the write strobes say which bytes of the first word change.
- **Byte strobes** go to the back end unchanged with every write; the back ends apply them per
  byte (registers and memory words alike) and a beat with ``WSTRB = 0`` writes nothing and answers
  OKAY, as a block RAM controller does.
- **Errors per beat.** The back end may refuse a read (``r_err``: the beat answers SLVERR with
  data 0) or a write (``w_err``: that beat changes nothing); the other beats of the burst go on.
  A write burst gets one B response, SLVERR if any of its beats erred.
- **Concurrency.** Reads and writes are independent: a read burst and a write burst proceed in
  the same cycles, each on its own back-end port. A read and a write of the same word in the
  same cycle: the read returns whatever the back end's read port gives (the old word, for a
  non-transparent memory port); AXI leaves that order to the slave.
- Sideband inputs ``AxLOCK``, ``AxCACHE``, ``AxPROT`` are accepted and ignored: an exclusive
  access is done as a normal one and answers OKAY (the AXI4 answer of a slave without exclusive
  monitors).

Timing (clock cycles, no backpressure): a read burst of N beats accepted (AR handshake) at cycle
t returns its beats at t+1+L .. t+N+L for a back end of read latency L (1 or 2), and the next
read burst's address is accepted the cycle after the last beat of the previous one is issued
to the back end, so back-to-back read bursts (and single reads) stream with no gap. A write burst accepted at t takes its beats at t+1 .. t+N and
gives B at t+N+1; the next write address is accepted at t+N+1 (N + 1 cycles per write burst).
No output depends combinationally on an input (AXI4's rule for interfaces): every ``*ready``,
``*valid`` and payload output is a register.
"""

from __future__ import annotations

from types import SimpleNamespace

from amaranth.hdl import Module, Mux, Signal
from amaranth.lib import enum, wiring
from amaranth.lib.wiring import In, Out

__all__ = ["Burst", "Resp", "WordBusSignature", "axi4_slave_members", "forward", "lint_waivers",
           "Axi4Slave"]

DATA_WIDTH = 32
#: ``AxSIZE`` of a full-width beat: 2**2 bytes.
FULL_SIZE = 2


class Burst(enum.Enum, shape=2):
    FIXED = 0
    INCR = 1
    WRAP = 2


class Resp(enum.Enum, shape=2):
    OKAY = 0
    EXOKAY = 1
    SLVERR = 2
    DECERR = 3


class WordBusSignature(wiring.Signature):
    """The back-end interface, as the front end drives it (``Out``: front end to back end).

    Addresses are word addresses (the AXI byte address shifted right by two). Reads have a fixed
    latency of ``read_latency`` cycles (1 or 2): ``r_data`` and ``r_err`` answer that many cycles
    after the one where ``r_en`` was high, and are don't-care otherwise. (2 lets a back end
    register a block RAM's word before it leaves, when the RAM's clock-to-output is most of a
    cycle.) Writes are answered in their own cycle: ``w_err`` is a
    combinational function of ``w_addr``, ``w_strb`` (and the back end's state), and a write the
    back end refuses must change nothing. One read and one write may come in the same cycle.

    Parameters
    ----------
    addr_width : int
        Word-address width.
    read_latency : 1 or 2

    Members
    -------
    r_addr : Out(addr_width)
    r_en : Out(1)
    r_data : In(32)
        The word at ``r_addr``, ``read_latency`` cycles after ``r_en``.
    r_err : In(1)
        With ``r_data``: the read is refused (nothing is mapped there).
    r_wait : In(1)
        In the cycle of ``r_addr``: the back end cannot read there this cycle; the front end
        holds the read (``r_en`` stays low) and offers it again the next cycle, so the R
        channel waits. A combinational function of ``r_addr`` and the back end's state.
    w_addr : Out(addr_width)
    w_data : Out(32)
    w_strb : Out(4)
        Byte lanes of ``w_data`` to write.
    w_en : Out(1)
    w_err : In(1)
        Same cycle as ``w_en``: the write is refused and changes nothing.
    """

    def __init__(self, addr_width: int, read_latency: int = 1):
        if not isinstance(addr_width, int) or addr_width < 1:
            raise ValueError(f"addr_width must be a positive integer, not {addr_width!r}")
        if read_latency not in (1, 2) or isinstance(read_latency, bool):
            raise ValueError(f"read_latency must be 1 or 2, not {read_latency!r}")
        self._addr_width = addr_width
        self._read_latency = read_latency
        super().__init__({
            "r_addr": Out(addr_width),
            "r_en": Out(1),
            "r_data": In(DATA_WIDTH),
            "r_err": In(1),
            "r_wait": In(1),
            "w_addr": Out(addr_width),
            "w_data": Out(DATA_WIDTH),
            "w_strb": Out(DATA_WIDTH // 8),
            "w_en": Out(1),
            "w_err": In(1),
        })

    @property
    def addr_width(self) -> int:
        return self._addr_width

    @property
    def read_latency(self) -> int:
        return self._read_latency

    def __eq__(self, other):
        return (isinstance(other, WordBusSignature) and other.addr_width == self.addr_width
                and other.read_latency == self.read_latency)

    def __repr__(self):
        return f"WordBusSignature({self.addr_width}, read_latency={self.read_latency})"


def axi4_slave_members(addr_width: int, id_width: int, prefix: str = "s_axi") -> dict:
    """The flat AXI4 slave ports ``{prefix}_aw*`` ... ``{prefix}_r*`` as signature members, named as
    Vivado's interface inference and cocotbext-axi's ``AxiBus.from_prefix`` expect them."""
    p = prefix
    return {
        f"{p}_awid": In(id_width), f"{p}_awaddr": In(addr_width), f"{p}_awlen": In(8),
        f"{p}_awsize": In(3), f"{p}_awburst": In(2), f"{p}_awlock": In(1), f"{p}_awcache": In(4),
        f"{p}_awprot": In(3), f"{p}_awvalid": In(1), f"{p}_awready": Out(1),
        f"{p}_wdata": In(DATA_WIDTH), f"{p}_wstrb": In(DATA_WIDTH // 8), f"{p}_wlast": In(1),
        f"{p}_wvalid": In(1), f"{p}_wready": Out(1),
        f"{p}_bid": Out(id_width), f"{p}_bresp": Out(2), f"{p}_bvalid": Out(1), f"{p}_bready": In(1),
        f"{p}_arid": In(id_width), f"{p}_araddr": In(addr_width), f"{p}_arlen": In(8),
        f"{p}_arsize": In(3), f"{p}_arburst": In(2), f"{p}_arlock": In(1), f"{p}_arcache": In(4),
        f"{p}_arprot": In(3), f"{p}_arvalid": In(1), f"{p}_arready": Out(1),
        f"{p}_rid": Out(id_width), f"{p}_rdata": Out(DATA_WIDTH), f"{p}_rresp": Out(2),
        f"{p}_rlast": Out(1), f"{p}_rvalid": Out(1), f"{p}_rready": In(1),
    }


def lint_waivers(top: str) -> str:
    """A paragraph of Verilator waivers (``TOP.vlt`` syntax) for the one thing the front end leaves
    unread on purpose, the byte offset ``AxADDR[1:0]``; a core appends it to its waivers."""
    f = f'-file "*{top}.v"'
    lines = ["// The AXI4 front end addresses words: it does not read the byte offset AxADDR[1:0]",
             "// (write strobes select the bytes; a read returns the whole word)."]
    lines += [f"lint_off -rule UNUSEDSIGNAL {f} -match \"Bits of signal are not used: '*s_axi_{c}addr'?1:0?\""
              for c in ("aw", "ar")]
    return "\n".join(lines) + "\n"


def forward(m: Module, outer: wiring.Component, inner: wiring.Component, members: dict) -> None:
    """Connect the flat ports ``members`` of ``outer`` (a core's top) to the same-named ports of
    ``inner`` (its :class:`Axi4Slave`): flat vendor names cannot go through ``wiring.connect``."""
    for name, member in members.items():
        if member.flow == In:
            m.d.comb += getattr(inner, name).eq(getattr(outer, name))
        else:
            m.d.comb += getattr(outer, name).eq(getattr(inner, name))


class Axi4Slave(wiring.Component):
    """AXI4 slave front end of a word back end (see the module docstring for every decision).

    Parameters
    ----------
    addr_width : int
        AXI byte-address width, 3..64.
    id_width : int
        ``AxID``/``xID`` width, 1..32.
    read_latency : 1 or 2
        The back end's (:class:`WordBusSignature`).

    Members
    -------
    s_axi_aw*, s_axi_w*, s_axi_b*, s_axi_ar*, s_axi_r*
        The AXI4 slave port (:func:`axi4_slave_members`), 32-bit data.
    bus : Out(WordBusSignature(addr_width - 2, read_latency))
        To the back end.

    Latency and throughput: reads, AR handshake to first R beat ``1 + read_latency`` cycles,
    then one beat per clock and back-to-back bursts; writes, one beat per clock from the cycle
    after the AW handshake, B one cycle after the last beat, N + 1 cycles per N-beat burst.
    The back end's read port is enabled only when the R channel has room for its answer, so
    ``RREADY`` low stalls it.
    """

    def __init__(self, addr_width: int = 16, id_width: int = 4, read_latency: int = 1):
        if not isinstance(addr_width, int) or not 3 <= addr_width <= 64:
            raise ValueError(f"addr_width must be an integer from 3 to 64, not {addr_width!r}")
        if not isinstance(id_width, int) or not 1 <= id_width <= 32:
            raise ValueError(f"id_width must be an integer from 1 to 32, not {id_width!r}")
        self._addr_width = addr_width
        self._id_width = id_width
        self._read_latency = read_latency
        super().__init__({
            **axi4_slave_members(addr_width, id_width),
            "bus": Out(WordBusSignature(addr_width - 2, read_latency)),
        })

    @property
    def addr_width(self) -> int:
        return self._addr_width

    @property
    def id_width(self) -> int:
        return self._id_width

    @property
    def read_latency(self) -> int:
        return self._read_latency

    def _refused(self, addr, length, size, burst):
        """Burst-level error: unsupported type or size, or an INCR burst leaving its 4 KB page."""
        page_bits = min(12, self._addr_width) - 2  # word-address bits within a page
        first = addr[2:2 + page_bits]
        crosses = (first + length)[page_bits:] != 0
        return ((size != FULL_SIZE) | ((burst != Burst.INCR) & (burst != Burst.FIXED))
                | ((burst == Burst.INCR) & crosses))

    def elaborate(self, platform):
        m = Module()
        aw = self.addr_width - 2
        bus = self.bus

        # ------------------------------------------------------------------ read channel
        # Burst state: while `r_active`, the registers hold the next beat to issue; otherwise the
        # AR inputs do (an address is issued in the cycle it is accepted).
        r_active = Signal()
        r_addr = Signal(aw)
        r_left = Signal(8)          # beats after the one at r_addr
        r_id = Signal(self.id_width)
        r_bad = Signal()            # burst-level error
        r_fixed = Signal()
        h_valid, h_addr, h_left, h_id, h_bad, h_fixed = (
            Signal(), Signal(aw), Signal(8), Signal(self.id_width), Signal(), Signal())
        with m.If(r_active):
            m.d.comb += [h_valid.eq(1), h_addr.eq(r_addr), h_left.eq(r_left), h_id.eq(r_id),
                         h_bad.eq(r_bad), h_fixed.eq(r_fixed)]
        with m.Else():
            m.d.comb += [
                h_valid.eq(self.s_axi_arvalid),
                h_addr.eq(self.s_axi_araddr[2:]),
                h_left.eq(self.s_axi_arlen),
                h_id.eq(self.s_axi_arid),
                h_bad.eq(self._refused(self.s_axi_araddr, self.s_axi_arlen, self.s_axi_arsize,
                                       self.s_axi_arburst)),
                h_fixed.eq(self.s_axi_arburst == Burst.FIXED),
            ]
        m.d.comb += self.s_axi_arready.eq(~r_active)

        # Answers in flight: the back-end reads pending (`p_*`, one stage per cycle of read
        # latency L), the R output register and L skid entries (`s_*`, a queue). A read issues
        # only when at most L of them stay occupied after this cycle, so every answer finds
        # room, and the R channel still streams one beat a clock.
        lat = self._read_latency
        idw = self.id_width
        p = [SimpleNamespace(valid=Signal(name=f"p{i}_valid"), last=Signal(name=f"p{i}_last"),
                             id=Signal(idw, name=f"p{i}_id"), bad=Signal(name=f"p{i}_bad"))
             for i in range(lat)]
        skid = [SimpleNamespace(last=Signal(name=f"s{i}_last"), id=Signal(idw, name=f"s{i}_id"),
                                resp=Signal(2, name=f"s{i}_resp"), data=Signal(DATA_WIDTH, name=f"s{i}_data"))
                for i in range(lat)]
        s_count = Signal(range(lat + 1))
        r_out_taken = self.s_axi_rvalid & self.s_axi_rready
        kept = Signal(range(2 * lat + 3))
        m.d.comb += kept.eq(sum(q.valid for q in p) + self.s_axi_rvalid + s_count - r_out_taken)
        issue = Signal()
        m.d.comb += [
            issue.eq(h_valid & (kept <= lat) & (h_bad | ~bus.r_wait)),
            bus.r_en.eq(issue & ~h_bad),
            bus.r_addr.eq(h_addr),
        ]
        m.d.sync += p[0].valid.eq(issue)
        with m.If(issue):
            m.d.sync += [p[0].last.eq(h_left == 0), p[0].id.eq(h_id), p[0].bad.eq(h_bad)]
            with m.If(h_left == 0):
                m.d.sync += r_active.eq(0)
            with m.Else():
                m.d.sync += [r_active.eq(1), r_left.eq(h_left - 1),
                             r_addr.eq(Mux(h_fixed, h_addr, h_addr + 1))]
            with m.If(~r_active):
                m.d.sync += [r_id.eq(h_id), r_bad.eq(h_bad), r_fixed.eq(h_fixed)]
        with m.Elif(h_valid & ~r_active):  # accepted, not yet issued
            m.d.sync += [r_active.eq(1), r_addr.eq(h_addr), r_left.eq(h_left), r_id.eq(h_id),
                         r_bad.eq(h_bad), r_fixed.eq(h_fixed)]
        for a, b in zip(p, p[1:]):
            m.d.sync += [b.valid.eq(a.valid), b.last.eq(a.last), b.id.eq(a.id), b.bad.eq(a.bad)]

        # The answer arriving (the last pending stage), as an R beat.
        ans = p[-1]
        a_err = ans.bad | bus.r_err
        a_resp = Mux(a_err, Resp.SLVERR, Resp.OKAY)
        a_data = Mux(a_err, 0, bus.r_data)

        def load_r(last, rid, resp, rdata):
            return [self.s_axi_rvalid.eq(1), self.s_axi_rlast.eq(last), self.s_axi_rid.eq(rid),
                    self.s_axi_rresp.eq(resp), self.s_axi_rdata.eq(rdata)]

        # R takes the skid queue's head first, else the answer; an answer R does not take
        # joins the queue's tail (there is room: see the issue rule).
        r_free = ~self.s_axi_rvalid | self.s_axi_rready
        pop = Signal()
        push = Signal()
        m.d.comb += [pop.eq(r_free & (s_count != 0)), push.eq(ans.valid & ~(r_free & (s_count == 0)))]
        m.d.sync += s_count.eq(s_count - pop + push)
        tail = Signal.like(s_count)
        m.d.comb += tail.eq(s_count - pop)
        for i, entry in enumerate(skid):
            with m.If(push & (tail == i)):
                m.d.sync += [entry.last.eq(ans.last), entry.id.eq(ans.id), entry.resp.eq(a_resp),
                             entry.data.eq(a_data)]
            if i + 1 < lat:
                with m.Elif(pop):
                    nxt = skid[i + 1]
                    m.d.sync += [entry.last.eq(nxt.last), entry.id.eq(nxt.id), entry.resp.eq(nxt.resp),
                                 entry.data.eq(nxt.data)]
        with m.If(r_free):
            with m.If(s_count != 0):
                m.d.sync += load_r(skid[0].last, skid[0].id, skid[0].resp, skid[0].data)
            with m.Elif(ans.valid):
                m.d.sync += load_r(ans.last, ans.id, a_resp, a_data)
            with m.Else():
                m.d.sync += self.s_axi_rvalid.eq(0)

        # ------------------------------------------------------------------ write channel
        w_active = Signal()
        w_addr = Signal(aw)
        w_left = Signal(8)
        w_bad = Signal()
        w_fixed = Signal()
        w_id = Signal(self.id_width)
        w_erred = Signal()   # some beat of this burst erred
        m.d.comb += [
            self.s_axi_awready.eq(~w_active),
            # The last beat waits while B still holds the previous burst's response.
            self.s_axi_wready.eq(w_active & ~((w_left == 0) & self.s_axi_bvalid)),
        ]
        with m.If(self.s_axi_awvalid & self.s_axi_awready):
            m.d.sync += [
                w_active.eq(1),
                w_addr.eq(self.s_axi_awaddr[2:]),
                w_left.eq(self.s_axi_awlen),
                w_id.eq(self.s_axi_awid),
                w_bad.eq(self._refused(self.s_axi_awaddr, self.s_axi_awlen, self.s_axi_awsize,
                                       self.s_axi_awburst)),
                w_fixed.eq(self.s_axi_awburst == Burst.FIXED),
                w_erred.eq(0),
            ]

        beat = self.s_axi_wvalid & self.s_axi_wready
        m.d.comb += [
            bus.w_en.eq(beat & ~w_bad),
            bus.w_addr.eq(w_addr),
            bus.w_data.eq(self.s_axi_wdata),
            bus.w_strb.eq(self.s_axi_wstrb),
        ]
        beat_err = w_bad | bus.w_err
        with m.If(self.s_axi_bvalid & self.s_axi_bready):
            m.d.sync += self.s_axi_bvalid.eq(0)
        with m.If(beat):
            m.d.sync += w_erred.eq(w_erred | beat_err)
            with m.If(w_left == 0):
                m.d.sync += [w_active.eq(0), self.s_axi_bvalid.eq(1), self.s_axi_bid.eq(w_id),
                             self.s_axi_bresp.eq(Mux(w_erred | beat_err, Resp.SLVERR, Resp.OKAY))]
            with m.Else():
                m.d.sync += [w_left.eq(w_left - 1), w_addr.eq(Mux(w_fixed, w_addr, w_addr + 1))]
        self._formal_state = SimpleNamespace(
            w_active=w_active, w_addr=w_addr, w_left=w_left, w_bad=w_bad, w_fixed=w_fixed, w_id=w_id,
            w_erred=w_erred, r_active=r_active, r_addr=r_addr, r_left=r_left, r_id=r_id, r_bad=r_bad,
            r_fixed=r_fixed, pending=p, skid=skid, skid_count=s_count)
        return m

    @property
    def formal_state(self) -> SimpleNamespace:
        """The channels' registers of the last elaboration (write: ``w_active``, ``w_addr``,
        ``w_left``, ``w_bad``, ``w_fixed``, ``w_id``, ``w_erred``; read: ``r_*`` alike, the
        ``pending`` back-end reads, oldest last, and the ``skid`` queue of ``skid_count``
        answers), for the formal proofs' induction
        (:class:`kfgen.hdl.bus.formal.Axi4Properties`); ``None`` before one."""
        return getattr(self, "_formal_state", None)
