"""HW/SW co-simulation (kfgen.sim.ukf.cosim): the nanosatellite and tracker applications run
on the generated Verilog, driven through AXI by the Python software side and by the
generated C driver; every word read back equals the golden model's, both processors produce
the same estimates, and the chapter's accuracy claim holds on the co-simulated core."""

import numpy as np
import pytest

from kfgen.sim.engine.run import build_core
from kfgen.sim.ukf.accuracy import run_reference
from kfgen.sim.ukf.app import load_app
from kfgen.sim.ukf.apps.nanosat import attitude_error_deg
from kfgen.sim.ukf.run import build_driver, run_cosim

from helpers import ROOT, VERILATOR_CACHE, kfgen

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
    return out, top, build_core(out, top, VERILATOR_CACHE)


@pytest.fixture(scope="module")
def nanosat_python(nanosat_core):
    out, top, model = nanosat_core
    npz = out / "cosim_python.npz"
    run_cosim(model, out, top, "python_processor", "cosim_python", NANOSAT, STEPS, out=npz)
    with np.load(npz) as d:
        return {k: d[k] for k in d.files}


@pytest.mark.full  # the chapter's core (M = 20) a second time; make test co-simulates the pendulum, Python and C
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


@pytest.mark.full  # the chapter's core (M = 20) a second time; make test co-simulates the pendulum, Python and C
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
    pytest.param("python_processor", "single", "poll", marks=pytest.mark.full),
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
    model = build_core(out, top, VERILATOR_CACHE)
    npz = out / f"{processor}.npz"
    lib = build_driver(out, top) if processor == "c_processor" else None
    steps = 6
    run_cosim(model, out, top, processor, f"{processor}_{beats}_{wait}", TRACKER, steps, beats=beats, wait=wait,
              out=npz, driver=lib)
    app = load_app(TRACKER)
    ref = run_reference(app, app.scenario(steps, 1))
    with np.load(npz) as d:
        assert np.max(np.abs(d["estimates"] - ref)) < 1e-9 * max(1.0, np.max(np.abs(ref)))


@pytest.mark.parametrize("fmt,form", [("binary32", "ldl"), pytest.param("binary64", "ldl", marks=pytest.mark.full),
                                      pytest.param("binary16", "ldl", marks=pytest.mark.full), ("binary32", "sqrt")])
def test_c_driver_builds(tmp_path, fmt, form):
    """The C driver compiles as C99 with every warning an error, both for a bare-metal
    processor (volatile MMIO) and with the hooks (the square-root form's with its Cholesky
    factor of P0); a format C cannot convert gets none."""
    import subprocess

    kfgen("ukf", "--states", "2", "--observations", "1", "--process-noise", "1", "--measurement-noise", "1",
          "--format", fmt, "--form", form, "-o", tmp_path)
    assert ("UKF__SQRTP_OFFSET" in (tmp_path / "ukf.h").read_text()) == (form == "sqrt")
    if fmt == "binary16":
        assert not list(tmp_path.glob("*_driver.*"))
        return
    for flags in ([], ["-DKFGEN_MMIO_HOOKS"]):
        proc = subprocess.run(["gcc", "-std=c99", "-Wall", "-Wextra", "-Werror", "-O2", *flags, "-c",
                               str(tmp_path / "ukf_driver.c"), "-o", str(tmp_path / "ukf_driver.o")],
                              capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr


# ---------------------------------------------------------------- python -m kfgen.gen.cosim ukf

#: The README's application (its Pendulum), without a scenario.
NO_SCENARIO = '''
import numpy as np
from kfgen.sim.ukf.app import UkfApplication

class Pendulum(UkfApplication):
    n, nw, nv, m = 2, 2, 1, 1
    dt = 0.01
    x0, P0 = np.array([0.1, 0.0]), np.eye(2)
    Q, R = np.eye(2) * 1e-4, np.array([[1e-2]])

    def f(self, x, w, u, dt):
        return x + dt * np.array([x[1], -9.81 * np.sin(x[0])]) + w

    def h(self, x, v):
        return np.array([np.sin(x[0])]) + v

class Indefinite(Pendulum):
    P0 = np.array([[1.0, 2.0], [2.0, 1.0]])
'''

#: The Pendulum of docs/examples with a measurement beyond binary32's range at iteration 2:
#: the core's update raises err_nan there.
GLITCH = f'''
import importlib.util

spec = importlib.util.spec_from_file_location("pendulum_example", {str(ROOT / "docs" / "examples" / "pendulum.py")!r})
example = importlib.util.module_from_spec(spec)
spec.loader.exec_module(example)

class Glitch(example.Pendulum):
    def scenario(self, steps, seed):
        sc = super().scenario(steps, seed)
        sc.z[2] = 1e39
        return sc

class ShortZ(example.Pendulum):
    def scenario(self, steps, seed):
        sc = super().scenario(steps, seed)
        return sc._replace(z=sc.z[:-1])
'''


def cosim_main(*args):
    """``python -m kfgen.gen.cosim ukf ARGS`` in this process: (exit status, stdout, stderr)."""
    import contextlib
    import io

    from kfgen.gen.cosim import main

    with contextlib.redirect_stdout(io.StringIO()) as out, contextlib.redirect_stderr(io.StringIO()) as err:
        code = main(["ukf", *(str(a) for a in args)])
    return code, out.getvalue(), err.getvalue()


@pytest.mark.parametrize("args,says", [
    (["--app", "{tmp}/readme.py:Pendulum"], "Pendulum defines no scenario(steps, seed)"),
    (["--app", "{tmp}/readme.py:Indefinite"], "Indefinite.P0 must be positive definite"),
    (["--app", "{tmp}/glitch.py:ShortZ", "--steps", "7"],
     "ShortZ.scenario(7, 1).z must be a finite array of shape (7, 1), not shape (6, 1)"),
    (["--app", "nanosat:Nanosat", "--format", "binary16", "--processor", "c"],
     "--processor c: the C driver converts binary32 and binary64 elements only, not binary16 "
     "(use --processor python)"),
    (["--app", "tracker:Tracker", "--steps", "0"], "--steps must be a positive integer, not 0"),
])
def test_run_rejects_before_building(tmp_path, monkeypatch, args, says):
    """What cannot run is refused in one line, exit 2, before anything is generated or built."""
    import kfgen.gen.cosim as cosim

    def never(*_a, **_k):
        raise AssertionError("generated or built")
    monkeypatch.setattr(cosim, "write_core", never)
    monkeypatch.setattr(cosim, "build_core", never)
    (tmp_path / "readme.py").write_text(NO_SCENARIO)
    (tmp_path / "glitch.py").write_text(GLITCH)
    code, out, err = cosim_main(*(a.replace("{tmp}", str(tmp_path)) for a in args), "-o", tmp_path / "work")
    assert code == 2 and err.startswith(f"cosim: error: {says}") and err.count("\n") == 1, err
    assert not out and not (tmp_path / "work").exists()


@pytest.mark.parametrize("args,says", [
    ([], "the following arguments are required: --app"),
    (["--app", "tracker:Tracker", "--processor", "arm"], "argument --processor: invalid choice: 'arm'"),
    (["--app", "tracker:Tracker", "--steps", "many"], "argument --steps: invalid int value: 'many'"),
])
def test_run_usage_errors_are_one_line(tmp_path, args, says):
    import contextlib
    import io

    from kfgen.gen.cosim import main

    with contextlib.redirect_stderr(io.StringIO()) as err, pytest.raises(SystemExit) as info:
        main(["ukf", *args, "-o", str(tmp_path / "work")])
    assert info.value.code == 2 and err.getvalue().startswith(f"cosim: error: {says}"), err.getvalue()
    assert err.getvalue().count("\n") == 1 and not (tmp_path / "work").exists()


def test_run_help_gives_defaults_and_exit_codes():
    import contextlib
    import io

    from kfgen.gen.cosim import main

    with contextlib.redirect_stdout(io.StringIO()) as out, pytest.raises(SystemExit) as info:
        main(["ukf", "--help"])
    text = " ".join(out.getvalue().split())
    assert info.value.code == 0
    for says in ("--seed SEED the scenario's seed (default 1)", "AXI bursts or single beats (default burst)",
                 "wait for irq or poll STATUS (default irq)", "iterations (default 20)",
                 "2 bad arguments or application", "3 the core raised a numerical fault"):
        assert says in text, says


def test_run_fault_is_one_line_exit_3(tmp_path, monkeypatch):
    """A StepError out of the co-simulation: one line naming the iteration, the step and the
    bit, exit 3 (the runner's part; the run's part is test_pendulum_fault)."""
    import kfgen.gen.cosim as cosim
    from kfgen.sim.ukf.software import StepError

    def fault(*_a, **_k):
        raise StepError("sig_gen", "err_pivot", 7)
    monkeypatch.setattr(cosim, "write_core", lambda core, params, out: (tmp_path, None))
    monkeypatch.setattr(cosim, "build_core", lambda *a, **k: None)
    monkeypatch.setattr(cosim, "run_cosim", fault)
    code, out, err = cosim_main("--app", "tracker:Tracker", "--steps", "3", "-o", tmp_path)
    assert code == 3 and not out and err.count("\n") == 1, err
    assert err.startswith("cosim: error: the core raised a numerical fault at iteration 7: sig_gen raised "
                          "err_pivot (a pivot not positive: a covariance that is not positive definite)"), err


@pytest.fixture(scope="module")
def pendulum_work(build_root):
    """One work directory for the Pendulum's runs: one generated core (M = 5, P = 1), one
    Verilator build (about 20 s) for all of them."""
    return build_root / "pendulum_cosim"


def run_command(*args, cwd):
    """``python -m kfgen.gen.cosim ukf ARGS`` as a user runs it: not under pytest (whose
    variable makes cocotb's runner log a failed test itself)."""
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k != "PYTEST_CURRENT_TEST"}
    return subprocess.run([sys.executable, "-m", "kfgen.gen.cosim", "ukf", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, env=env)


@pytest.mark.verilator
@pytest.mark.xdist_group("cosim_pendulum")
def test_pendulum_example_cosimulates(pendulum_work):
    """The docs' example as the docs run it (docs/examples/pendulum.py, from the checkout's
    top): every word equal to the golden model's, and cosim.npz as documented."""
    from kfgen.sim.ukf.accuracy import run_golden
    from kfgen.sim.ukf.app import checked_scenario

    steps = 5
    proc = run_command("--app", "docs/examples/pendulum.py:Pendulum", "--steps", steps, "-o", pendulum_work, cwd=ROOT)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert proc.stdout.startswith(f"{steps} iterations of docs/examples/pendulum.py:Pendulum on ukf_app (P = 1, "
                                  "binary32), python processor, burst transfers, irq: every word equal"), proc.stdout
    app = load_app(str(ROOT / "docs" / "examples" / "pendulum.py") + ":Pendulum")
    sc = checked_scenario(app, steps, 1)
    with np.load(pendulum_work / "ukf_app" / "cosim.npz") as d:
        assert sorted(d.files) == ["cycles", "cycles_columns", "estimates", "sim_cycles", "t", "truth", "wall_s"]
        assert np.array_equal(d["estimates"], run_golden(app, sc, "binary32"))
        assert np.array_equal(d["truth"], sc.truth) and np.array_equal(d["t"], sc.t)
        assert d["cycles"].shape == (steps, 4) and list(d["cycles_columns"]) == ["sig_gen", "predict", "update",
                                                                                 "transfer"]
        assert np.all(d["cycles"] > 0) and int(d["sim_cycles"]) > d["cycles"].sum() and float(d["wall_s"]) > 0


@pytest.mark.verilator
@pytest.mark.xdist_group("cosim_pendulum")
# make test-full (17 s): make test runs the KF's and EKF's C drivers on their cores, with a fault
@pytest.mark.full
@pytest.mark.parametrize("processor", ["python", "c"])
def test_pendulum_fault(pendulum_work, tmp_path, processor):
    """A numerical fault in the core (a measurement beyond binary32 at iteration 2): one line
    naming the iteration, the step and the bit, exit 3, from either processor; the app given
    as a file relative to the current directory (the simulation runs elsewhere)."""
    (tmp_path / "glitch.py").write_text(GLITCH)
    proc = run_command("--app", "glitch.py:Glitch", "--steps", 4, "--processor", processor, "-o", pendulum_work,
                       cwd=tmp_path)
    assert proc.returncode == 3 and not proc.stdout and proc.stderr.count("\n") == 1, proc.stdout + proc.stderr
    assert proc.stderr.startswith("cosim: error: the core raised a numerical fault at iteration 2: update raised "
                                  "err_nan (a NaN or infinity in a result); log "), proc.stderr
    assert not (pendulum_work / "ukf_app" / "cosim.npz").exists()


#: The docs' Pendulum with an f or an h that is wrong (the lines the test names: 12, 15, 19).
BUGGY = f'''
import importlib.util

import numpy as np

spec = importlib.util.spec_from_file_location("pendulum_example", {str(ROOT / "docs" / "examples" / "pendulum.py")!r})
example = importlib.util.module_from_spec(spec)
spec.loader.exec_module(example)

class Raises(example.Pendulum):
    def f(self, x, w, u, dt):
        return x[5] + w

class LongH(example.Pendulum):
    def h(self, x, v):
        return np.array([x[0], x[1]]) + v[0]

class SigmaOnly(example.Pendulum):
    def h(self, x, v):
        return np.array([x[0]]) + v if x[0] == self.x0[0] else None
'''


@pytest.mark.parametrize("cls,says", [
    ("Raises", "Raises.f ({file}:12) raised IndexError: index 5 is out of bounds for axis 0 with size 2 "
               "(called on x0)"),
    ("LongH", "LongH.h ({file}:15) returned shape (2,), not m = 1 values (called on x0)"),
    ("SigmaOnly", "SigmaOnly.h ({file}:19) returned None, not m = 1 values "
                  "(called on x0 + chol(P0)[:, 0])"),
])
def test_buggy_f_or_h_is_refused_before_anything_is_built(tmp_path, monkeypatch, cls, says):
    """An f or an h that raises or returns the wrong length, without --on-chip: one line naming
    the function, its file:line and what was wrong, exit 2, nothing generated or built."""
    import kfgen.gen.cosim as cosim

    def never(*_a, **_k):
        raise AssertionError("generated or built")
    monkeypatch.setattr(cosim, "write_core", never)
    monkeypatch.setattr(cosim, "build_core", never)
    path = tmp_path / "buggy.py"
    path.write_text(BUGGY)
    code, out, err = cosim_main("--app", f"{path}:{cls}", "--steps", 2, "-o", tmp_path / "work")
    assert code == 2 and not out and err.count("\n") == 1, err
    assert err == f"cosim: error: {says.format(file=path)}\n", err
    assert not (tmp_path / "work").exists()


@pytest.mark.full  # generates the on-chip pendulum twice (13 s)
def test_relative_and_absolute_app_paths_generate_the_same_bytes(tmp_path, monkeypatch):
    """The co-simulation's on-chip core from ``myapps/pendulum.py:Pendulum`` (relative to the
    current directory) and from its absolute path: every generated file the same bytes, the
    application recorded by its file's name."""
    import shutil

    import kfgen.gen.cosim as cosim

    class Generated(Exception):
        pass

    def stop(*_a, **_k):
        raise Generated
    monkeypatch.setattr(cosim, "build_core", stop)
    (tmp_path / "myapps").mkdir()
    shutil.copy(ROOT / "docs" / "examples" / "pendulum.py", tmp_path / "myapps" / "pendulum.py")
    monkeypatch.chdir(tmp_path)
    for spec, out in (("myapps/pendulum.py:Pendulum", "rel"), (f"{tmp_path}/myapps/pendulum.py:Pendulum", "abs")):
        with pytest.raises(Generated):
            cosim_main("--app", spec, "--on-chip", "-o", tmp_path / out)
    rel, abs_ = (sorted(p for p in (tmp_path / d / "ukf_app").rglob("*") if p.is_file()) for d in ("rel", "abs"))
    assert [p.name for p in rel] == [p.name for p in abs_] and len(rel) > 5
    for a, b in zip(rel, abs_):
        assert a.read_bytes() == b.read_bytes(), a.name
    manifest = (tmp_path / "rel" / "ukf_app" / "ukf_app.json").read_text()
    assert '"app": "pendulum.py:Pendulum"' in manifest and str(tmp_path) not in manifest


@pytest.mark.full  # its own on-chip build; make test checks the bytes without one (above)
@pytest.mark.verilator
def test_on_chip_app_given_by_a_relative_path(build_root, tmp_path):
    """``--app myapps/pendulum.py:Pendulum --on-chip`` from the directory that holds myapps (the
    documented form): the run, in another directory, finds the application (two iterations of
    the smallest on-chip core)."""
    import shutil

    (tmp_path / "myapps").mkdir()
    shutil.copy(ROOT / "docs" / "examples" / "pendulum.py", tmp_path / "myapps" / "pendulum.py")
    proc = run_command("--app", "myapps/pendulum.py:Pendulum", "--on-chip", "--steps", 2,
                       "-o", build_root / "pendulum_on_chip", cwd=tmp_path)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert proc.stdout.startswith("2 iterations of myapps/pendulum.py:Pendulum on ukf_app"), proc.stdout
