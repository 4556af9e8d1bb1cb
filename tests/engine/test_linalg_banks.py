"""The engine's banked operand memory alone: the bus read's retry rule in Amaranth's simulator,
and each bank one true dual-port block RAM under Yosys for Xilinx and for ECP5."""

import re
import subprocess

import pytest
from amaranth.sim import Simulator

from kfgen.gen.verilog import emit
from kfgen.hdl.linalg.banks import BUS_READ_LATENCY, BankedMemory
from kfgen.hdl.linalg.microcode import LANE_READ_LATENCY, Geometry
from kfgen.sim.toolchain import yosys_cmd

G = Geometry(size=64, banks=2)
INIT = [0x100 + a for a in range(G.size)]


def banks():
    """Two unit read lanes and a bus read lane, two unit write lanes (one unit's result and
    its mirror: one group) and the bus write lane."""
    return BankedMemory(G, 32, INIT, reads=3, writes=3, groups=[0, 0, 1])


def test_lanes_ports_and_bus_retry():
    """The engine's lanes reach the RAM a cycle after their request on the port they name,
    and a read's word is on its lane LANE_READ_LATENCY cycles after it; reads of one word share a
    port. The bus's lanes take a port the engine leaves free (its write a cycle after the
    request, its read in that cycle, its word two cycles later); a bus read of a word some
    lane writes in that RAM cycle, of a bank some engine lane writes then, or whose bank has
    no free port, is not served (its block-RAM word would be undefined, or there is no
    port); the retry reads the new word. A flush drops the requests of its cycle."""
    dut = banks()
    unit_rd, bus_rd = dut.rd[:2], dut.rd[-1]
    unit_wr, bus_wr = dut.wr[:2], dut.wr[-1]
    assert LANE_READ_LATENCY == 3 and BUS_READ_LATENCY == 2

    async def tb(ctx):
        log = []  # per cycle: (rd_ok, bus data after the cycle, unit lanes' data after it)
        words = []  # (cycle of a bus read, the word it must give): checked at the end

        async def cycle(flush=0, **lanes):
            for lane in (*dut.rd, *dut.wr):
                ctx.set(lane.en, 0)
            ctx.set(dut.flush, flush)
            for lane, a, *rest in lanes.values():
                ctx.set(lane.en, 1)
                ctx.set(lane.addr.bank, G.addr(a)["bank"])
                ctx.set(lane.addr.row, G.addr(a)["row"])
                port, *data = rest or [0]
                ctx.set(lane.port, port)
                if data:
                    ctx.set(lane.data, data[0])
            ok = ctx.get(dut.rd_ok)
            await ctx.tick()
            log.append((ok, ctx.get(bus_rd.data), [ctx.get(r.data) for r in unit_rd]))
            return ok

        async def read(a, word, **lanes):
            """A bus read of ``a`` (with other lanes) that is served and gives ``word``."""
            assert await cycle(bus=(bus_rd, a), **lanes) == 1
            words.append((len(log) - 1, word))

        await read(5, 0x105)
        # the engine writes word 6: in the RAM the next cycle, when a bus read of it retries
        await cycle(w=(unit_wr[0], 6, 1, 0xAAAA))
        assert await cycle(bus=(bus_rd, 6)) == 0
        await read(6, 0xAAAA)
        # the bus writes word 8 while it reads it (a read and a write burst meeting): the
        # write is registered, so the read takes the old word; the next one retries
        await read(8, 0x108, w=(bus_wr, 8, 0, 0xBBBB))
        assert await cycle(bus=(bus_rd, 8)) == 0
        await read(8, 0xBBBB)
        # two engine reads of word 12 on port 1 (a broadcast), then a bus read of word 10 of
        # the same bank takes port 0 beside them; the engine's word three cycles later
        n = len(log)
        await cycle(r0=(unit_rd[0], 12, 1), r1=(unit_rd[1], 12, 1))
        await read(10, 0x10A)
        await cycle()
        assert log[n + 2][2] == [0x10C, 0x10C]
        # an engine read (port 1) and write (port 0) of other words of a bank: the bus's read
        # of that bank is not served; the engine's read and write are
        n = len(log)
        await cycle(r0=(unit_rd[0], 16, 1), w=(unit_wr[0], 18, 0, 0xDDDD))
        assert await cycle(bus=(bus_rd, 14)) == 0
        await cycle()
        assert log[n + 2][2][0] == 0x110
        await read(18, 0xDDDD)
        # a write requested with flush high is dropped
        await cycle(flush=1, w=(unit_wr[0], 20, 0, 0xEEEE))
        await cycle()
        await read(20, 0x114)
        # an engine write of a bank (port 0) leaves port 1 free, but the bus's read of another
        # word of that bank waits for the bank to be written (the decision is a bank's, not a
        # word's); a read of the other bank in that cycle is served
        await cycle(w=(unit_wr[0], 22, 0, 0xFFFF))
        assert await cycle(bus=(bus_rd, 24)) == 0
        await read(24, 0x118)
        await cycle(w=(unit_wr[0], 26, 0, 0x1234))
        await read(25, 0x119)
        for _ in range(BUS_READ_LATENCY - 1):
            await cycle()
        # a bus read's word is on data BUS_READ_LATENCY cycles after its request
        assert [log[k + BUS_READ_LATENCY - 1][1] for k, _ in words] == [w for _, w in words]

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(tb)
    sim.run()


@pytest.fixture(scope="module")
def stats(tmp_path_factory):
    """Cell counts of the banks' Verilog after ``synth_xilinx`` and ``synth_ecp5``."""
    out = tmp_path_factory.mktemp("banks")
    (out / "banks.v").write_text(emit(banks(), "banks", ["banks"]))
    procs = {}
    for family in ("xilinx", "ecp5"):  # both at once: each Yosys is single-threaded
        script = f"read_verilog banks.v; synth_{family} -flatten -top banks; tee -q -o stat_{family}.txt stat"
        procs[family] = subprocess.Popen([*yosys_cmd(), "-q", "-p", script], cwd=out, text=True,
                                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    counts = {}
    for family, proc in procs.items():
        log, _ = proc.communicate()
        assert proc.returncode == 0, log[-3000:]
        text = (out / f"stat_{family}.txt").read_text()
        counts[family] = {c: int(n) for n, c in re.findall(r"^\s+(\d+)\s+(\w+)\s*$", text, re.M)}
    return counts


@pytest.mark.parametrize("family, ram, per_bank, ff", [
    ("ecp5", "DP16KD", 2, "TRELLIS_FF"),  # 32 bits: two 18-bit wide halves
    ("xilinx", "RAMB36E1", 1, "FDRE"),  # 32 bits on both ports: a RAMB18's TDP is 18 wide
])
@pytest.mark.xdist_group("linalg_banks")
def test_each_bank_is_one_block_ram(stats, family, ram, per_bank, ff):
    """Each bank a true dual-port block RAM (both ports reading and writing), not flip-flops:
    the only registers left are the lanes' and the ports' (257: per engine read lane its row,
    bank, port, port hits and data select twice, 15; per engine write lane its row and port
    hits, 9, and one word for the unit; the bus's write, 39; the bus read's data select
    twice, 4; the ports taken and the banks written, 6; each port's word, 128),
    far below the 2,048 bits of the memory."""
    cells = stats[family]
    assert cells.get(ram, 0) == per_bank * G.banks, cells
    assert cells.get(ff, 0) <= 257, cells
