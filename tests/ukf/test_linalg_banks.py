"""The engine's banked operand memory alone: the bus read's retry rule in Amaranth's simulator,
and each bank one true dual-port block RAM under Yosys for Xilinx and for ECP5."""

import re
import subprocess

import pytest
from amaranth.sim import Simulator

from kfgen.gen.verilog import emit
from kfgen.hdl.linalg.banks import BankedMemory
from kfgen.hdl.linalg.microcode import Geometry
from kfgen.sim.toolchain import yosys_cmd

G = Geometry(size=64, banks=2)
INIT = [0x100 + a for a in range(G.size)]


def banks():
    """Two unit read lanes and a bus read lane, two unit write lanes (one unit's result and
    its mirror: one group) and the bus write lane."""
    return BankedMemory(G, 32, INIT, reads=3, writes=3, groups=[0, 0, 1])


def test_bus_read_of_a_word_written_retries():
    """A bus read of a word some lane writes in that cycle is not served (its block-RAM word
    is undefined); the retry reads the new word. Other bus reads are served beside writes."""
    dut = banks()
    unit_rd, bus_rd = dut.rd[0], dut.rd[-1]
    unit_wr, bus_wr = dut.wr[0], dut.wr[-1]

    def at(lane, a):
        return [(lane.en, 1), (lane.addr.bank, G.addr(a)["bank"]), (lane.addr.row, G.addr(a)["row"])]

    async def tb(ctx):
        async def cycle(**lanes):
            """One cycle of the lanes given; ``rd_ok`` then, and the bus's word after it."""
            for lane in (*dut.rd[:-1], *dut.wr):
                ctx.set(lane.en, 0)
            for name, (lane, a, *data) in lanes.items():
                for sig, v in at(lane, a):
                    ctx.set(sig, v)
                if data:
                    ctx.set(lane.data, data[0])
            ok = ctx.get(dut.rd_ok)
            await ctx.tick()
            return ok, ctx.get(bus_rd.data)

        ctx.set(bus_rd.en, 1)
        assert await cycle(bus=(bus_rd, 5)) == (1, 0x105)
        # the step writes word 6 while the bus reads it: retry, then the new word
        assert (await cycle(bus=(bus_rd, 6), w=(unit_wr, 6, 0xAAAA)))[0] == 0
        assert await cycle(bus=(bus_rd, 6)) == (1, 0xAAAA)
        # the bus writes word 8 while it reads it (a read and a write burst meeting)
        assert (await cycle(bus=(bus_rd, 8), w=(bus_wr, 8, 0xBBBB)))[0] == 0
        assert await cycle(bus=(bus_rd, 8)) == (1, 0xBBBB)
        # beside a write of another word of the bank, and sharing a unit's read: served
        assert await cycle(bus=(bus_rd, 10), w=(unit_wr, 12, 0xCCCC)) == (1, 0x10A)
        assert await cycle(bus=(bus_rd, 12), r=(unit_rd, 12)) == (1, 0xCCCC)
        # the bank's two ports taken by a unit's read and write of other words: not served
        assert (await cycle(bus=(bus_rd, 14), r=(unit_rd, 16), w=(unit_wr, 18, 1)))[0] == 0

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
def test_each_bank_is_one_block_ram(stats, family, ram, per_bank, ff):
    """Each bank a true dual-port block RAM (both ports reading and writing), not flip-flops:
    the only registers left are the read lanes' port selects."""
    cells = stats[family]
    assert cells.get(ram, 0) == per_bank * G.banks, cells
    assert cells.get(ff, 0) <= 16, cells
