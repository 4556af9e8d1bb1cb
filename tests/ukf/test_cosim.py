"""HW/SW co-simulation (kfgen.sim.ukf.cosim): the nanosatellite and tracker applications run
on the generated Verilog, driven through AXI by the Python software side and by the
generated C driver; every word read back equals the golden model's, both processors produce
the same estimates, and the chapter's accuracy claim holds on the co-simulated core."""

import numpy as np
import pytest

from kfgen.sim.ukf.accuracy import run_reference
from kfgen.sim.ukf.app import load_app
from kfgen.sim.ukf.apps.nanosat import attitude_error_deg
from kfgen.sim.ukf.run import build_driver, build_ukf_core, run_cosim

from helpers import VERILATOR_CACHE, kfgen

NANOSAT = "kfgen.sim.ukf.apps.nanosat:Nanosat"
TRACKER = "kfgen.sim.ukf.apps.tracker:Tracker"
#: Iterations of the nanosatellite's Python run (100 a second): convergence takes about 0.3 s
#: (0.03-0.35 s over seeds), the chapter's claim is checked from CONVERGED on. The whole
#: 10 s run is ``make test-full``'s (and ``make plots``').
STEPS = 60
CONVERGED = 0.4
#: Iterations of the C driver's run (the same words as the first ones of the Python run).
C_STEPS = 5


@pytest.fixture(scope="module")
def nanosat_core(build_root):
    """The default core (the chapter's 7/6/7/6 at P = 1), which the nanosatellite's sizes
    are: the same Verilog, hence the same Verilator build, as test_ukf_core's m20_p1."""
    app = load_app(NANOSAT)
    assert app.core_parameters() == {"states": 7, "observations": 6, "process_noise": 7,
                                     "measurement_noise": 6, "w0": 0.0}
    top = "ukf_m20_p1"
    out = build_root / top
    kfgen("ukf", "--name", top, "-o", out)
    return out, top, build_ukf_core(out, top, VERILATOR_CACHE)


@pytest.fixture(scope="module")
def nanosat_python(nanosat_core):
    out, top, model = nanosat_core
    npz = out / "cosim_python.npz"
    run_cosim(model, out, top, "python_processor", "cosim_python", NANOSAT, STEPS, out=npz)
    with np.load(npz) as d:
        return {k: d[k] for k in d.files}


@pytest.mark.verilator
@pytest.mark.xdist_group("cosim_nanosat")
def test_nanosat_python_processor(nanosat_python):
    """The chapter's claim on the generated core: attitude error below 0.1 degree after
    convergence, the gyro bias estimate converging to the true bias; and the RTL's
    estimates beside the float64 reference's."""
    check_nanosat(nanosat_python, CONVERGED)


def check_nanosat(d, converged):
    t, x, truth = d["t"], d["estimates"], d["truth"]
    err = attitude_error_deg(x[:, :4], truth[:, :4])
    after = t >= converged
    assert after.sum() >= 20 and err[after].max() < 0.1, err[after].max()
    bias = np.linalg.norm(x[:, 4:] - truth[:, 4:], axis=1)  # rad/s; 0.77 at the start
    assert bias[after].mean() < 0.02, (bias[0], bias[after].mean())
    app = load_app(NANOSAT)
    ref = run_reference(app, app.scenario(len(t), 1))
    ref_err = attitude_error_deg(ref[:, :4], truth[:, :4])
    assert np.max(np.abs(err[after] - ref_err[after])) < 0.01


@pytest.mark.full
@pytest.mark.verilator
def test_nanosat_whole_run(nanosat_core):
    """The whole 10 s scenario (1000 iterations): the claim from the first second on."""
    out, top, model = nanosat_core
    npz = out / "cosim_whole.npz"
    run_cosim(model, out, top, "python_processor", "cosim_whole", NANOSAT, 1000, out=npz)
    with np.load(npz) as d:
        check_nanosat({k: d[k] for k in d.files}, 1.0)


@pytest.mark.verilator
@pytest.mark.xdist_group("cosim_nanosat")
def test_nanosat_c_processor(nanosat_core, nanosat_python):
    """The generated C driver, built with gcc -std=c99 -Wall -Wextra -Werror, polling STATUS:
    every word equals the golden model's, and its estimates equal the Python processor's."""
    out, top, model = nanosat_core
    lib = build_driver(out, top)
    npz = out / "cosim_c.npz"
    run_cosim(model, out, top, "c_processor", "cosim_c", NANOSAT, C_STEPS, wait="poll", out=npz, driver=lib)
    with np.load(npz) as d:
        assert np.array_equal(d["estimates"], nanosat_python["estimates"][:C_STEPS])


@pytest.mark.verilator
@pytest.mark.parametrize("processor,beats,wait", [
    ("python_processor", "single", "poll"),
    # the C driver with bursts and irq runs on the nanosatellite in every run
    pytest.param("c_processor", "burst", "irq", marks=pytest.mark.full)])
@pytest.mark.xdist_group("cosim_tracker")
def test_tracker(build_root, processor, beats, wait):
    """The range-bearing tracker on a core sized by ``--app`` in binary64 (two bus words an
    element) at P = 2: single beats and polling by the Python processor, bursts and irq by
    the C driver; the estimates close to the float64 reference's."""
    top = "ukf_tracker"
    out = build_root / top
    if not (out / f"{top}.json").exists():
        kfgen("ukf", "--app", TRACKER, "--format", "binary64", "--pes", "2", "--name", top, "-o", out)
    model = build_ukf_core(out, top, VERILATOR_CACHE)
    npz = out / f"{processor}.npz"
    lib = build_driver(out, top) if processor == "c_processor" else None
    steps = 6
    run_cosim(model, out, top, processor, f"{processor}_{beats}_{wait}", TRACKER, steps, beats=beats, wait=wait,
              out=npz, driver=lib)
    app = load_app(TRACKER)
    ref = run_reference(app, app.scenario(steps, 1))
    with np.load(npz) as d:
        assert np.max(np.abs(d["estimates"] - ref)) < 1e-9 * max(1.0, np.max(np.abs(ref)))


@pytest.mark.parametrize("fmt", ["binary32", "binary64", "binary16"])
def test_c_driver_builds(tmp_path, fmt):
    """The C driver compiles as C99 with every warning an error, both for a bare-metal
    processor (volatile MMIO) and with the hooks; a format C cannot convert gets none."""
    import subprocess

    kfgen("ukf", "--states", "2", "--observations", "1", "--process-noise", "1", "--measurement-noise", "1",
          "--format", fmt, "-o", tmp_path)
    if fmt == "binary16":
        assert not list(tmp_path.glob("*_driver.*"))
        return
    for flags in ([], ["-DKFGEN_MMIO_HOOKS"]):
        proc = subprocess.run(["gcc", "-std=c99", "-Wall", "-Wextra", "-Werror", "-O2", *flags, "-c",
                               str(tmp_path / "ukf_driver.c"), "-o", str(tmp_path / "ukf_driver.o")],
                              capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr
