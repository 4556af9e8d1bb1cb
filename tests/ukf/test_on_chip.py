"""The UKF with f and h on chip (``kfgen ukf --app MODULE:CLASS --on-chip``): the
application's models traced into the engine, one ``iteration`` step per measurement.

The golden model of the on-chip core is held against the float64 reference and against the
three-step core with software f and h; the RTL (Verilator, cocotbext-axi) against the golden
model word for word, the iteration's cycles against the manifest; the command line's
refusals; the regenerate command."""

import json
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
from kfgen.sim.ukf.run import build_ukf_core, run_ukf

from helpers import VERILATOR_CACHE, kfgen, kfgen_in_process

NANOSAT = "nanosat:Nanosat"
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


def test_iteration_program_and_map():
    """One step, iteration, at CTRL.step = 3; u after z; the moved points written by the
    core (read-only); the schedule within 10 % of its multiply-adds at P = 1."""
    p = UkfParams(app=NANOSAT, on_chip=True)
    progs = programs(p)
    assert list(progs.steps) == ["iteration"]
    assert p.nu == 3 and progs.layout["u"].base == progs.layout["z"].base + p.m
    (sched,) = schedules(p, progs).values()
    fmas = progs.iteration.fma_count
    assert fmas <= sched.cycles <= 1.1 * fmas
    off = programs(UkfParams())
    assert fmas == sum(s.fma_count for s in off.steps.values()) + p.N * p.models.fma_count


@pytest.fixture(scope="module")
def generated(build_root):
    out = build_root / "ukf_on_chip"
    kfgen("ukf", *ON_CHIP, "--name", "ukf_oc", "-o", out)
    return out


def test_manifest(generated):
    m = json.loads((generated / "ukf_oc.json").read_text())
    p = UkfParams(**m["parameters"])
    (sched,) = schedules(p).values()
    assert m["cycles"] == {"iteration": sched.cycles + OVERHEAD}
    ctrl = next(r for r in m["registers"] if r["name"] == "CTRL")
    assert next(f for f in ctrl["fields"] if f["name"] == "step")["values"] == {"iteration": 3}
    ident = next(r for r in m["registers"] if r["name"] == "ID")
    assert next(f for f in ident["fields"] if f["name"] == "version")["reset"] == 2
    regions = {mm["name"]: mm for mm in m["memories"]}
    assert regions["u"]["shape"] == [3, 1] and regions["u"]["access"] == "rw"
    assert regions["sigma_points_f"]["access"] == regions["sigma_points_h"]["access"] == "ro"


def test_regenerate_command(generated, tmp_path):
    header = (generated / "ukf_oc.core").read_text().split("\n\n", 1)[0]
    (line,) = [ln[2:].strip() for ln in header.splitlines() if ln.startswith("#   kfgen ") and ln.endswith(" -o DIR")]
    assert "--app nanosat:Nanosat --on-chip" in line
    argv = line.split()[1:-2]
    assert kfgen_in_process(*argv, "-o", tmp_path).returncode == 0
    for p in generated.iterdir():
        if p.is_file():
            assert p.read_bytes() == (tmp_path / p.name).read_bytes(), p.name


@pytest.mark.verilator
@pytest.mark.xdist_group("ukf_on_chip")
def test_rtl_iterations(generated):
    """Lint clean; the nanosatellite's scenario on the RTL, one start per iteration, every
    region word for word against the golden model, the cycles equal to the manifest's."""
    rc, messages = lint(generated / "ukf_oc.v")
    assert rc == 0 and not messages, "\n".join(messages)
    model = build_ukf_core(generated, "ukf_oc", VERILATOR_CACHE)
    run_ukf(model, generated, "ukf_oc", ["on_chip_iterations"], "on_chip", {"KFGEN_TB_ITERATIONS": "3"})


@pytest.mark.verilator
@pytest.mark.xdist_group("ukf_on_chip")
def test_c_processor(generated, tmp_path):
    """The generated C driver's TOP_iterate(dev, u, z) on the same build: every word against
    the golden model, and the estimates those of the golden model's on-chip core."""
    from kfgen.sim.ukf.run import build_driver, run_cosim
    model = build_ukf_core(generated, "ukf_oc", VERILATOR_CACHE)
    driver = build_driver(generated, "ukf_oc", tmp_path)
    npz = tmp_path / "c.npz"
    run_cosim(model, generated, "ukf_oc", "c_processor", "c_on_chip", NANOSAT, 3, seed=2, out=npz, driver=driver)
    app = Nanosat()
    want = run_golden(app, checked_scenario(app, 3, 2), on_chip=NANOSAT)
    with np.load(npz) as d:
        assert list(d["cycles_columns"]) == ["iteration", "transfer"]
        assert np.array_equal(d["estimates"], want)


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


class Sine(Base):
    def h(self, x, v):
        return np.array([np.sin(x[0])]) + v


class Wrong(Base):
    def h(self, x, v):
        return x + v[0]
'''


@pytest.mark.parametrize("cls, says", [
    ("Branch", r"comparison, `if` or conversion of a traced value does not trace (FILE:23)"),
    ("Sine", "np.sin does not trace (FILE:30): the engine has no unit for it yet"),
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
    ([*ON_CHIP, "--states", "6"], "--app: nanosat:Nanosat has n, nw, nv, m = (7, 7, 6, 6), the core (6, 7, 6, 6)"),
    (["--app", "tracker:Tracker", "--on-chip"], "np.arctan2 does not trace"),
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
    rows = [r for r in section.splitlines() if r.startswith("| ") and r[2].isdigit()]
    assert len(rows) == 4
    for row in rows:
        pes, chip, steps, fmas = (int(c.strip().replace(",", "")) for c in row.strip("|").split("|"))
        p = UkfParams(app=NANOSAT, on_chip=True, pes=pes)
        progs = programs(p)
        (sched,) = schedules(p, progs).values()
        assert (chip, fmas) == (sched.cycles + OVERHEAD, progs.iteration.fma_count), row
        assert steps == sum(s.cycles + OVERHEAD for s in schedules(UkfParams(pes=pes)).values()), row


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
