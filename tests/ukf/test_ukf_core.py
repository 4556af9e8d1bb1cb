"""The UKF core end to end: ``kfgen ukf`` output (files, manifest, lint), then one Verilator
build driven through AXI4 by cocotbext-axi (:mod:`kfgen.sim.ukf.tb`): several iterations with
every word against the golden model and the cycles against the manifest, and the bus and
fault cases."""

import json
import re

import pytest

from kfgen.hdl.linalg.engine import OVERHEAD
from kfgen.hdl.ukf.params import UkfParams
from kfgen.hdl.ukf.steps import schedules
from kfgen.sim.toolchain import lint, run_testbench_icarus, run_testbench_verilator
from kfgen.sim.engine.run import build_core, run_tb
from kfgen.sim.ukf.run import TB
from kfgen.sim.ukf.smoke import ITERATIONS

from helpers import (ENGINE_CAMPAIGN, VERILATOR_CACHE, kfgen, kfgen_in_process, planted_bug, run_fault_campaign,
                     testbench_passes)

TOP = "ukf_small"
SMALL = ["--states", "2", "--observations", "1", "--process-noise", "1", "--measurement-noise", "1",
         "--pes", "1", "--format", "binary32", "--w0", "0.25"]


@pytest.fixture(scope="module")
def rtl(build_root):
    out = build_root / "ukf_core"
    kfgen("ukf", *SMALL, "--name", TOP, "-o", out)
    return out


@pytest.mark.xdist_group("ukf_core")
def test_files_and_manifest(rtl):
    names = sorted(p.name for p in rtl.glob(f"{TOP}.*"))
    assert names == sorted(f"{TOP}.{ext}" for ext in ("v", "vlt", "json", "rdl", "h", "md", "core", "xdc", "sdc",
                                                      "xml"))
    assert (rtl / f"{TOP}_ip.tcl").is_file() and (rtl / f"{TOP}_driver.py").is_file()
    man = json.loads((rtl / f"{TOP}.json").read_text())
    params = UkfParams(**man["parameters"])
    assert (params.n, params.m, params.nw, params.nv, params.w0) == (2, 1, 1, 1, 0.25)
    scheds = schedules(params)
    assert man["cycles"] == {k: s.cycles + OVERHEAD for k, s in scheds.items()}
    assert {r["name"] for r in man["registers"]} == {"ID", "CTRL", "STATUS", "IRQ_ENABLE"}
    assert man["engine"]["program_store"]["bits"] > 0
    assert "irq" in {p["name"] for p in man["ports"]}


@pytest.mark.xdist_group("ukf_core")
def test_lint(rtl):
    rc, messages = lint(rtl / f"{TOP}.v")
    assert rc == 0 and not messages, "\n".join(messages)


@pytest.mark.xdist_group("ukf_core")
@pytest.mark.parametrize("simulator", ["icarus", pytest.param("verilator", marks=pytest.mark.verilator)])
def test_shipped_testbench(rtl, tmp_path, simulator):
    """The shipped TOP_tb.v replays TOP_vectors.hex (the three steps, f and h's words from the
    software's session) on the core: PASS, each iteration's cycles the manifest's; and it
    fails, naming the operation, on vectors with one word planted wrong: the estimate's last
    word, or the cycles of the first start."""
    out = testbench_passes(rtl, TOP, simulator, tmp_path)
    cycles = json.loads((rtl / f"{TOP}.json").read_text())["cycles"]
    total = cycles["sig_gen"] + cycles["predict"] + cycles["update"]
    assert re.findall(r"^iteration (\d+): (\d+) cycles$", out, re.M) == [(str(k), str(total))
                                                                        for k in range(ITERATIONS)]
    run = {"icarus": run_testbench_icarus, "verilator": run_testbench_verilator}[simulator]
    for bug, says in (("read", r"FAIL: ukf_small: op (\d+): read at "), ("start", r"FAIL: ukf_small: start ")):
        bad = tmp_path / f"{bug}.hex"
        line = planted_bug(rtl / f"{TOP}_vectors.hex", bad, bug)
        proc = run(rtl, TOP, tmp_path, bad, build=False)
        assert proc.returncode != 0 and re.search(says, proc.stdout), (line, proc.stdout[-2000:])
        assert "PASS" not in proc.stdout
        if bug == "read":
            assert f"// {re.search(says, proc.stdout).group(1)}: " in line, "the failing operation is the planted one"


@pytest.mark.parametrize("how", ["option", "config"])
def test_no_irq(tmp_path, how):
    if how == "option":
        kfgen("ukf", *SMALL, "--no-irq", "--name", "ukf_quiet", "-o", tmp_path)
    else:
        (tmp_path / "c.toml").write_text("irq = false\nname = 'ukf_quiet'\n")
        kfgen("ukf", *SMALL, "--config", tmp_path / "c.toml", "-o", tmp_path)
    man = json.loads((tmp_path / "ukf_quiet.json").read_text())
    assert man["parameters"]["irq"] is False
    assert "irq" not in {p["name"] for p in man["ports"]}
    assert "IRQ_ENABLE" not in {r["name"] for r in man["registers"]}
    assert "--no-irq" in (tmp_path / "ukf_quiet.v").read_text().split("\n\n")[0]
    if how == "option":  # the shipped testbench polls STATUS instead of waiting for irq
        out = testbench_passes(tmp_path, "ukf_quiet", "icarus", tmp_path / "icarus")
        text = (tmp_path / "ukf_quiet_tb.v").read_text()
        assert "irq_rise" not in text and "axi_read(STATUS)" in text
        assert len(re.findall(r"^op \d+, start ", out, re.M)) == 3 * ITERATIONS


@pytest.mark.parametrize("args,says", [
    (["--states", "0"], "--states: "),
    (["--pes", "99"], "--pes: "),
    (["--w0", "1"], "--w0: "),
    (["--format", "binary128"], "--format: "),
    (["--address-width", "5"], "--address-width: "),
    (["--form", "qr"], "--form: "),
])
def test_bad_values_exit_2(tmp_path, args, says):
    proc = kfgen_in_process("ukf", *args, "-o", tmp_path / "x")
    assert proc.returncode == 2 and proc.stderr.startswith(f"kfgen: error: {says}")
    assert proc.stderr.count("\n") == 1 and not (tmp_path / "x").exists()


@pytest.fixture(scope="module")
def sim(rtl):
    return build_core(rtl, TOP, VERILATOR_CACHE)


@pytest.mark.verilator
@pytest.mark.xdist_group("ukf_core")
@pytest.mark.parametrize("tests", [["iterations"], ["errors"], pytest.param(["python_driver"], marks=pytest.mark.full)],
                         ids=lambda t: t[0])
def test_cocotb(rtl, sim, tests):
    """Both cases on one build (n = 2, m = 1, nw = nv = 1, P = 1, binary32)."""
    run_tb(sim, rtl, TOP, TB, tests, tests[0])


#: More configurations, one Verilator build each (12-23 s of CPU), both testbench cases on it:
#: a small core of the square-root form, and in ``make test-full`` the chapter's size (7/6/7/6,
#: M = 20: the default core) at P = 1 and 2, small cores in binary16 and binary64 with more
#: PEs than the small one and the chapter's P = 5 and 10. P = 1 is the nanosatellite
#: co-simulation's build (which make test runs): on its worker, so that neither waits for the
#: other's build.
CONFIGURATIONS = [
    pytest.param([], id="m20_p1", marks=[pytest.mark.xdist_group("cosim_nanosat"), pytest.mark.full]),
    pytest.param(["--pes", "2"], id="m20_p2", marks=pytest.mark.full),
    pytest.param([*SMALL, "--form", "sqrt", "--pes", "2"], id="small_sqrt_p2"),
    pytest.param(["--form", "sqrt", "--pes", "2"], id="m20_sqrt_p2", marks=pytest.mark.full),
    pytest.param([*SMALL, "--format", "binary16", "--pes", "3"], id="small_binary16_p3", marks=pytest.mark.full),
    # --target-mhz: the FMA, divider and square root at the stages a target picks, the schedule after them
    pytest.param([*SMALL, "--target-mhz", "75", "--pes", "2"], id="small_t75_p2", marks=pytest.mark.full),
    # above the engine's own clock: the program store's fetch register too (each step a cycle longer)
    pytest.param([*SMALL, "--target-mhz", "125", "--pes", "2"], id="small_t125_p2", marks=pytest.mark.full),
    pytest.param([*SMALL, "--format", "binary64", "--pes", "3"], id="small_binary64_p3", marks=pytest.mark.full),
    pytest.param(["--pes", "5"], id="m20_p5", marks=pytest.mark.full),
    pytest.param(["--pes", "10"], id="m20_p10", marks=pytest.mark.full),
]


@pytest.mark.verilator
@pytest.mark.parametrize("args", CONFIGURATIONS)
def test_cocotb_configurations(request, build_root, args):
    """Every word against the golden model, the cycles against the manifest and the bus and
    fault cases, on each configuration's own build (lint first)."""
    top = "ukf_" + request.node.callspec.id
    out = build_root / top
    kfgen("ukf", *args, "--name", top, "-o", out)
    rc, messages = lint(out / f"{top}.v")
    assert rc == 0 and not messages, "\n".join(messages)
    model = build_core(out, top, VERILATOR_CACHE)
    run_tb(model, out, top, TB, ["iterations", "errors"], "all")


def test_two_word_elements_in_amaranth():
    """binary64 in Amaranth's simulator, on the back end's word bus: a low half is held until
    its high half is written, both halves read back, partial strobes and sigma_points refused."""
    from amaranth.hdl import Module
    from amaranth.sim import Simulator

    from kfgen.hdl.linalg.engine import Engine
    from kfgen.hdl.engine.core import Backend
    from kfgen.hdl.ukf.regmap import ukf_map

    params = UkfParams(states=2, observations=1, process_noise=1, measurement_noise=1, format="binary64")
    rmap = ukf_map(params)
    engine = Engine(schedules(params))
    back = Backend(params, engine, rmap)
    top = Module()
    top.submodules.engine, top.submodules.back = engine, back
    bus = back.bus
    x = rmap["x"].address(1) // 4  # element 1 of x: word addresses x, x + 1
    sp = rmap["sigma_points"].address(0) // 4
    lo, hi = 0x89ABCDEF, 0x01234567

    async def tb(ctx):
        async def write(addr, data, strb=0xF):
            ctx.set(bus.w_addr, addr)
            ctx.set(bus.w_data, data)
            ctx.set(bus.w_strb, strb)
            ctx.set(bus.w_en, 1)
            err = ctx.get(bus.w_err)
            await ctx.tick()
            ctx.set(bus.w_en, 0)
            return err

        async def read(addr):
            """As the front end reads: the address held while the back end says wait (a
            word written the cycle before is still on its way to the memory)."""
            ctx.set(bus.r_addr, addr)
            for _ in range(4):
                if not ctx.get(bus.r_wait):
                    break
                await ctx.tick()
            else:
                raise AssertionError(f"the read of {addr:#x} waits on an idle core")
            ctx.set(bus.r_en, 1)
            await ctx.tick()
            ctx.set(bus.r_en, 0)
            await ctx.tick()  # read latency 2
            return ctx.get(bus.r_data), ctx.get(bus.r_err)

        assert not await write(x, lo)
        assert await read(x) == (0, 0) and await read(x + 1) == (0, 0)  # held, not written
        assert not await write(x + 1, hi)
        assert await read(x) == (lo, 0) and await read(x + 1) == (hi, 0)
        assert await write(x + 1, 0xFFFF, strb=0x3)  # partial strobe: SLVERR, nothing changes
        assert await read(x + 1) == (hi, 0)
        assert not await write(x, 0, strb=0)  # no strobe: OKAY, nothing written
        assert await write(sp, 1) and await write(sp + 1, 1)  # read-only region
        assert await read(sp + 1) == (0, 0)

    sim = Simulator(top)
    sim.add_clock(1e-8)
    sim.add_testbench(tb)
    sim.run()



@pytest.mark.verilator
@pytest.mark.xdist_group("ukf_core")
@pytest.mark.parametrize("sequences", [ENGINE_CAMPAIGN[0], pytest.param(ENGINE_CAMPAIGN[1], marks=pytest.mark.full)])
def test_fault_campaign(rtl, sim, sequences):
    run_fault_campaign(sim, rtl, TOP, TB, sequences)
