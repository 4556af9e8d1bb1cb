"""Fault campaigns on an engine core's bus (the UKF's and the IMM's testbenches run them).

Each sequence is a seeded random run of what software and a system can do to the core: reads
and writes anywhere in the aperture (registers, every region, holes, bursts that run across a
region's end or out of the buffer), byte strobes that are not whole, ``start`` of any step at
any moment (while busy too), soft resets by ``CTRL.reset``, ``STATUS`` clears, ``IRQ_ENABLE``
changes, idle gaps, and bus resets (``rst``) that abort a burst in flight. Every response is
checked against the map's rules wherever the core's state makes it certain (a write beat that
may meet the end of a step may be either), and every word read from an ``input`` region (which
only software writes) must be the last word written there, or not yet known: nothing reads back
that was not written. After each sequence the core must come idle within the watchdog's bound
and run ``clean`` (a whole iteration from freshly loaded inputs, every word against the golden
model). Nothing may hang: every sequence and its clean iteration run under a time limit.

Environment: ``KFGEN_TB_SEQUENCES`` (default 20) and ``KFGEN_TB_SEED``.
"""

from __future__ import annotations

import os

import cocotb
from cocotb.triggers import ClockCycles, with_timeout
from cocotbext.axi import AxiResp

from .watchdog import bound

__all__ = ["engine_campaign"]

class _Map:
    """The manifest's map as the campaign needs it: what a word address is."""

    def __init__(self, manifest):
        self.size = manifest["bus"]["size"]
        self.regs = {r["name"]: r for r in manifest["registers"]}
        self.words = {}  # byte address -> ("reg", name) or ("mem", name, access, role)
        for r in manifest["registers"]:
            for k in range(r.get("width", 32) // 32):
                self.words[r["offset"] + 4 * k] = ("reg", r["name"])
        self.regions = []
        for mm in manifest["memories"]:
            n = mm["shape"][0] * mm["shape"][1] * mm["words_per_element"]
            self.regions.append((mm["offset"], mm["offset"] + 4 * n, mm["name"]))
            for k in range(n):
                self.words[mm["offset"] + 4 * k] = ("mem", mm["name"], mm["access"], mm.get("role", ""))
        self.end = max(e for _, e, _ in self.regions)

    def what(self, addr):
        return self.words.get(addr)


async def engine_campaign(tb, clean, clock_ns: int, sequences: int | None = None):
    """Run ``sequences`` fault sequences on ``tb`` (a :class:`kfgen.sim.engine.tb.TB`, its clock
    period ``clock_ns``), each followed by ``await clean(tb)``; the counts of what was done,
    for the log."""
    sequences = int(os.environ.get("KFGEN_TB_SEQUENCES", "20")) if sequences is None else sequences
    amap, rng, axi, dut = _Map(tb.manifest), tb.rng, tb.axi, tb.dut
    cycles = tb.manifest["cycles"]
    steps = list(cycles)
    longest = max(cycles.values())
    shadow = {}  # input-region byte address -> last word certainly written (None: unknown)
    state = {"lo": 0, "hi": 0}  # a step started by the campaign ends within [lo, hi] (cycles)
    counts = dict.fromkeys(("read", "write", "start", "refused_start", "soft_reset", "bus_reset",
                            "uncertain", "checked_words"), 0)

    def busy_for_sure(at, span):
        return at + span < state["lo"]

    def idle_for_sure(at):
        return at > state["hi"] + 4

    def page_beats(addr):
        """The most beats an INCR burst from ``addr`` takes without leaving its 4 KB page (or
        the aperture)."""
        return (min(amap.size, (addr // 4096 + 1) * 4096) - addr) // 4

    def random_address():
        pick = rng.random()
        if pick < 0.15:  # a register or the words around them
            return int(rng.integers(0, 0x20)) & ~3
        if pick < 0.25:  # a hole: between the registers and the buffer, past the buffer
            return int(rng.choice([0x40, amap.end, amap.end + 4 * int(rng.integers(0, 8)),
                                   amap.size - 4]))
        lo, hi, _ = amap.regions[int(rng.integers(len(amap.regions)))]
        if rng.random() < 0.3:  # near a region's end: bursts run across it
            return max(lo, hi - 4 * int(rng.integers(1, 4)))
        return lo + 4 * int(rng.integers(0, (hi - lo) // 4))

    async def do_read():
        addr = random_address()
        beats = int(rng.integers(1, 9))
        beats = min(beats, page_beats(addr))
        got = await axi.read(addr, 4 * beats)
        kinds = [amap.what(addr + 4 * i) for i in range(beats)]
        want = AxiResp.SLVERR if any(k is None for k in kinds) else AxiResp.OKAY
        assert got.resp == want, ("read", hex(addr), beats, got.resp, want)
        for i, k in enumerate(kinds):
            word = int.from_bytes(got.data[4 * i:4 * i + 4], "little")
            if k is None:
                assert word == 0 or want == AxiResp.OKAY, ("a hole read non-zero", hex(addr + 4 * i))
            elif k[0] == "mem" and k[3] == "input" and shadow.get(addr + 4 * i) is not None:
                assert word == shadow[addr + 4 * i], ("read back what was not written", hex(addr + 4 * i),
                                                      hex(word), hex(shadow[addr + 4 * i]))
                counts["checked_words"] += 1
        counts["read"] += 1

    async def do_write():
        addr = random_address()
        if amap.what(addr) == ("reg", "CTRL"):
            addr = amap.regs["STATUS"]["offset"]  # CTRL is written by the start and reset ops
        beats = min(int(rng.integers(1, 9)), page_beats(addr))
        kinds = [amap.what(addr + 4 * i) for i in range(beats)]
        if any(k == ("reg", "CTRL") for k in kinds):
            beats = kinds.index(("reg", "CTRL"))
            kinds = kinds[:beats]
            if not beats:
                return
        words = [int(w) for w in rng.integers(0, 1 << 32, beats, dtype="uint64")]
        partial = beats == 1 and rng.random() < 0.2
        data = b"".join(w.to_bytes(4, "little") for w in words)
        at = tb.now()
        if partial:  # one byte lane of one word (an unaligned byte address: AXI's strobes)
            lane = int(rng.integers(0, 4))
            resp = (await axi.write(addr + lane, data[lane:lane + 1])).resp
        else:
            resp = (await axi.write(addr, data)).resp
        busy = True if busy_for_sure(at, 4 * beats + 16) else False if idle_for_sure(at) else None
        errs = []
        for k in kinds:
            if k is None or (k[0] == "reg" and k[1] in ("ID",)):
                errs.append(True)
            elif k[0] == "reg":
                errs.append(False)
            else:
                errs.append(True if (k[2] == "ro" or partial or busy) else None if busy is None else False)
        if any(e is True for e in errs):
            assert resp == AxiResp.SLVERR, ("write", hex(addr), beats, resp)
        elif all(e is False for e in errs):
            assert resp == AxiResp.OKAY, ("write", hex(addr), beats, resp)
        else:
            counts["uncertain"] += 1
        for i, k in enumerate(kinds):  # the input regions' shadow
            if k and k[0] == "mem" and k[3] == "input":
                a = addr + 4 * i
                if errs[i] is False:
                    shadow[a] = words[i]
                elif errs[i] is None:
                    shadow[a] = None
        counts["write"] += 1

    async def do_start():
        name = steps[int(rng.integers(len(steps)))]
        at = tb.now()
        resp = await tb.start(name)
        if busy_for_sure(at, 16):
            assert resp == AxiResp.SLVERR, ("start while busy", name, resp)
            counts["refused_start"] += 1
        elif idle_for_sure(at):
            assert resp == AxiResp.OKAY, ("start while idle", name, resp)
        if resp == AxiResp.OKAY:
            now = tb.now()
            state["lo"], state["hi"] = now - 16 + cycles[name], now + cycles[name]
        counts["start"] += 1

    async def do_soft_reset():
        resp = await tb.write_reg("CTRL", tb.bits("CTRL", reset=1))
        assert resp == AxiResp.OKAY
        state["lo"] = state["hi"] = tb.now()
        counts["soft_reset"] += 1

    async def do_bus_reset():
        """A burst in flight, then ``rst`` at a random cycle: the master's operation is
        dropped, the core comes back from reset."""
        lo, hi, _ = amap.regions[int(rng.integers(len(amap.regions)))]
        beats = min(16, (hi - lo) // 4)
        task = cocotb.start_soon(axi.write(lo, bytes(4 * beats)) if rng.random() < 0.5 else axi.read(lo, 4 * beats))
        await ClockCycles(dut.clk, int(rng.integers(1, 2 * beats)))
        dut.rst.value = 1
        await ClockCycles(dut.clk, 2)
        dut.rst.value = 0
        await ClockCycles(dut.clk, 1)
        if not task.done():
            task.cancel()
        for a in list(shadow):  # a write cut short left some of its words
            if lo <= a < hi:
                shadow[a] = None
        state["lo"] = state["hi"] = tb.now()
        counts["bus_reset"] += 1

    async def do_misc():
        if rng.random() < 0.5:
            await tb.write_reg("STATUS", int(rng.integers(0, 1 << 32)))
        else:
            await ClockCycles(dut.clk, int(rng.integers(1, 3 * longest // 2)))

    ops = [(do_read, 0.3), (do_write, 0.3), (do_start, 0.15), (do_soft_reset, 0.05), (do_bus_reset, 0.05),
           (do_misc, 0.15)]
    funcs, weights = [f for f, _ in ops], [w for _, w in ops]

    async def sequence():
        for _ in range(int(rng.integers(4, 12))):
            await funcs[int(rng.choice(len(funcs), p=weights))]()
        # whatever ran: idle within the watchdog's bound, then a clean iteration
        limit = bound(longest)
        busy_bit = tb.field("STATUS", "busy")["lsb"]
        start = tb.now()
        while await tb.read_reg("STATUS") >> busy_bit & 1:
            assert tb.now() - start <= limit, "the core stayed busy past the watchdog's bound"
            await ClockCycles(dut.clk, 16)
        await tb.write_reg("STATUS", 0xFFFF_FFFF)
        enable = tb.bits("IRQ_ENABLE", done=1, err_pivot=1, err_nan=1, err_busy=1)
        assert await tb.write_reg("IRQ_ENABLE", enable) == AxiResp.OKAY  # (a bus reset cleared it)
        state["lo"] = state["hi"] = tb.now()
        await clean(tb)
        for mm in tb.manifest["memories"]:  # clean wrote the inputs: the golden memory has them
            if mm.get("role") == "input" and mm["words_per_element"] == 1:
                base = tb.layout[mm["name"]].base
                for k in range(tb.layout[mm["name"]].size):
                    shadow[mm["offset"] + 4 * k] = int(tb.gold[base + k])

    # a sequence and its clean iteration, at most this many cycles (a hang is a failure)
    limit = 12 * (2 * longest + 400) + bound(longest) + 4 * sum(bound(c) for c in cycles.values()) + 50_000
    for _ in range(sequences):
        await with_timeout(sequence(), limit * clock_ns, "ns")
    return counts
