"""cocotb testbench of the AXI4 slave front end (:mod:`kfgen.hdl.bus.axi4`) on the test top that
:mod:`test_axi4` builds: the front end over 512 words of memory, a read/write register, a
read-only register and holes. cocotbext-axi's ``AxiMaster`` drives it, with and without idle
cycles and backpressure on every channel; a few cases that a well-behaved master cannot make (a
burst across 4 KB, a beat with no strobes) and the cycle counts are driven by hand.

Every test compares with :class:`Model`, a byte-level model of the address map, and checks the
R and B channels' handshake rules every clock.
"""

import itertools
import logging
import os

import cocotb
import numpy as np
from cocotb.clock import Clock
from cocotb.triggers import FallingEdge, ReadOnly, RisingEdge
from cocotbext.axi import AxiBurstType, AxiBus, AxiMaster, AxiResp

from kfgen.sim.streams import StreamChecker

ADDR_WIDTH = 16
ID_WIDTH = 4
# Unmapped 0x0000 .. 0x07ff; memory up to the 4 KB boundary, registers just after it, and
# nothing else.
MEM = 0x0800
MEM_WORDS = 512
SCRATCH = 0x1000             # read/write register
ID = 0x1004                  # read-only register
ID_VALUE = 0x4B464158        # "KFAX"


class Model:
    """The test top's address map, byte by byte; what every access must answer."""

    def __init__(self):
        self.mem = bytearray(4 * MEM_WORDS)
        self.scratch = bytearray(4)

    def _word(self, addr):
        """The bytearray and offset holding the word at ``addr``, whether writes are allowed;
        ``None`` if nothing is mapped there."""
        addr &= ~3
        if MEM <= addr < MEM + 4 * MEM_WORDS:
            return self.mem, addr - MEM, True
        if addr == SCRATCH:
            return self.scratch, 0, True
        if addr == ID:
            return bytearray(ID_VALUE.to_bytes(4, "little")), 0, False
        return None

    def read_word(self, addr):
        """(data bytes, ok) of one beat."""
        where = self._word(addr)
        if where is None:
            return bytes(4), False
        buf, off, _ = where
        return bytes(buf[off:off + 4]), True

    def write_beat(self, addr, data, strb):
        """Apply one beat; whether it answered OKAY."""
        where = self._word(addr)
        if where is None or not where[2]:
            return False
        buf, off, _ = where
        for i in range(4):
            if strb >> i & 1:
                buf[off + i] = data[i]
        return True

    def incr_read(self, addr, length):
        """(bytes, resp) of an INCR read of ``length`` bytes from ``addr`` as AxiMaster splits it."""
        out, ok = bytearray(), True
        for word in range(addr & ~3, addr + length, 4):
            data, good = self.read_word(word)
            out += data
            ok &= good
        skip = addr & 3
        return bytes(out[skip:skip + length]), AxiResp.OKAY if ok else AxiResp.SLVERR

    def incr_write(self, addr, data):
        """Apply an INCR write of ``data`` at ``addr`` as AxiMaster makes it; the response."""
        ok = True
        end = addr + len(data)
        for word in range(addr & ~3, end, 4):
            beat, strb = bytearray(4), 0
            for i in range(4):
                if addr <= word + i < end:
                    beat[i] = data[word + i - addr]
                    strb |= 1 << i
            ok &= self.write_beat(word, beat, strb)
        return AxiResp.OKAY if ok else AxiResp.SLVERR


class TB:
    def __init__(self, dut, master=True):
        self.dut = dut
        self.rng = np.random.default_rng(int(os.environ.get("KFGEN_TB_SEED", "1")))
        self.model = Model()
        self.cycle = 0
        cocotb.start_soon(Clock(dut.clk, 10, unit="ns").start())
        self.axi = None
        if master:
            self.axi = AxiMaster(AxiBus.from_prefix(dut, "s_axi"), dut.clk, dut.rst)
            logging.getLogger(f"cocotb.{dut._name}.s_axi").setLevel(logging.WARNING)
        else:
            for name in ("awvalid", "wvalid", "arvalid"):
                getattr(dut, f"s_axi_{name}").value = 0
            dut.s_axi_bready.value = 1
            dut.s_axi_rready.value = 1
        self.checkers = [
            StreamChecker("R", dut.s_axi_rvalid, dut.s_axi_rready,
                          {k: getattr(dut, f"s_axi_{k}") for k in ("rid", "rdata", "rresp", "rlast")}),
            StreamChecker("B", dut.s_axi_bvalid, dut.s_axi_bready,
                          {k: getattr(dut, f"s_axi_{k}") for k in ("bid", "bresp")}),
        ]
        #: cycle numbers of every handshake, by channel ("aw", "w", "b", "ar", "r")
        self.handshakes = {ch: [] for ch in ("aw", "w", "b", "ar", "r")}

    async def cycle_reset(self):
        self.dut.rst.value = 1
        for _ in range(3):
            await RisingEdge(self.dut.clk)
        self.dut.rst.value = 0
        await RisingEdge(self.dut.clk)
        cocotb.start_soon(self._monitor())

    async def _monitor(self):
        """Once a clock, in the settled phase before the rising edge: protocol checks, and the
        handshakes that edge will make, numbered by clock."""
        dut = self.dut
        while True:
            await FallingEdge(dut.clk)
            await ReadOnly()
            self.cycle += 1
            for checker in self.checkers:
                checker.sample(self.cycle)
            for ch in self.handshakes:
                if getattr(dut, f"s_axi_{ch}valid").value == 1 and getattr(dut, f"s_axi_{ch}ready").value == 1:
                    self.handshakes[ch].append(self.cycle)

    def set_idle(self, idle: bool):
        """Random idle cycles on the master's AW, W and AR (valid held low)."""
        for ch in (self.axi.write_if.aw_channel, self.axi.write_if.w_channel, self.axi.read_if.ar_channel):
            ch.set_pause_generator(self._random_pauses() if idle else None)

    def set_backpressure(self, on: bool):
        """Random backpressure on B and R (ready held low)."""
        for ch in (self.axi.write_if.b_channel, self.axi.read_if.r_channel):
            ch.set_pause_generator(self._random_pauses() if on else None)

    def _random_pauses(self):
        rng = np.random.default_rng(self.rng.integers(1 << 32))
        while True:
            yield bool(rng.random() < 0.4)

    def random_bytes(self, n):
        return bytes(self.rng.integers(0, 256, n, dtype=np.uint8))

    async def write(self, addr, data, **kw):
        resp = (await self.axi.write(addr, data, **kw)).resp
        return resp

    async def check_incr_write(self, addr, data):
        resp = await self.write(addr, data)
        expect = self.model.incr_write(addr, data)
        assert resp == expect, f"write {len(data)} bytes at {addr:#06x}: {resp!r}, expected {expect!r}"

    async def check_incr_read(self, addr, length):
        got = await self.axi.read(addr, length)
        data, resp = self.model.incr_read(addr, length)
        assert got.resp == resp, f"read {length} bytes at {addr:#06x}: {got.resp!r}, expected {resp!r}"
        assert got.data == data, f"read {length} bytes at {addr:#06x}:\n{got.data.hex()}\nexpected\n{data.hex()}"

    # ------------------------------------------------------------- hand-driven transfers
    # Driven in the settled phase before an edge, as the monitor samples, so handshakes are exact.

    async def _next(self):
        await FallingEdge(self.dut.clk)

    async def raw_write(self, addr, beats, strbs=None, awlen=None, size=2, burst=1, awid=3, wait_b=True):
        """One write burst: AW, then the beats back to back; returns bresp (``wait_b``)."""
        dut = self.dut
        strbs = strbs or [0xF] * len(beats)
        await self._next()
        dut.s_axi_awid.value = awid
        dut.s_axi_awaddr.value = addr
        dut.s_axi_awlen.value = len(beats) - 1 if awlen is None else awlen
        dut.s_axi_awsize.value = size
        dut.s_axi_awburst.value = burst
        dut.s_axi_awvalid.value = 1
        await ReadOnly()
        while dut.s_axi_awready.value != 1:
            await self._next()
            await ReadOnly()
        await self._next()
        dut.s_axi_awvalid.value = 0
        for i, (word, strb) in enumerate(zip(beats, strbs)):
            dut.s_axi_wdata.value = word
            dut.s_axi_wstrb.value = strb
            dut.s_axi_wlast.value = int(i == len(beats) - 1)
            dut.s_axi_wvalid.value = 1
            await ReadOnly()
            while dut.s_axi_wready.value != 1:
                await self._next()
                await ReadOnly()
            await self._next()
        dut.s_axi_wvalid.value = 0
        if not wait_b:
            return None
        await ReadOnly()
        while dut.s_axi_bvalid.value != 1:
            await self._next()
            await ReadOnly()
        assert int(dut.s_axi_bid.value) == awid
        return AxiResp(int(dut.s_axi_bresp.value))

    async def raw_read(self, addr, arlen, size=2, burst=1, arid=5):
        """One read burst; the (rdata, rresp) of every beat."""
        dut = self.dut
        await self._next()
        dut.s_axi_arid.value = arid
        dut.s_axi_araddr.value = addr
        dut.s_axi_arlen.value = arlen
        dut.s_axi_arsize.value = size
        dut.s_axi_arburst.value = burst
        dut.s_axi_arvalid.value = 1
        await ReadOnly()
        while dut.s_axi_arready.value != 1:
            await self._next()
            await ReadOnly()
        await self._next()
        dut.s_axi_arvalid.value = 0
        beats = []
        while True:
            await ReadOnly()
            if dut.s_axi_rvalid.value == 1:
                assert int(dut.s_axi_rid.value) == arid
                beats.append((int(dut.s_axi_rdata.value), AxiResp(int(dut.s_axi_rresp.value))))
                assert int(dut.s_axi_rlast.value) == (len(beats) == arlen + 1), f"rlast at beat {len(beats)}"
                if len(beats) == arlen + 1:
                    await self._next()
                    return beats
            await self._next()


async def setup(dut, idle=False, backpressure=False, master=True):
    """A TB after reset; with the master, memory and register cleared as the model starts (the
    simulation goes on from test to test)."""
    tb = TB(dut, master)
    await tb.cycle_reset()
    if master:
        await tb.check_incr_write(MEM, bytes(4 * MEM_WORDS))
        await tb.check_incr_write(SCRATCH, bytes(4))
        tb.set_idle(idle)
        tb.set_backpressure(backpressure)
    for ch in tb.handshakes.values():
        ch.clear()
    return tb


LENGTHS = [*range(1, 17), 256]


# ------------------------------------------------------------------------------- tests

@cocotb.test(timeout_time=2, timeout_unit="ms")
@cocotb.parametrize(idle=[False, True], backpressure=[False, True])
async def bursts(dut, idle, backpressure):
    """INCR bursts of 1..16 and 256 words, written then read back, at word and byte offsets."""
    tb = await setup(dut, idle, backpressure)
    for n in LENGTHS:
        base = MEM + 4 * int(tb.rng.integers(0, MEM_WORDS - n + 1))
        await tb.check_incr_write(base, tb.random_bytes(4 * n))
        await tb.check_incr_read(base, 4 * n)
    # byte offsets and lengths: partial strobes on the first and last words
    for offset, length in [(1, 1), (2, 2), (3, 5), (1, 10), (6, 17), (3, 64)]:
        base = MEM + 4 * int(tb.rng.integers(0, MEM_WORDS - 20)) + offset
        await tb.check_incr_write(base, tb.random_bytes(length))
        await tb.check_incr_read(base & ~3, (length + offset + 3) & ~3)
        await tb.check_incr_read(base, length)


@cocotb.test(timeout_time=2, timeout_unit="ms")
@cocotb.parametrize(idle=[False, True], backpressure=[False, True])
async def errors(dut, idle, backpressure):
    """SLVERR for unmapped addresses, the read-only register, WRAP and narrow bursts."""
    tb = await setup(dut, idle, backpressure)
    await tb.check_incr_write(MEM, tb.random_bytes(32))
    # unmapped: single beats, and bursts running from the hole into memory and past the registers
    for addr in (0x0000, MEM - 4, ID + 4, 0xFFFC):
        await tb.check_incr_write(addr, tb.random_bytes(4))
        await tb.check_incr_read(addr, 4)
    await tb.check_incr_write(MEM - 8, tb.random_bytes(16))  # two words dropped, two written
    await tb.check_incr_read(MEM - 16, 48)                   # 0 in the hole, data where mapped
    await tb.check_incr_write(SCRATCH, tb.random_bytes(16))  # SCRATCH written, the rest refused
    await tb.check_incr_read(SCRATCH, 16)
    # read-only
    await tb.check_incr_write(ID, tb.random_bytes(4))
    await tb.check_incr_read(ID, 4)
    await tb.check_incr_read(SCRATCH, 8)                    # OKAY: both registers readable
    # WRAP, and sizes other than the bus width: SLVERR on every beat, nothing written, data 0
    for burst, size in [(AxiBurstType.WRAP, 2), (AxiBurstType.INCR, 0), (AxiBurstType.INCR, 1),
                        (AxiBurstType.FIXED, 1)]:
        for addr, n in [(MEM + 0x100, 16), (SCRATCH, 4)]:
            resp = await tb.write(addr, tb.random_bytes(n), burst=burst, size=size)
            assert resp == AxiResp.SLVERR, (burst, size, resp)
            got = await tb.axi.read(addr, n, burst=burst, size=size)
            assert got.resp == AxiResp.SLVERR and got.data == bytes(n), (burst, size, got)
            await tb.check_incr_read(addr, n)               # unchanged


@cocotb.test(timeout_time=2, timeout_unit="ms")
async def fixed_bursts(dut):
    """A FIXED burst repeats its address: the last beat stays, every read beat is that word."""
    tb = await setup(dut, idle=True, backpressure=True)
    data = tb.random_bytes(16)
    resp = await tb.write(MEM + 0x40, data, burst=AxiBurstType.FIXED)
    assert resp == AxiResp.OKAY
    tb.model.incr_write(MEM + 0x40, data[12:])
    got = await tb.axi.read(MEM + 0x40, 16, burst=AxiBurstType.FIXED)
    assert got.resp == AxiResp.OKAY and got.data == data[12:] * 4, got
    await tb.check_incr_read(MEM + 0x40, 16)                # the next words untouched
    resp = await tb.write(SCRATCH, data, burst=AxiBurstType.FIXED)
    assert resp == AxiResp.OKAY
    tb.model.incr_write(SCRATCH, data[12:])
    await tb.check_incr_read(SCRATCH, 4)


@cocotb.test(timeout_time=2, timeout_unit="ms")
@cocotb.parametrize(paced=[False, True])
async def strobes(dut, paced):
    """Every strobe pattern on a memory word and on the register changes exactly those bytes."""
    tb = await setup(dut, idle=paced, backpressure=paced)
    for addr in (MEM + 0x200, SCRATCH):
        await tb.check_incr_write(addr, tb.random_bytes(4))
        for strb in range(16):
            beat = tb.random_bytes(4)
            offs = [i for i in range(4) if strb >> i & 1]
            if offs and offs == list(range(offs[0], offs[-1] + 1)):   # contiguous: AxiMaster makes it
                await tb.check_incr_write(addr + offs[0], beat[offs[0]:offs[-1] + 1])
            await tb.check_incr_read(addr, 4)


@cocotb.test(timeout_time=2, timeout_unit="ms")
async def raw_cases(dut):
    """What AxiMaster never sends: sparse and empty strobes, bursts across 4 KB, any arid/awid."""
    tb = await setup(dut, master=False)
    m = tb.model
    for addr in (MEM + 0x300, SCRATCH):
        word = int(tb.rng.integers(0, 1 << 32))
        assert await tb.raw_write(addr, [word]) == AxiResp.OKAY
        m.write_beat(addr, word.to_bytes(4, "little"), 0xF)
        for strb in (0x0, 0x5, 0xA, 0x9, 0xF):
            word = int(tb.rng.integers(0, 1 << 32))
            resp = await tb.raw_write(addr, [word], [strb])
            assert resp == AxiResp.OKAY, (addr, strb, resp)       # no strobes: OKAY, nothing written
            m.write_beat(addr, word.to_bytes(4, "little"), strb)
            (data, rresp), = await tb.raw_read(addr, 0)
            assert rresp == AxiResp.OKAY and data.to_bytes(4, "little") == m.read_word(addr)[0]
    # an INCR burst ending exactly on the 4 KB boundary is fine (memory's last two words)
    assert await tb.raw_write(0x0FF8, [7, 8], awid=0xF) == AxiResp.OKAY
    assert await tb.raw_read(0x0FF8, 1, arid=0) == [(7, AxiResp.OKAY), (8, AxiResp.OKAY)]
    # across it: SLVERR on every beat, nothing written (0x1000 and 0x1004 are registers)
    before = await tb.raw_read(SCRATCH, 1)
    assert await tb.raw_write(0x0FF8, [1, 2, 3, 4]) == AxiResp.SLVERR
    assert await tb.raw_read(0x0FF8, 3) == [(0, AxiResp.SLVERR)] * 4
    assert await tb.raw_read(0x0FF8, 1) == [(7, AxiResp.OKAY), (8, AxiResp.OKAY)]
    assert await tb.raw_read(SCRATCH, 1) == before
    # B held: the next burst's last beat waits for it, and both answers come, in order
    dut.s_axi_bready.value = 0
    await tb.raw_write(MEM, [1], awid=1, wait_b=False)
    second = cocotb.start_soon(tb.raw_write(MEM + 4, [2, 3], awid=2, wait_b=False))
    for _ in range(8):
        await FallingEdge(dut.clk)
    await ReadOnly()
    assert not second.done() and dut.s_axi_bvalid.value == 1 and int(dut.s_axi_bid.value) == 1
    await FallingEdge(dut.clk)
    dut.s_axi_bready.value = 1
    answers = []
    while len(answers) < 2:
        await ReadOnly()
        if dut.s_axi_bvalid.value == 1:
            answers.append((int(dut.s_axi_bid.value), AxiResp(int(dut.s_axi_bresp.value))))
        await FallingEdge(dut.clk)
    assert answers == [(1, AxiResp.OKAY), (2, AxiResp.OKAY)] and second.done(), answers
    assert await tb.raw_read(MEM, 2) == [(1, AxiResp.OKAY), (2, AxiResp.OKAY), (3, AxiResp.OKAY)]
    # the reserved burst type 3 and a size wider than the bus
    for burst, size in [(3, 2), (1, 3)]:
        assert await tb.raw_write(MEM, [9], burst=burst, size=size) == AxiResp.SLVERR
        assert await tb.raw_read(MEM, 0, burst=burst, size=size) == [(0, AxiResp.SLVERR)]


@cocotb.test(timeout_time=2, timeout_unit="ms")
async def throughput(dut):
    """With no idle cycles or backpressure a 16-beat burst takes the cycles the docstring
    guarantees: write beats in 16 consecutive cycles from the cycle after AW, B the cycle after;
    read beats in 16 consecutive cycles from 1 + L cycles after AR (L the back end's read
    latency), and back-to-back read bursts."""
    n = 16
    lat = int(os.environ.get("KFGEN_TB_READ_LATENCY", "1"))
    tb = await setup(dut)
    hs = tb.handshakes
    await tb.axi.write(MEM, tb.random_bytes(4 * n))
    (aw,) = hs["aw"]
    assert hs["w"] == list(range(aw + 1, aw + n + 1)), (aw, hs["w"])
    assert hs["b"] == [aw + n + 1], (aw, hs["b"])
    await tb.axi.read(MEM, 4 * n)
    (ar,) = hs["ar"]
    assert hs["r"] == list(range(ar + 1 + lat, ar + n + 1 + lat)), (ar, hs["r"])
    # two reads issued together: the second address is taken as the first burst's last beat is
    # issued, and the R channel never idles
    for ch in hs.values():
        ch.clear()
    first = tb.axi.init_read(MEM, 4 * n)
    second = tb.axi.init_read(MEM + 0x100, 4 * n)
    await first.wait()
    await second.wait()
    ar = hs["ar"][0]
    assert hs["ar"] == [ar, ar + n], hs["ar"]
    assert hs["r"] == list(range(ar + 1 + lat, ar + 2 * n + 1 + lat)), (ar, hs["r"])
    dut._log.info("16-beat burst: write AW->B %d cycles, read AR->last R %d cycles", n + 1, n + 1)


@cocotb.test(timeout_time=2, timeout_unit="ms")
@cocotb.parametrize(paced=[False, True])
async def stress(dut, paced):
    """Concurrent random reads and writes: four workers, each on its own part of memory, write
    random bursts and read them back while the others run; a fifth keeps reading the registers."""
    tb = await setup(dut, idle=paced, backpressure=paced)
    span = 4 * MEM_WORDS // 4
    done = []

    async def worker(k):
        rng = np.random.default_rng(k + 10)
        lo = MEM + k * span
        for _ in range(12):
            length = int(rng.integers(1, 65))
            addr = lo + int(rng.integers(0, span - length + 1))
            await tb.check_incr_write(addr, bytes(rng.integers(0, 256, length, dtype=np.uint8)))
            length = int(rng.integers(1, 129))
            addr = lo + int(rng.integers(0, span - length + 1))
            await tb.check_incr_read(addr, length)
        done.append(k)

    async def registers():
        while len(done) < 4:
            await tb.check_incr_read(SCRATCH, 8)

    tasks = [cocotb.start_soon(worker(k)) for k in range(4)] + [cocotb.start_soon(registers())]
    for task in tasks:
        await task
    for ch in ("aw", "ar"):
        assert len(tb.handshakes[ch]) > 40
    # reads and writes overlapped in time
    busy_w = set(itertools.chain(tb.handshakes["w"]))
    assert len(busy_w & set(tb.handshakes["r"])) > 20
