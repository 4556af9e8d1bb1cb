"""The UKF with f and h on chip (``kfgen ukf --app MODULE:CLASS --on-chip``): the
application's models traced into the engine, one ``iteration`` step per measurement.

The golden model of the on-chip core is held against the float64 reference and against the
three-step core with software f and h; the RTL (Verilator, cocotbext-axi) against the golden
model word for word, the iteration's cycles against the manifest; the command line's
refusals; the regenerate command."""

import json
import re
import sys

import numpy as np
import pytest

from kfgen.hdl.ukf.params import UkfParams
from kfgen.hdl.ukf.steps import programs, schedules
from kfgen.hdl.linalg.engine import OVERHEAD
from kfgen.sim.toolchain import lint
from kfgen.sim.ukf.accuracy import run_golden, run_reference
from kfgen.sim.ukf.app import checked_scenario
from kfgen.sim.ukf.apps.nanosat import Nanosat, attitude_error_deg
from kfgen.sim.engine.run import build_core, run_tb
from kfgen.sim.ukf.run import TB
from kfgen.sim.ukf.smoke import ITERATIONS

from helpers import VERILATOR_CACHE, iteration_cycles, kfgen, kfgen_in_process, run_shipped_testbench

NANOSAT = "nanosat:Nanosat"
TRACKER = "tracker:Tracker"
ON_CHIP = ["--app", NANOSAT, "--on-chip"]


@pytest.fixture(scope="module")
def scenario():
    app = Nanosat()
    sc = checked_scenario(app, 60, 3)
    return app, sc, run_reference(app, sc)


def test_binary64_on_chip_is_the_reference(scenario):
    """binary64: the on-chip core's estimates equal the float64 reference's (and the
    three-step core's with f and h in software) to 1e-9."""
    app, sc, ref = scenario
    chip = run_golden(app, sc, "binary64", on_chip=NANOSAT)
    soft = run_golden(app, sc, "binary64")
    assert np.max(np.abs(chip - ref)) < 1e-9
    assert np.max(np.abs(chip - soft)) < 1e-9


def test_binary32_on_chip_tracks_the_attitude(scenario):
    """binary32: as close to the reference as the three-step core, and the attitude within
    0.1 degree of the truth after convergence."""
    app, sc, ref = scenario
    chip = run_golden(app, sc, "binary32", on_chip=NANOSAT)
    soft = run_golden(app, sc, "binary32")
    assert np.max(np.abs(chip - ref)) <= 2 * max(np.max(np.abs(soft - ref)), 1e-3)
    errors = attitude_error_deg(chip[30:, :4], sc.truth[30:, :4])
    assert np.max(errors) < 0.1, np.max(errors)


@pytest.fixture(scope="module")
def tracker():
    from kfgen.sim.ukf.apps.tracker import Tracker
    app = Tracker()
    sc = checked_scenario(app, 60, 5)
    return app, sc, run_reference(app, sc)


def test_tracker_on_chip_golden(tracker):
    """The tracker's h (np.hypot, np.arctan2) on chip: in binary64 the reference's estimates
    (relative 1e-9: the atan2 unit is faithful, numpy's within an ulp too); in binary32 as
    close to the reference as the three-step core with f and h in software."""
    app, sc, ref = tracker
    scale = np.max(np.abs(ref), axis=0)
    chip64 = run_golden(app, sc, "binary64", on_chip=TRACKER)
    assert np.max(np.abs(chip64 - ref) / scale) < 1e-9
    chip = run_golden(app, sc, "binary32", on_chip=TRACKER)
    soft = run_golden(app, sc, "binary32")
    assert np.max(np.abs(chip - ref) / scale) <= 2 * max(np.max(np.abs(soft - ref) / scale), 1e-6)
    p = UkfParams(**app.core_parameters(), app=TRACKER, on_chip=True)
    assert [op[0] for op in p.models.h.ops].count("atan2") == 1
    assert [op.unit for op in programs(p).iteration.ops].count("atan2") == p.N  # h on every point


@pytest.mark.full
@pytest.mark.verilator
def test_tracker_on_chip_rtl(build_root):
    """The tracker core on chip (atan2 and hypot's square root on the engine's shared units)
    on the RTL, word for word against the golden model; lint clean."""
    out = build_root / "ukf_tracker"
    kfgen("ukf", "--app", TRACKER, "--on-chip", "--name", "ukf_trk", "-o", out)
    rc, messages = lint(out / "ukf_trk.v")
    assert rc == 0 and not messages, "\n".join(messages)
    m = json.loads((out / "ukf_trk.json").read_text())
    assert m["engine"]["atan2_latency"] == m["engine"]["atan2_interval"] > 1
    model = build_core(out, "ukf_trk", VERILATOR_CACHE)
    run_tb(model, out, "ukf_trk", TB, ["on_chip_iterations"], "tracker", {"KFGEN_TB_ITERATIONS": "3"})


def test_iteration_program_and_map():
    """Two steps, iteration at CTRL.step = 3 and its prologue noise at 4 (the factors of Q
    and R and the sigma points' noise rows, which only Q and R change); u after z; the moved
    points written by the core (read-only); the iteration's schedule within 10 % of its
    multiply-adds at P = 1; the two hold the three steps' multiply-adds and the models'."""
    p = UkfParams(app=NANOSAT, on_chip=True)
    progs = programs(p)
    assert list(progs.steps) == ["iteration", "noise"] and progs.prologue == ("noise", "iteration", ("Q", "R"))
    assert p.nu == 3 and progs.layout["u"].base == progs.layout["z"].base + p.m
    sched = schedules(p, progs)["iteration"]
    fmas = progs.iteration.fma_count
    assert fmas <= sched.cycles <= 1.1 * fmas
    off = programs(UkfParams())
    assert fmas + progs.noise.fma_count == sum(s.fma_count for s in off.steps.values()) + p.N * p.models.fma_count
    # noise writes nothing the iteration writes, and reads only Q, R and constants of the bus's
    written = {d for op in progs.iteration.ops for d in op.dst}
    assert not written & {d for op in progs.noise.ops for d in op.dst}
    lay = progs.layout
    bus_read = {a for op in progs.noise.ops for a in op.reads if a < lay["P"].base + lay["P"].size or
                lay["z"].base <= a < lay["z"].base + p.m + p.nu}
    assert not bus_read  # (not x, P, z or u)


@pytest.fixture(scope="module")
def generated(build_root):
    out = build_root / "ukf_on_chip"
    kfgen("ukf", *ON_CHIP, "--name", "ukf_oc", "-o", out)
    return out


@pytest.mark.xdist_group("ukf_on_chip")  # (the module's core, generated once)
def test_manifest(generated):
    m = json.loads((generated / "ukf_oc.json").read_text())
    p = UkfParams(**m["parameters"])
    scheds = schedules(p)
    assert m["cycles"] == {name: s.cycles + OVERHEAD for name, s in scheds.items()}
    ctrl = next(r for r in m["registers"] if r["name"] == "CTRL")
    assert next(f for f in ctrl["fields"] if f["name"] == "step")["values"] == {"iteration": 3, "noise": 4}
    ident = next(r for r in m["registers"] if r["name"] == "ID")
    assert next(f for f in ident["fields"] if f["name"] == "version")["reset"] == 2
    regions = {mm["name"]: mm for mm in m["memories"]}
    assert regions["u"]["shape"] == [3, 1] and regions["u"]["access"] == "rw"
    assert regions["sigma_points_f"]["access"] == regions["sigma_points_h"]["access"] == "ro"
    # the UKF page's cost of the models: the program store and the operand memory
    from helpers import ROOT
    text = " ".join((ROOT / "docs" / "ukf.md").read_text().split())
    store, words = m["engine"]["program_store"]["bits"], progs_words(p)
    assert f"grows from 125,200 to {store:,} bits at P = 1" in text
    assert f"by {words - progs_words(UkfParams()):,} words" in text and f"{words:,} words in all" in text


def progs_words(p) -> int:
    return programs(p).layout.size


@pytest.mark.xdist_group("ukf_on_chip")  # (the module's core, generated once)
def test_regenerate_command(generated, tmp_path):
    header = (generated / "ukf_oc.core").read_text().split("\n\n", 1)[0]
    (line,) = [ln[2:].strip() for ln in header.splitlines() if ln.startswith("#   kfgen ") and ln.endswith(" -o DIR")]
    assert "--app nanosat:Nanosat --on-chip" in line
    argv = line.split()[1:-2]
    assert kfgen_in_process(*argv, "-o", tmp_path).returncode == 0
    for p in generated.iterdir():
        if p.is_file():
            assert p.read_bytes() == (tmp_path / p.name).read_bytes(), p.name


@pytest.mark.full
@pytest.mark.verilator
@pytest.mark.xdist_group("ukf_on_chip")
def test_rtl_iterations(generated):
    """Lint clean; the nanosatellite's scenario on the RTL, one start per iteration, every
    region word for word against the golden model, the cycles equal to the manifest's."""
    rc, messages = lint(generated / "ukf_oc.v")
    assert rc == 0 and not messages, "\n".join(messages)
    model = build_core(generated, "ukf_oc", VERILATOR_CACHE)
    run_tb(model, generated, "ukf_oc", TB, ["on_chip_iterations"], "on_chip", {"KFGEN_TB_ITERATIONS": "3"})


@pytest.mark.full
@pytest.mark.verilator
@pytest.mark.xdist_group("ukf_on_chip")
def test_c_processor(generated, tmp_path):
    """The generated C driver's TOP_iterate(dev, u, z) on the nanosatellite's build (with a
    control input): every word against the golden model, and the estimates those of the
    golden model's on-chip core. (In make test, on the small core: test_streams_rtl.)"""
    from kfgen.sim.ukf.run import build_driver, run_cosim
    model = build_core(generated, "ukf_oc", VERILATOR_CACHE)
    driver = build_driver(generated, "ukf_oc", tmp_path)
    npz = tmp_path / "c.npz"
    run_cosim(model, generated, "ukf_oc", "c_processor", "c_on_chip", NANOSAT, 3, seed=2, out=npz, driver=driver)
    app = Nanosat()
    want = run_golden(app, checked_scenario(app, 3, 2), on_chip=NANOSAT)
    with np.load(npz) as d:
        assert list(d["cycles_columns"]) == ["iteration", "transfer"]
        assert np.array_equal(d["estimates"], want)


#: A small application with a scenario, for the stream ports' core (a quick build): no control
#: input, so the core has no u region.
SMALL_APP = '''
import numpy as np
from kfgen.sim.ukf.app import Scenario, UkfApplication


class Drift(UkfApplication):
    n, nw, nv, m = 2, 2, 1, 1
    W0 = 0.25
    dt = 0.1
    x0 = np.array([0.5, -0.2])
    P0 = np.eye(2) * 0.5
    Q = np.eye(2) * 1e-3
    R = np.eye(1) * 1e-2

    def f(self, x, w, u, dt):
        return np.array([x[0] + dt * x[1], 0.98 * x[1] - 0.05 * x[0] * x[0] * dt]) + w

    def h(self, x, v):
        return np.array([np.sqrt(x[0] * x[0] + 1.0)]) + v

    def scenario(self, steps, seed):
        rng = np.random.default_rng(seed)
        x, truth, z = self.x0.copy(), [], []
        for _ in range(steps):
            x = self.f(x, rng.normal(0, 0.03, 2), None, self.dt)
            truth.append(x)
            z.append(self.h(x, rng.normal(0, 0.1, 1)))
        return Scenario(np.arange(1, steps + 1) * self.dt, np.array(truth), None, np.array(z))
'''


@pytest.fixture(scope="module")
def streams_core(build_root):
    out = build_root / "ukf_streams"
    out.mkdir(parents=True, exist_ok=True)
    (out / "drift.py").write_text(SMALL_APP)
    kfgen("ukf", "--app", f"{out / 'drift.py'}:Drift", "--on-chip", "--streams", "--name", "ukf_st", "-o", out)
    return out


@pytest.mark.xdist_group("ukf_streams")  # (the module's core, generated once)
def test_streams_manifest(streams_core):
    m = json.loads((streams_core / "ukf_st.json").read_text())
    st = m["streams"]
    assert [f["name"] for f in st["s_axis"]["fields"]] == ["z[0]"]
    assert [f["name"] for f in st["m_axis"]["fields"]] == ["x[0]", "x[1]", "P[0,0]", "P[1,1]"]
    assert [f["lsb"] for f in st["m_axis"]["fields"]] == [0, 32, 64, 96] and st["m_axis"]["tdata_width"] == 128
    assert st["latency_cycles"] == m["cycles"]["iteration"] + 1 + 4 + 4
    assert "u" not in {mm["name"] for mm in m["memories"]}
    ports = {p["name"]: p for p in m["ports"]}
    assert ports["s_axis_tdata"]["width"] == 32 and ports["m_axis_tuser"]["width"] == 2
    # the documents: the fields in TOP.md, and as macros in the C driver's header
    assert "| `m_axis_tdata` | P[1,1] | 127:96 |" in (streams_core / "ukf_st.md").read_text()
    header = (streams_core / "ukf_st_driver.h").read_text()
    assert "#define UKF_ST_M_AXIS_P1_1_LSB 96u" in header and "#define UKF_ST_S_AXIS_TDATA_WIDTH 32u" in header


@pytest.mark.verilator
@pytest.mark.xdist_group("ukf_streams")
def test_streams_rtl(streams_core):
    """Lint clean; measurements in on s_axis and estimates out on m_axis (cocotbext-axi, with
    backpressure), word for word, the latency the manifest's; then the bus-driven iteration
    on the same core, by the Python software side and by the generated C driver."""
    rc, messages = lint(streams_core / "ukf_st.v")
    assert rc == 0 and not messages, "\n".join(messages)
    model = build_core(streams_core, "ukf_st", VERILATOR_CACHE)
    run_tb(model, streams_core, "ukf_st", TB, ["stream_iterations", "on_chip_iterations"], "streams",
            {"KFGEN_TB_ITERATIONS": "4"})
    # the C driver's TOP_iterate(dev, u, z) on the same build, its estimates the golden model's
    from kfgen.sim.ukf.app import load_app
    from kfgen.sim.ukf.run import build_driver, run_cosim
    spec = f"{streams_core / 'drift.py'}:Drift"
    npz = streams_core / "c.npz"
    run_cosim(model, streams_core, "ukf_st", "c_processor", "c_on_chip", spec, 3, seed=2, out=npz,
              driver=build_driver(streams_core, "ukf_st", streams_core))
    app = load_app(spec)
    with np.load(npz) as d:
        assert list(d["cycles_columns"]) == ["iteration", "transfer"]
        assert np.array_equal(d["estimates"], run_golden(app, checked_scenario(app, 3, 2), on_chip=spec))


def _shipped_testbench(directory, top, simulator, work):
    """The shipped TOP_tb.v on an on-chip core: PASS, one start an iteration, the first
    running the noise program too (Q and R were loaded), each the manifest's cycles."""
    out = run_shipped_testbench(directory, top, simulator, work)
    cycles = json.loads((directory / f"{top}.json").read_text())["cycles"]
    want = [cycles["noise"] + cycles["iteration"]] + [cycles["iteration"]] * (ITERATIONS - 1)
    assert iteration_cycles(out) == want
    assert len(re.findall(r"^op \d+, start ", out, re.M)) == ITERATIONS


@pytest.mark.xdist_group("ukf_streams")
def test_streams_core_shipped_testbench(streams_core, tmp_path):
    """Icarus runs the small on-chip core's TOP_tb.v over AXI4 (its stream ports idle)."""
    _shipped_testbench(streams_core, "ukf_st", "icarus", tmp_path)


@pytest.mark.full
@pytest.mark.xdist_group("ukf_on_chip")
@pytest.mark.parametrize("simulator", ["icarus", pytest.param("verilator", marks=pytest.mark.verilator)])
def test_shipped_testbench(generated, tmp_path, simulator):
    """The nanosatellite's on-chip core: its TOP_tb.v in Icarus and Verilator."""
    _shipped_testbench(generated, "ukf_oc", simulator, tmp_path)


@pytest.mark.full
@pytest.mark.verilator
@pytest.mark.parametrize("fmt", ["binary16", "binary64"])
def test_streams_other_formats(build_root, fmt):
    """The stream ports with 16-bit fields and with two-bus-word elements, P = 2."""
    out = build_root / f"ukf_streams_{fmt}"
    out.mkdir(parents=True, exist_ok=True)
    (out / "drift.py").write_text(SMALL_APP)
    top = f"ukf_st_{fmt}"
    kfgen("ukf", "--app", f"{out / 'drift.py'}:Drift", "--on-chip", "--streams", "--format", fmt, "--pes", "2",
          "--name", top, "-o", out)
    rc, messages = lint(out / f"{top}.v")
    assert rc == 0 and not messages, "\n".join(messages)
    model = build_core(out, top, VERILATOR_CACHE)
    run_tb(model, out, top, TB, ["stream_iterations", "on_chip_iterations"], "streams", {"KFGEN_TB_ITERATIONS": "3"})


@pytest.mark.full
@pytest.mark.verilator
def test_nanosat_streams_rtl(build_root):
    out = build_root / "ukf_nanosat_streams"
    kfgen("ukf", *ON_CHIP, "--streams", "--name", "ukf_nst", "-o", out)
    model = build_core(out, "ukf_nst", VERILATOR_CACHE)
    run_tb(model, out, "ukf_nst", TB, ["stream_iterations"], "streams", {"KFGEN_TB_ITERATIONS": "3"})


UNTRACEABLE = '''
import numpy as np
from kfgen.sim.ukf.app import UkfApplication


class Base(UkfApplication):
    n, nw, nv, m = 2, 2, 1, 1
    dt = 0.1
    x0 = np.zeros(2)
    P0 = np.eye(2)
    Q = np.eye(2) * 1e-3
    R = np.eye(1) * 1e-2

    def f(self, x, w, u, dt):
        return x + dt * w

    def h(self, x, v):
        return x[:1] + v


class Branch(Base):
    def f(self, x, w, u, dt):
        if x[0] > 0:
            return x
        return x + w


class Tangent(Base):
    def h(self, x, v):
        return np.array([np.tan(x[0])]) + v


class Wrong(Base):
    def h(self, x, v):
        return x + v[0]
'''


@pytest.mark.parametrize("cls, says", [
    ("Branch", r"comparison, `if` or conversion of a traced value does not trace (FILE:23)"),
    ("Tangent", "np.tan does not trace (FILE:30): the engine has no unit for it yet"),
    ("Wrong", "Wrong.h returns 2 numbers, not 1"),
])
def test_untraceable_applications_exit_2(tmp_path, cls, says):
    path = tmp_path / "apps.py"
    path.write_text(UNTRACEABLE)
    proc = kfgen_in_process("ukf", "--app", f"{path}:{cls}", "--on-chip", "-o", tmp_path / "out")
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert "--app" in proc.stderr and says.replace("FILE", str(path)) in proc.stderr, proc.stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("args, says", [
    (["--on-chip"], "--on-chip: compiles an application's f and h into the core: give --app MODULE:CLASS"),
    (["--app", NANOSAT, "--streams"], "--streams: feeds the on-chip iteration: give --on-chip (and --app) with it"),
    ([*ON_CHIP, "--states", "6"], "--app: nanosat:Nanosat has n, nw, nv, m = (7, 7, 6, 6), the core (6, 7, 6, 6)"),
    (["--app", TRACKER, "--on-chip", "--format", "e4m10"],
     "--format: sin, cos and atan2 need a format whose subnormals are below 2**-7"),
])
def test_on_chip_refusals(tmp_path, args, says):
    proc = kfgen_in_process("ukf", *args, "-o", tmp_path / "out")
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and says in proc.stderr, proc.stderr


def test_without_on_chip_the_app_only_sizes_the_core():
    """An application that does not trace still sizes a three-step core."""
    assert list(programs(UkfParams(app="tracker:Tracker", states=4, observations=2, process_noise=2,
                                   measurement_noise=2)).steps) == ["sig_gen", "predict", "update"]


def test_ukf_page_table_is_the_schedules():
    """The on-chip cycles table of docs/ukf.md: each row the schedules' (iteration, the
    three steps, multiply-adds)."""
    from helpers import ROOT
    text = (ROOT / "docs" / "ukf.md").read_text()
    section = text.split("## The whole iteration on chip", 1)[1].split("\n## ", 1)[0]
    table = section.split("| P | on chip: iteration |", 1)[1].split("\n\n", 1)[0]
    rows = [r for r in table.splitlines() if r.startswith("| ") and r[2].isdigit()]
    assert len(rows) == 4
    for row in rows:
        pes, chip, steps, fmas = (int(c.strip().replace(",", "")) for c in row.strip("|").split("|"))
        p = UkfParams(app=NANOSAT, on_chip=True, pes=pes)
        progs = programs(p)
        sched = schedules(p, progs)["iteration"]
        assert (chip, fmas) == (sched.cycles + OVERHEAD, progs.iteration.fma_count), row
        assert steps == sum(s.cycles + OVERHEAD for s in schedules(UkfParams(pes=pes)).values()), row


@pytest.mark.xdist_group("ukf_on_chip")  # (the module's core, generated once)
def test_c_driver_compiles_bare_metal(generated, tmp_path):
    """The on-chip core's driver (TOP_iterate(dev, u, z)) as C99 with every warning an error,
    for a bare-metal processor."""
    import subprocess
    proc = subprocess.run(["gcc", "-std=c99", "-Wall", "-Wextra", "-Werror", "-O2", "-c",
                           str(generated / "ukf_oc_driver.c"), "-o", str(tmp_path / "d.o")],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert "int ukf_oc_iterate(ukf_oc_dev_t *dev, const double *u, const double *z);" in \
        (generated / "ukf_oc_driver.h").read_text()


@pytest.mark.full
@pytest.mark.verilator
def test_figure12_on_chip(tmp_path, capsys):
    """Figure 12 from the on-chip core's Verilog over the 1000 iterations: its estimates the
    golden model's, the attitude below 0.1 degree after the first second."""
    from kfgen.sim.ukf import plots
    kfgen("ukf", "--app", "nanosat:Nanosat", "--on-chip", "-o", tmp_path / "rtl")
    plots.main(["-o", str(tmp_path / "fig"), "--on-chip", "--rtl", str(tmp_path / "rtl")])
    assert (tmp_path / "fig" / "figure12_on_chip.png").stat().st_size > 10_000
    out = capsys.readouterr().out.splitlines()

    def row(name):  # at 0.1 s, at 1 s, max after 1 s, mean after 1 s, bias error
        (line,) = [ln for ln in out if ln.startswith(name + " ")]
        return line[len(name):].split()
    rtl, gold = row(plots.RTL_ON_CHIP), row(plots.GOLDEN_ON_CHIP)
    assert rtl == gold and float(rtl[2]) < 0.1, (rtl, gold)


@pytest.mark.full
@pytest.mark.verilator
def test_figure12_sqrt(tmp_path, capsys):
    """Figure 12 of the square-root form from the printed P0 = I (make plots): the Verilog's
    estimates its golden model's, the attitude below 0.1 degree after the first second."""
    from kfgen.sim.ukf import plots
    kfgen("ukf", "--app", "nanosat:NanosatPrinted", "--on-chip", "--form", "sqrt", "-o", tmp_path / "rtl")
    plots.main(["-o", str(tmp_path / "fig"), "--form", "sqrt", "--on-chip", "--rtl", str(tmp_path / "rtl")])
    assert (tmp_path / "fig" / "figure12_sqrt_on_chip.png").stat().st_size > 10_000
    out = capsys.readouterr().out.splitlines()

    def row(name):
        (line,) = [ln for ln in out if ln.startswith(name + " ")]
        return line[len(name):].split()
    rtl, gold = row(plots.RTL_ON_CHIP), row(plots.GOLDEN_ON_CHIP)
    assert rtl == gold and float(rtl[2]) < 0.1, (rtl, gold)


def test_config_file_names_the_application(tmp_path):
    """``app`` in a --config file does what --app does (the sizes, and the models on chip)."""
    cfg = tmp_path / "c.toml"
    cfg.write_text('app = "tracker:Tracker"\non-chip = true\nstates = 4\n')
    proc = kfgen_in_process("ukf", "--config", cfg, "-o", tmp_path / "out")
    assert proc.returncode == 0, proc.stderr
    m = json.loads((tmp_path / "out" / "ukf.json").read_text())
    assert (m["parameters"]["app"], m["parameters"]["on_chip"], list(m["cycles"])) == (TRACKER, True, ["iteration", "noise"])
    cfg.write_text('app = "nosuch:App"\non-chip = true\n')
    proc = kfgen_in_process("ukf", "--config", cfg, "-o", tmp_path / "bad")
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and f"(from {cfg} (app))" in proc.stderr, \
        proc.stderr


#: An application whose f has words that read only u (computed once for every point), an
#: exp, a division and a maximum; its control input is two long.
SHARED_APP = '''
import numpy as np
from kfgen.sim.ukf.app import Scenario, UkfApplication


class Steered(UkfApplication):
    n, nw, nv, m, nu = 3, 3, 2, 2, 2
    dt = 0.05
    x0 = np.array([0.2, -0.1, 0.3])
    P0 = np.eye(3) * 0.2
    Q = np.eye(3) * 1e-3
    R = np.eye(2) * 1e-2

    def f(self, x, w, u, dt):
        gain = np.exp(-0.5 * (u[0] * u[0] + u[1] * u[1]))  # reads only u: once for every point
        push = np.array([u[0], u[1], u[0] - u[1]]) * gain * dt
        return x + push + np.array([x[1], -x[0], 0.0]) * dt / (1.0 + x[2] * x[2]) + w

    def h(self, x, v):
        return np.array([np.maximum(x[0], x[1]), x[2] * 2.0]) + v

    def scenario(self, steps, seed):
        rng = np.random.default_rng(seed)
        u = rng.normal(0, 0.5, (steps, 2))
        x, truth, z = self.x0.copy(), [], []
        for k in range(steps):
            x = self.f(x, rng.normal(0, 0.03, 3), u[k], self.dt)
            truth.append(x)
            z.append(self.h(x, rng.normal(0, 0.1, 2)))
        return Scenario(np.arange(1, steps + 1) * self.dt, np.array(truth), u, np.array(z))
'''


def test_shared_words_and_control_input(tmp_path):
    """Words that read only u are computed once (a region of their own), and the on-chip
    core in binary64 equals the three-step core with software f and h to 1e-9."""
    from kfgen.sim.ukf.app import load_app
    path = tmp_path / "steered.py"
    path.write_text(SHARED_APP)
    spec = f"{path}:Steered"
    app = load_app(spec)
    p = UkfParams(**app.core_parameters(), app=spec, on_chip=True, format="binary64")
    progs = programs(p)
    assert p.models.f.shared and progs.layout["f_shared"].size == len(p.models.f.shared)
    assert sum(op.unit == "exp" for op in progs.iteration.ops) == 1  # the gain, once for all points
    sc = checked_scenario(app, 30, 4)
    chip = run_golden(app, sc, "binary64", on_chip=spec)
    soft = run_golden(app, sc, "binary64")
    assert np.max(np.abs(chip - soft)) < 1e-9 and np.max(np.abs(chip - run_reference(app, sc))) < 1e-9


@pytest.mark.full
@pytest.mark.verilator
def test_shared_words_rtl(build_root):
    """The Steered application's core (u, a shared exp, a divider, a maximum) on the RTL."""
    out = build_root / "ukf_steered"
    out.mkdir(parents=True, exist_ok=True)
    (out / "steered.py").write_text(SHARED_APP)
    kfgen("ukf", "--app", f"{out / 'steered.py'}:Steered", "--on-chip", "--name", "ukf_steered", "-o", out)
    model = build_core(out, "ukf_steered", VERILATOR_CACHE)
    run_tb(model, out, "ukf_steered", TB, ["on_chip_iterations"], "steered", {"KFGEN_TB_ITERATIONS": "4"})
