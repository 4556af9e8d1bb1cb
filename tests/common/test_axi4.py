"""The AXI4 slave front end (:mod:`kfgen.hdl.bus.axi4`) behind a test top: the front end, 512 words
of memory, a read/write and a read-only register, and holes (:mod:`axi4_tb` has the map).

The top goes through the same Verilog emission and waivers as a core, must lint clean, and runs
under Verilator with cocotbext-axi's master (:mod:`axi4_tb`), one build for every case. An
Amaranth-simulator test checks the AXI4 rule that no output follows an input without a clock.
"""

import pytest
from amaranth.hdl import Cat, Module, Mux, Signal, unsigned
from amaranth.lib import memory, wiring
from amaranth.lib.wiring import In
from amaranth.sim import Simulator

from kfgen.gen.verilog import emit, header, waivers
from kfgen.hdl.bus.axi4 import Axi4Slave, WordBusSignature, axi4_slave_members, forward, lint_waivers
from kfgen.sim.toolchain import lint
from kfgen.sim.verilator import build, run_test

import axi4_tb
from helpers import VERILATOR_CACHE
from axi4_tb import ADDR_WIDTH, ID, ID_VALUE, ID_WIDTH, MEM, MEM_WORDS, SCRATCH

TOP = "axi4_test"


class MapBackend(wiring.Component):
    """The simplest back end: memory, a read/write register, a read-only register, holes.

    Read latency 1 (the memory's read port, and the registers read into a register beside it),
    or 2 (both registered once more);
    byte strobes applied per byte to memory words and to the register. Reads of the upper half
    of the memory wait (``r_wait``) one cycle in four, by a free-running LFSR, as a busy back
    end's would (the lower half keeps the throughput case's one beat a clock).
    """

    def __init__(self, read_latency=1):
        self._lat = read_latency
        super().__init__({"bus": In(WordBusSignature(ADDR_WIDTH - 2, read_latency))})

    def elaborate(self, platform):
        m = Module()
        bus = self.bus
        m.submodules.mem = mem = memory.Memory(shape=unsigned(32), depth=MEM_WORDS, init=[])
        wr = mem.write_port(granularity=8)
        rd = mem.read_port()  # read latency 1; not transparent: a same-cycle write is seen after
        scratch = Signal(32)

        def decode(addr):
            return ((addr >= MEM // 4) & (addr < MEM // 4 + MEM_WORDS), addr == SCRATCH // 4,
                    addr == ID // 4)

        r_mem, r_scratch, r_id = decode(bus.r_addr)
        lfsr = Signal(8, init=1)
        m.d.sync += lfsr.eq(Cat(lfsr[7] ^ lfsr[5] ^ lfsr[4] ^ lfsr[3], lfsr[:7]))
        m.d.comb += bus.r_wait.eq(r_mem & (bus.r_addr >= MEM // 4 + MEM_WORDS // 2) & lfsr[0] & lfsr[1])
        from_mem, err, reg = Signal(), Signal(), Signal(32)
        m.d.comb += [rd.addr.eq(bus.r_addr), rd.en.eq(bus.r_en & r_mem)]
        with m.If(bus.r_en):
            m.d.sync += [from_mem.eq(r_mem), err.eq(~(r_mem | r_scratch | r_id)),
                         reg.eq(Mux(r_scratch, scratch, ID_VALUE))]
        data = Mux(from_mem, rd.data, reg)
        if self._lat == 2:
            data_r, err_r = Signal(32), Signal()
            m.d.sync += [data_r.eq(data), err_r.eq(err)]
            data, err = data_r, err_r
        m.d.comb += [bus.r_data.eq(data), bus.r_err.eq(err)]

        w_mem, w_scratch, _ = decode(bus.w_addr)
        m.d.comb += [
            bus.w_err.eq(~(w_mem | w_scratch)),   # the hole and the read-only register refuse
            wr.addr.eq(bus.w_addr),
            wr.data.eq(bus.w_data),
            wr.en.eq(Mux(bus.w_en & w_mem, bus.w_strb, 0)),
        ]
        for i in range(4):
            with m.If(bus.w_en & w_scratch & bus.w_strb[i]):
                m.d.sync += scratch[8 * i:8 * i + 8].eq(bus.w_data[8 * i:8 * i + 8])
        return m


class Axi4TestTop(wiring.Component):
    def __init__(self, read_latency=1):
        self._lat = read_latency
        self._members = axi4_slave_members(ADDR_WIDTH, ID_WIDTH)
        super().__init__(self._members)

    def elaborate(self, platform):
        m = Module()
        m.submodules.front = front = Axi4Slave(ADDR_WIDTH, ID_WIDTH, self._lat)
        m.submodules.back = back = MapBackend(self._lat)
        wiring.connect(m, front.bus, back.bus)
        forward(m, self, front, self._members)
        return m


@pytest.fixture(scope="module", params=[1, pytest.param(2, marks=pytest.mark.full)], ids=["latency1", "latency2"])
def rtl(request, build_root):
    """The test top with a back end of read latency 1 and 2 (the UKF's and IMM's buffer)."""
    out = build_root / f"axi4_l{request.param}"
    out.mkdir(parents=True, exist_ok=True)
    lines = header("axi4 test top", TOP, {"addr_width": ADDR_WIDTH, "id_width": ID_WIDTH,
                                          "read_latency": request.param})
    text = emit(Axi4TestTop(request.param), TOP, lines)
    (out / f"{TOP}.v").write_text(text)
    (out / f"{TOP}.vlt").write_text(waivers(text, TOP, lines) + "\n" + lint_waivers(TOP))
    return out


@pytest.mark.xdist_group("axi4")
def test_lint(rtl):
    rc, messages = lint(rtl / f"{TOP}.v")
    assert rc == 0 and not messages, "\n".join(messages)


@pytest.fixture(scope="module")
def sim(rtl):
    runs = rtl / "runs"
    runs.mkdir(exist_ok=True)
    # the shared cache: one build a latency for both workers (the other waits for it)
    return build([rtl / f"{TOP}.v"], TOP, VERILATOR_CACHE), runs, int(rtl.name[-1])


@pytest.mark.verilator
@pytest.mark.parametrize("tests", [["bursts", "fixed_bursts"], ["errors", "strobes", "raw_cases"],
                                   ["throughput", "stress"]], ids=lambda tests: tests[0])
@pytest.mark.xdist_group("axi4")
def test_cocotb(sim, tests):
    """Every case of :mod:`axi4_tb`, in three simulator runs of one build."""
    model, run_dir, lat = sim
    pattern = "|".join(rf"axi4_tb\.{t}\b" for t in tests)
    run_test(model, "axi4_tb", run_dir, tests[0], {"COCOTB_TEST_FILTER": pattern,
                                                    "KFGEN_TB_READ_LATENCY": str(lat)})


@pytest.mark.parametrize("read_latency", [1, 2])
def test_no_input_to_output_path(read_latency):
    """AXI4: no combinational path from an input to an output. Between clock edges, random
    inputs (busy bursts, random ready) must leave every output as it was after the edge."""
    import numpy as np

    dut = Axi4Slave(ADDR_WIDTH, ID_WIDTH, read_latency)
    ins = [getattr(dut, n) for n, mb in dut.signature.members.items() if n.startswith("s_axi") and mb.flow == In]
    outs = [getattr(dut, n) for n, mb in dut.signature.members.items() if n.startswith("s_axi") and mb.flow != In]
    rng = np.random.default_rng(3)
    changed = []

    async def tb(ctx):
        for _ in range(400):
            for sig in ins:
                ctx.set(sig, int(rng.integers(0, 1 << len(sig))) if len(sig) != 3 else 2)
            for sig in (dut.bus.r_err, dut.bus.w_err, dut.bus.r_wait):
                ctx.set(sig, int(rng.random() < 0.2))
            before = [ctx.get(o) for o in outs]
            for sig in ins:
                if len(sig) == 1:
                    ctx.set(sig, 1 - ctx.get(sig))
            ctx.set(dut.bus.r_err, 1 - ctx.get(dut.bus.r_err))
            ctx.set(dut.bus.w_err, 1 - ctx.get(dut.bus.w_err))
            ctx.set(dut.bus.r_wait, 1 - ctx.get(dut.bus.r_wait))
            changed.extend(o.name for o, b in zip(outs, before) if ctx.get(o) != b)
            await ctx.tick()

    s = Simulator(dut)
    s.add_clock(1e-8)
    s.add_testbench(tb)
    s.run()
    assert not changed, sorted(set(changed))


def test_word_bus_signature_compares_every_parameter():
    """Two word buses are one interface only with the same address width and read latency (a
    back end answering a cycle late is not the bus a front end of latency 1 drives)."""
    assert WordBusSignature(10, 2) == WordBusSignature(10, 2)
    assert WordBusSignature(10, 1) != WordBusSignature(10, 2)
    assert WordBusSignature(10, 2) != WordBusSignature(11, 2)
    assert WordBusSignature(10).flip() == WordBusSignature(10, 1).flip()
    assert repr(WordBusSignature(10, 2)) == "WordBusSignature(10, read_latency=2)"
