"""The engine's hardware in Amaranth's simulator: a small UKF's three steps, every memory word
against the golden executor bit for bit, every step's cycles against the schedule; a
covariance that is not positive definite gives err_pivot and an idle engine."""

import numpy as np
import pytest
from amaranth.sim import Simulator

from kfgen.hdl.arith.float.div import FloatDiv
from kfgen.hdl.arith.float.fma import FloatFMA
from kfgen.hdl.arith.float.sqrt import FloatSqrt
from kfgen.hdl.linalg.banks import BUS_READ_LATENCY
from kfgen.hdl.linalg.engine import OVERHEAD, Engine
from kfgen.hdl.linalg.schedule import Machine, schedule
from kfgen.hdl.ukf.params import UkfParams
from kfgen.hdl.ukf.programs import build_ukf
from kfgen.sim.linalg.exec import from_words, run, to_words


def ukf_programs(sizes, w0=0.0, fmt="binary32"):
    """The UKF's programs for ``sizes`` (n, nw, nv, m)."""
    n, nw, nv, m = sizes
    return build_ukf(UkfParams(states=n, observations=m, process_noise=nw, measurement_noise=nv, w0=w0,
                               format=fmt))


def machine(pes, fmt, fetch_register=0):
    units = [cls(fmt) for cls in (FloatFMA, FloatDiv, FloatSqrt)]
    for u in units:
        u._MustUse__silence = True  # only the latency is read
    return Machine(pes, *(u.latency for u in units), fetch_register=fetch_register)


def f(pt, n):
    """A nonlinear motion model on an augmented point (x, w, v)."""
    x0, x1, w = pt[0], pt[1], pt[n]
    return [x0 + 0.1 * x1 + 0.01 * np.sin(x0), 0.95 * x1 + w]


def h(pt_f, v):
    return [np.sqrt(pt_f[0] ** 2 + 1.0) + v]


class TB:
    """Drives the engine's bus port and start; keeps the golden memory beside it."""

    def __init__(self, ctx, dut, ukf):
        self.ctx, self.dut, self.ukf = ctx, dut, ukf
        self.lay, self.fmt = ukf.layout, ukf.fmt
        self.gold = self.lay.initial_memory()

    async def put(self, name, values):
        r = self.lay[name]
        words = to_words(self.fmt, np.ravel(values))
        assert len(words) == r.size
        self.ctx.set(self.dut.mem_we, 1)
        for i, w in enumerate(words):
            self.gold[r.base + i] = w
            self.ctx.set(self.dut.mem_waddr, r.base + i)
            self.ctx.set(self.dut.mem_wdata, w)
            await self.ctx.tick()
        self.ctx.set(self.dut.mem_we, 0)

    def get(self, name):
        r = self.lay[name]
        words = self.gold[r.base:r.base + r.size]
        return np.array(from_words(self.fmt, words)).reshape(r.rows, r.cols)

    async def memory(self):
        out = []
        for a in range(self.lay.size + BUS_READ_LATENCY - 1):  # word a after tick a + 1
            self.ctx.set(self.dut.mem_raddr, min(a, self.lay.size - 1))
            await self.ctx.tick()
            if a >= BUS_READ_LATENCY - 1:
                out.append(self.ctx.get(self.dut.mem_rdata))
        return out

    async def step(self, name):
        """Run one step in hardware and in the golden model; compare memory, status, cycles."""
        ctx, dut = self.ctx, self.dut
        st = run(self.ukf.steps[name], self.gold)
        ctx.set(dut.step, dut.step_names.index(name))
        ctx.set(dut.start, 1)
        await ctx.tick()
        ctx.set(dut.start, 0)
        cycles = 1
        assert ctx.get(dut.busy)
        while not ctx.get(dut.done):
            await ctx.tick()
            cycles += 1
            assert cycles <= dut.cycles(name), f"{name} does not end"
        assert cycles == dut.cycles(name)
        assert not ctx.get(dut.busy)
        assert (ctx.get(dut.err_pivot), ctx.get(dut.err_nan), ctx.get(dut.flags)) == \
            (st.pivot, st.nan, st.flags), name
        got = await self.memory()
        bad = [(a, hex(g), hex(w)) for a, (g, w) in enumerate(zip(got, self.gold)) if g != w]
        assert not bad, (name, bad[:8])
        return st


def simulate(dut, tb):
    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(tb)
    sim.run()


@pytest.mark.parametrize("pes,fmt,fetch", [(1, "binary32", 0), (2, "binary32", 1),
                                           pytest.param(2, "binary32", 0, marks=pytest.mark.full),
                                           pytest.param(1, "binary16", 0, marks=pytest.mark.full)])
def test_engine_ukf_iteration(pes, fmt, fetch):
    """sig_gen, software f, predict, software h, update, then a P that is not positive
    definite: the hardware's memory equals the golden model's word for word after each
    (``fetch``: the program store's fetch register)."""
    ukf = ukf_programs((2, 1, 1, 1), 0.25, fmt)
    mc = machine(pes, fmt, fetch)
    scheds = {k: schedule(p, mc) for k, p in ukf.steps.items()}
    dut = Engine(scheds)
    for k, s in scheds.items():
        assert dut.cycles(k) == s.cycles + OVERHEAD + fetch
    n = ukf.params.n

    async def tb(ctx):
        t = TB(ctx, dut, ukf)
        await t.put("x", [0.5, -1.25])
        await t.put("P", [[0.4, 0.1], [0.1, 0.3]])
        await t.put("Q", [[0.02]])
        await t.put("R", [[0.05]])
        st = await t.step("sig_gen")
        assert not st.pivot
        chi = t.get("sigma_points")
        pts_f = [f(p, n) for p in chi]
        await t.put("sigma_points_f", pts_f)
        await t.step("predict")
        await t.put("sigma_points_h", [h(p, c[n + 1]) for p, c in zip(pts_f, chi)])
        await t.put("z", [1.2])
        await t.step("update")
        assert np.all(np.isfinite(t.get("P")))
        await t.put("P", [[1.0, 2.0], [2.0, 1.0]])  # D_1 = 1 - 4 < 0
        st = await t.step("sig_gen")
        assert st.pivot and ctx.get(dut.err_pivot) and not ctx.get(dut.busy)
        await t.put("P", [[0.4, 0.1], [0.1, 0.3]])  # idle and usable again
        ctx.set(dut.step, dut.step_names.index("sig_gen"))
        ctx.set(dut.start, 1)
        await ctx.tick()
        ctx.set(dut.start, 0)
        await ctx.tick().repeat(dut.cycles("sig_gen") // 2)
        ctx.set(dut.halt, 1)  # soft reset mid-step, divisions in flight
        await ctx.tick()
        ctx.set(dut.halt, 0)
        assert not ctx.get(dut.busy)
        await ctx.tick().repeat(40)
        assert not ctx.get(dut.done)
        # sig_gen rewrites all it wrote before the abort: the rerun ends as one run would
        st = await t.step("sig_gen")
        assert not st.pivot

    simulate(dut, tb)


def test_engine_verilog_lint(tmp_path):
    """The engine alone as Verilog: Verilator -Wall clean with the generated waivers."""
    from kfgen.gen.verilog import emit, header, waivers
    from kfgen.sim.toolchain import ToolMissing, lint

    ukf = ukf_programs((2, 1, 1, 1), 0.25, "binary32")
    mc = machine(1, "binary32")
    dut = Engine({k: schedule(p, mc) for k, p in ukf.steps.items()})
    head = header("engine", "engine_top", {"n": 2, "nw": 1, "nv": 1, "m": 1, "pes": 1})
    verilog = emit(dut, "engine_top", head)
    (tmp_path / "engine_top.v").write_text(verilog)
    (tmp_path / "engine_top.vlt").write_text(waivers(verilog, "engine_top", head))
    try:
        rc, messages = lint(tmp_path / "engine_top.v")
    except ToolMissing as e:
        pytest.skip(str(e))
    assert rc == 0 and not messages, "\n".join(messages)


def test_engine_generic_program():
    """Any program of the IR, not only the UKF's: descending and mixed strides, accumulations
    split into segments, mirrored results of every unit, chains between units, a NaN from a
    square root reaching a checked result (err_nan), on P = 2 with bank conflicts."""
    from types import SimpleNamespace

    from kfgen.hdl.arith.float.format import FloatFormat
    from kfgen.hdl.linalg.program import Copy, Div, Dot, Layout, Program, Sqrt

    fmt = FloatFormat.parse("binary32")
    lay = Layout()
    v = lay.add("v", 1, 24, "bus")
    w = lay.add("w", 1, 24)
    one = lay.const("one", to_words(fmt, [1.0]))(0, 0)
    prog = Program("mix", lay, fmt)
    V, W = (lambda i: v(0, i)), (lambda i: w(0, i))
    prog.emit(Dot(W(0), V(0), [(V(1), V(2), False), (V(3), V(4), True), (V(5), V(6), False)]))
    prog.emit(Dot((W(1), W(2)), None, [(V(20 - k), V(k), k % 3 == 0) for k in range(9)]))
    prog.emit(Div((W(3), W(4)), V(7), V(8), "pivot"))
    prog.emit(Sqrt(W(5), V(11)))  # a negative operand: NaN
    prog.emit(Copy((W(6), W(7)), W(0)))
    prog.emit(Dot(W(8), W(0), [(W(1), W(3), True), (one, W(6), False)]))
    prog.emit(Sqrt((W(9), W(10)), W(4)))
    for i in range(6):
        prog.emit(Dot(W(11 + i), V(i), [(V(j), W(9), j % 2 == 1) for j in range(i, 18, 3)]))
    prog.emit(Dot(W(17), W(8), [(W(5), one, False)], "finite"))  # the NaN reaches a check
    prog.emit(Div(W(18), W(17), W(12), "finite"))
    values = np.random.default_rng(7).uniform(0.5, 2.0, 24)
    values[11] = -1.0
    dut = Engine({"mix": schedule(prog, machine(2, fmt))})

    async def tb(ctx):
        t = TB(ctx, dut, SimpleNamespace(layout=lay, fmt=fmt, steps={"mix": prog}))
        await t.put("v", values)
        st = await t.step("mix")
        assert st.nan and not st.pivot

    simulate(dut, tb)


def _rom_bits(fragment) -> int:
    """Bits of every memory without a write port (a ROM) in the elaborated ``fragment``."""
    from amaranth.hdl import Shape
    from amaranth.hdl._mem import MemoryInstance

    bits = 0
    if isinstance(fragment, MemoryInstance) and not fragment._write_ports:
        bits += fragment._data.depth * Shape.cast(fragment._data.shape).width
    return bits + sum(_rom_bits(sub) for sub, _, _ in fragment.subfragments)


@pytest.mark.parametrize("core", ["ukf", "imm"])
def test_manifest_program_store_is_what_is_built(core):
    """The manifest's program store is the ROMs the elaborated core holds, bit for bit (it
    once reported a single-store format the hardware never builds)."""
    from amaranth.hdl import Fragment

    from kfgen.hdl.engine.descriptor import engine_manifest
    from kfgen.hdl.imm.core import Imm
    from kfgen.hdl.imm.params import ImmParams
    from kfgen.hdl.ukf.core import Ukf

    dut = (Ukf(UkfParams(states=2, observations=1, process_noise=1, measurement_noise=1, pes=2)) if core == "ukf"
           else Imm(ImmParams(models=2, states=2, measurements=1)))
    store = engine_manifest(dut)["engine"]["program_store"]
    built = _rom_bits(Fragment.get(dut, None))
    assert store["bits"] == built > 0
    assert store["instructions"] == sum(r["words"] for r in store["roms"].values())


@pytest.mark.parametrize("piece", [512, 8])
def test_fetch_register_delays_every_issue_by_one_cycle(monkeypatch, piece):
    """Each stream of a small UKF, every step: with the fetch register, the instructions
    leave the stream in the same order and spacing, each exactly a cycle later (the ROM in
    one piece, and in pieces of 8 words)."""
    from kfgen.hdl.linalg.engine import _stream_layout
    from kfgen.hdl.linalg.microcode import compile_steps
    from kfgen.hdl.linalg.sequencer import InstructionStream

    monkeypatch.setattr(InstructionStream, "ROM_PIECE", piece)

    ukf = ukf_programs((2, 1, 1, 1), 0.25)
    code = compile_steps([schedule(p, machine(2, "binary32")) for p in ukf.steps.values()])

    def fires(img, fetch):
        dut = InstructionStream(img, _stream_layout(code, img), fetch)
        seen = []

        async def tb(ctx):
            for k in range(len(img.bases)):
                ctx.set(dut.step, k)
                ctx.set(dut.start, 1)
                await ctx.tick()
                ctx.set(dut.start, 0)
                n = img.ends[k] - img.bases[k]
                for cycle in range(1, 1 << 16):
                    if len([s for s in seen if s[0] == k]) == n:
                        break
                    if ctx.get(dut.fire):
                        seen.append((k, cycle, ctx.get(dut.ins.as_value())))
                    await ctx.tick()
                await ctx.tick().repeat(3)
                assert not ctx.get(dut.fire), "nothing after the step's last instruction"

        simulate(dut, tb)
        return seen, dut.lead

    for name, img in code.streams.items():
        (plain, lead0), (fetched, lead1) = fires(img, False), fires(img, True)
        assert lead1 == lead0 + 1 == InstructionStream.LEAD + 1
        assert len(plain) == len(img.words), name
        assert fetched == [(k, c + 1, w) for k, c, w in plain], name
