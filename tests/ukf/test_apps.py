"""UKF applications (kfgen.sim.ukf.app): the loader and its errors, the nanosatellite and
tracker applications, their accuracy in the float64 reference and in the bit-exact binary32
golden model of their cores, and ``kfgen ukf --app``."""

import json
import sys

import numpy as np
import pytest

from kfgen.hdl.ukf.params import UkfParams
from kfgen.sim.ukf.accuracy import run_golden, run_reference
from kfgen.sim.ukf.app import AppError, UkfApplication, checked_scenario, load_app
from kfgen.sim.ukf.apps.nanosat import (G, STEPS, Nanosat, attitude_error_deg, euler_quaternion,
                                        euler_rotation, quat_multiply, rotation)
from kfgen.sim.ukf.apps.tracker import Tracker
from kfgen.sim.ukf.software import StepError

from helpers import ROOT, kfgen, kfgen_in_process

NANOSAT = "kfgen.sim.ukf.apps.nanosat:Nanosat"
#: Iterations of the default golden run: past convergence (about 0.3 s) and half a second more.
SHORT = 150

APP_FILE = '''
import numpy as np
from kfgen.sim.ukf.app import UkfApplication

class Small(UkfApplication):
    n, nw, nv, m = 3, 2, 1, 1
    W0 = 0.25
    dt = 0.5
    x0 = np.zeros(3)
    P0 = np.eye(3)
    Q = np.eye(2)
    R = np.eye(1)

class WrongShape(Small):
    Q = np.eye(3)

class NoSizes(UkfApplication):
    pass

class Huge(Small):
    n = 300
    x0 = np.zeros(300)
    P0 = np.eye(300)

class Indefinite(Small):
    P0 = np.diag([1.0, -1.0, 1.0])

class NanP0(Small):
    P0 = [[1.0, np.nan, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]

class Asymmetric(Small):
    Q = [[1.0, 0.5], [0.0, 1.0]]

class SemidefiniteR(Small):
    R = np.zeros((1, 1))

class InfX0(Small):
    x0 = [0.0, np.inf, 0.0]
'''


@pytest.fixture
def app_file(tmp_path):
    path = tmp_path / "my_apps.py"
    path.write_text(APP_FILE)
    return path


# ---------------------------------------------------------------- the loader

def test_load_module_class():
    app = load_app(NANOSAT)
    assert isinstance(app, Nanosat) and app.n + app.nw + app.nv == 20
    assert app.core_parameters() == {"states": 7, "observations": 6, "process_noise": 7,
                                     "measurement_noise": 6, "w0": 0.0}


def test_load_file_and_current_directory(app_file, monkeypatch):
    app = load_app(f"{app_file}:Small")
    assert (app.n, app.nw, app.nv, app.m, app.W0) == (3, 2, 1, 1, 0.25)
    monkeypatch.chdir(app_file.parent)  # a module beside the user, as `kfgen` from there sees it
    assert type(load_app("my_apps:Small")).__name__ == "Small"


@pytest.mark.parametrize("spec,says", [
    ("Nanosat", "must be module:Class"),
    ("a:b:c", "must be module:Class"),
    (":Nanosat", "must be module:Class"),
    ("kfgen.sim.ukf.apps.nanosat:", "must be module:Class"),
    ("kfgen.sim.ukf.apps.nanosat:Nano sat", "is not a class name"),
    ("kfgen_no_such_module:App", "cannot import 'kfgen_no_such_module': ModuleNotFoundError"),
    ("no_such_file.py:App", "no such file"),
    ("kfgen.sim.ukf.apps.nanosat:Missing", "has no 'Missing'"),
    ("kfgen.sim.ukf.apps.nanosat:G", "is a float, not a UkfApplication class"),
    ("kfgen.sim.ukf.apps.nanosat:rotation", "rotation() failed: TypeError"),
    ("fractions:Fraction", "is a Fraction, not a UkfApplication"),
    ("{file}:WrongShape", "WrongShape.Q must be a finite array of shape (2, 2), not shape (3, 3)"),
    ("{file}:NoSizes", "NoSizes.n must be a positive integer, not None"),
    ("{file}:Indefinite", "Indefinite.P0 must be positive definite (a covariance the filter can factorise), "
                          "not with eigenvalue -1"),
    ("{file}:NanP0", "NanP0.P0 must be finite, not nan at [0, 1]"),
    ("{file}:Asymmetric", "Asymmetric.Q must be symmetric, not 0.5 at [0, 1] and 0.0 at [1, 0]"),
    ("{file}:SemidefiniteR", "SemidefiniteR.R must be positive definite"),
    ("{file}:InfX0", "InfX0.x0 must be finite, not inf at [1]"),
    ("{dir}/broken.py:Broken", "cannot import"),
])
def test_load_errors(app_file, spec, says):
    (app_file.parent / "broken.py").write_text("import numpy\nraise RuntimeError('two\\nlines')\n")
    spec = spec.replace("{dir}", str(app_file.parent)).replace("{file}", str(app_file))
    with pytest.raises(AppError) as info:
        load_app(spec)
    assert says in str(info.value) and "\n" not in str(info.value), str(info.value)
    assert isinstance(info.value, ValueError)


def test_short_names_of_shipped_apps():
    """``nanosat:Nanosat`` and ``tracker:Tracker`` (as the docs write them) are the shipped ones."""
    assert type(load_app("nanosat:Nanosat")) is Nanosat
    assert type(load_app("tracker:Tracker")) is Tracker
    with pytest.raises(AppError, match="module 'tracker' has no 'Nanosat'"):
        load_app("tracker:Nanosat")


@pytest.mark.parametrize("body,says", [
    ("from kfgen.sim.ukf.apps.tracker import Tracker as T\nclass Tracker(T):\n    dt = 2.0\n", None),
    ("import kfgen_no_such_dependency\n", "cannot import 'tracker': ModuleNotFoundError: No module named "
                                           "'kfgen_no_such_dependency'"),
])
def test_users_module_wins_over_a_shipped_name(tmp_path, monkeypatch, body, says):
    """A module of the user's named like a shipped one is the one loaded, even when it fails."""
    (tmp_path / "tracker.py").write_text(body)
    monkeypatch.chdir(tmp_path)
    monkeypatch.delitem(sys.modules, "tracker", raising=False)
    try:
        if says is None:
            app = load_app("tracker:Tracker")
            assert type(app).__module__ == "tracker" and app.dt == 2.0
        else:
            with pytest.raises(AppError) as info:
                load_app("tracker:Tracker")
            assert str(info.value) == says
    finally:
        sys.modules.pop("tracker", None)


def test_core_parameters_as_documented():
    """The docstring's use: the application's sizes and W0, with the core's own choices beside."""
    app = Tracker()
    p = UkfParams(**app.core_parameters(), format="binary64", pes=2)
    assert (p.n, p.m, p.nw, p.nv, p.w0, p.pes, p.format.name) == (4, 2, 2, 2, 0.0, 2, "binary64")
    assert "Returns" in UkfApplication.core_parameters.__doc__


def test_step_error_names_iteration_step_and_bit():
    exc = StepError("sig_gen", "err_pivot")
    assert str(exc) == "sig_gen raised err_pivot" and exc.iteration is None
    at = exc.at(3)
    assert (at.step, at.bit, at.iteration) == ("sig_gen", "err_pivot", 3)
    assert str(at) == "iteration 3: sig_gen raised err_pivot"


# ---------------------------------------------------------------- scenarios

PENDULUM = str(ROOT / "docs" / "examples" / "pendulum.py") + ":Pendulum"


def test_pendulum_example():
    """docs/examples/pendulum.py: sized, its scenario without a control input (u = None), and
    the reference and binary32 golden model following it."""
    app = load_app(PENDULUM)
    assert app.core_parameters() == {"states": 2, "observations": 1, "process_noise": 2,
                                     "measurement_noise": 1, "w0": 0.0}
    sc = checked_scenario(app, 200, 1)
    assert sc.u is None and sc.t.shape == (200,) and sc.truth.shape == (200, 2) and sc.z.shape == (200, 1)
    ref, gold = run_reference(app, sc), run_golden(app, sc, "binary32")
    assert np.max(np.abs(ref - gold)) < 1e-5
    # the angle beats the one a single measurement gives (arcsin z), by a factor 2 or more
    rms = np.sqrt(np.mean((ref[100:, 0] - sc.truth[100:, 0]) ** 2))
    raw = np.sqrt(np.mean((np.arcsin(np.clip(sc.z[100:, 0], -1, 1)) - sc.truth[100:, 0]) ** 2))
    assert rms < 0.5 * raw, (rms, raw)


def test_no_control_input_is_an_empty_u():
    """u = None in a scenario: f gets an empty array, shape (0,), in the reference, the golden
    model and (through the same Scenario.inputs) the co-simulation; (K, 0) is the same."""
    app = load_app(PENDULUM)
    seen = []
    original = app.f

    def f(x, w, u, dt):
        seen.append(np.shape(u))
        return original(x, w, u, dt)
    sc = checked_scenario(app, 3, 1)
    app.f = f
    ref = run_reference(app, sc)
    gold = run_golden(app, sc)
    assert set(seen) == {(0,)} and len(seen) > 6
    empty = sc._replace(u=np.zeros((3, 0)))
    assert np.array_equal(run_reference(app, empty), ref) and np.array_equal(run_golden(app, empty), gold)
    assert [u.shape for u, _ in sc.inputs()] == [(0,)] * 3


SCENARIOS = '''
import numpy as np
from kfgen.sim.ukf.app import Scenario, UkfApplication

class Base(UkfApplication):
    n, nw, nv, m = 2, 1, 1, 1
    dt = 1.0
    x0, P0, Q, R = np.zeros(2), np.eye(2), np.eye(1), np.eye(1)

    def scenario(self, steps, seed):
        k = np.arange(steps)
        return Scenario(k * 1.0, np.zeros((steps, 2)), None, np.zeros((steps, 1)))

class NoScenario(Base):
    scenario = __import__("kfgen.sim.ukf.app").sim.ukf.app.UkfApplication.scenario

class ShortZ(Base):
    def scenario(self, steps, seed):
        return super().scenario(steps, seed)._replace(z=np.zeros((steps - 1, 1)))

class FlatU(Base):
    def scenario(self, steps, seed):
        return super().scenario(steps, seed)._replace(u=np.zeros(steps))

class NanZ(Base):
    def scenario(self, steps, seed):
        sc = super().scenario(steps, seed)
        sc.z[1, 0] = np.nan
        return sc

class Raises(Base):
    def scenario(self, steps, seed):
        raise KeyError("two\\nlines")

class NotAScenario(Base):
    def scenario(self, steps, seed):
        return {"z": 1}
'''


@pytest.mark.parametrize("cls,says", [
    ("NoScenario", "NoScenario defines no scenario(steps, seed): a run needs its measurements "
                   "(see kfgen.sim.ukf.app.Scenario)"),
    ("ShortZ", "ShortZ.scenario(4, 1).z must be a finite array of shape (4, 1), not shape (3, 1)"),
    ("FlatU", "FlatU.scenario(4, 1).u must be None (no control input) or an array of shape (4, p), not shape (4,)"),
    ("NanZ", "NanZ.scenario(4, 1).z must be finite, not nan at [1, 0]"),
    ("Raises", "Raises.scenario(4, 1) failed: KeyError: 'two\\nlines'"),
    ("NotAScenario", "NotAScenario.scenario() must return a Scenario(t, truth, u, z), not dict"),
])
def test_scenario_errors(tmp_path, cls, says):
    path = tmp_path / "scenarios.py"
    path.write_text(SCENARIOS)
    assert checked_scenario(load_app(f"{path}:Base"), 4, 1).u is None
    with pytest.raises(AppError) as info:
        checked_scenario(load_app(f"{path}:{cls}"), 4, 1)
    assert str(info.value) == says


def test_base_class_models_are_required():
    app = UkfApplication()
    for call in (lambda: app.f(None, None, None, None), lambda: app.h(None, None), lambda: app.scenario(1, 1)):
        with pytest.raises(NotImplementedError):
            call()


# ---------------------------------------------------------------- the nanosatellite's models

def test_euler_quaternion_is_eq_43():
    for a in np.random.default_rng(5).uniform(-np.pi, np.pi, (20, 3)):
        q = euler_quaternion(*a)
        assert np.isclose(np.linalg.norm(q), 1.0)
        assert np.allclose(rotation(q), euler_rotation(*a), atol=1e-14)


def test_quaternion_product_composes_rotations():
    rng = np.random.default_rng(6)
    a, b = (euler_quaternion(*rng.uniform(-3, 3, 3)) for _ in range(2))
    assert np.allclose(rotation(quat_multiply(a, b)), rotation(a) @ rotation(b), atol=1e-14)


def test_f_subtracts_the_estimated_bias():
    app = Nanosat()
    x = np.r_[euler_quaternion(0.3, -0.2, 0.1), 0.05, -0.03, 0.04]
    # a gyro reading equal to the bias estimate: no rotation, the state stays
    assert np.allclose(app.f(x, np.zeros(7), x[4:], app.dt), x, atol=1e-15)
    # the bias changes the prediction, so the measurements see it (it is observable)
    other = np.r_[x[:4], 0.0, 0.0, 0.0]
    u = np.array([0.1, 0.2, -0.1])
    assert not np.allclose(app.h(app.f(x, np.zeros(7), u, app.dt)[:7], np.zeros(6)),
                           app.h(app.f(other, np.zeros(7), u, app.dt), np.zeros(6)))
    # the process noise enters f' (38), scaled by dt
    w = np.arange(7) * 1e-3
    assert np.allclose(app.f(x, w, u, app.dt) - app.f(x, np.zeros(7), u, app.dt), w * app.dt)


def test_h_is_gravity_and_field_in_the_rotated_frame():
    app = Nanosat()
    a = (0.4, -0.3, 1.2)
    z = app.h(np.r_[euler_quaternion(*a), 0, 0, 0], np.zeros(6))
    A = euler_rotation(*a)
    assert np.allclose(z, np.r_[G * A[:, 2], A[:, 0]])


def test_nanosat_scenario():
    app = Nanosat()
    sc = app.scenario(200, 3)
    assert sc.t.shape == (200,) and sc.truth.shape == (200, 7) and sc.u.shape == (200, 3) and sc.z.shape == (200, 6)
    assert np.isclose(sc.t[0], 0.01) and np.allclose(np.diff(sc.t), 0.01)
    assert all(np.array_equal(a, b) for a, b in zip(sc, app.scenario(200, 3)))  # seeded
    assert not np.array_equal(sc.z, app.scenario(200, 4).z)
    # f moves the truth to the truth with the noise-free rate (the gyro reading less the
    # gyro noise and less the true bias): the scenario and the model agree
    quiet = Nanosat()
    quiet.sigma_g = 0.0
    quiet.eta_d = 0.0
    qs = quiet.scenario(200, 3)
    x = np.r_[qs.truth[0, :4], qs.truth[0, 4:]]
    for k in range(1, 200):
        x = quiet.f(x, np.zeros(7), qs.u[k], quiet.dt)
    assert attitude_error_deg(x[:4], qs.truth[-1, :4])[0] < 1e-3
    # a slow tumble: about 5 deg/s
    rates = np.linalg.norm(qs.u - qs.truth[:, 4:], axis=1)
    assert np.all((np.radians(2) < rates) & (rates < np.radians(8)))
    # the initial estimate is within 20 degrees of the first attitude
    assert attitude_error_deg(app.x0[:4], sc.truth[0, :4])[0] < 20


# ---------------------------------------------------------------- accuracy

def _check_nanosat(x, sc, after: float):
    """The chapter's claims past time ``after``: attitude error below 0.1 degree, the bias
    estimate within 0.01 rad/s of the drifting true bias on average (the initial estimate,
    0, is 0.07 rad/s away)."""
    late = sc.t > after
    err = attitude_error_deg(x[:, :4], sc.truth[:, :4])
    bias_err = np.linalg.norm(x[:, 4:] - sc.truth[:, 4:], axis=1)
    assert err[late].max() < 0.1, err[late].max()
    assert bias_err[late].mean() < 0.01, bias_err[late].mean()
    return err


@pytest.fixture(scope="module")
def nanosat_run():
    app = Nanosat()
    return app, app.scenario(STEPS, 1)


def test_nanosat_reference(nanosat_run):
    app, sc = nanosat_run
    err = _check_nanosat(run_reference(app, sc), sc, 1.0)
    assert err[0] > 1.0 and np.linalg.norm(sc.truth[0, 4:] - app.x0[4:]) > 0.05  # it starts away


def test_nanosat_golden_binary32(nanosat_run):
    app, sc = nanosat_run
    short = type(sc)(*(a[:SHORT] for a in sc))
    x = run_golden(app, short, "binary32")
    err = _check_nanosat(x, short, 1.0)
    ref = attitude_error_deg(run_reference(app, short)[:, :4], short.truth[:, :4])
    assert np.max(np.abs(err - ref)[short.t > 0.5]) < 0.005


@pytest.mark.full
def test_nanosat_golden_binary32_whole_run(nanosat_run):
    app, sc = nanosat_run
    x = run_golden(app, sc, "binary32")
    err = _check_nanosat(x, sc, 1.0)
    ref = attitude_error_deg(run_reference(app, sc)[:, :4], sc.truth[:, :4])
    assert np.max(np.abs(err - ref)[sc.t > 0.5]) < 0.005


def test_chapter_p0_fails_in_binary32():
    """The chapter's P0 = I with sensors good enough for 0.1 degree: the float64 filter
    converges, but in binary32 the first update's P - Pxz K^T cancels entries of 1 down to
    1e-8, below binary32's resolution there, and the next sig_gen raises err_pivot. Hence
    the application's P0 = 0.01 I (kfgen.sim.ukf.apps.nanosat)."""
    app = Nanosat()
    app.P0 = np.eye(7)
    sc = app.scenario(SHORT, 1)
    _check_nanosat(run_reference(app, sc), sc, 1.0)
    with pytest.raises(StepError, match="sig_gen raised err_pivot"):
        run_golden(app, type(sc)(*(a[:3] for a in sc)), "binary32")


@pytest.mark.parametrize("run", ["reference", "golden"])
def test_tracker_converges(run):
    app = Tracker()
    sc = app.scenario(100, 2)
    x = run_reference(app, sc) if run == "reference" else run_golden(app, sc, "binary32")
    late = slice(50, None)
    pos = np.linalg.norm(x[:, :2] - sc.truth[:, :2], axis=1)
    vel = np.linalg.norm(x[:, 2:] - sc.truth[:, 2:], axis=1)
    raw = np.c_[sc.z[:, 0] * np.cos(sc.z[:, 1]), sc.z[:, 0] * np.sin(sc.z[:, 1])]  # one measurement
    raw_pos = np.linalg.norm(raw - sc.truth[:, :2], axis=1)
    assert np.sqrt(np.mean(pos[late] ** 2)) < 0.7 * np.sqrt(np.mean(raw_pos[late] ** 2))
    assert np.sqrt(np.mean(vel[late] ** 2)) < 3.0 < vel[0]
    assert np.all(sc.truth[:, :2] > 0)  # the first quadrant: the bearing never wraps


# ---------------------------------------------------------------- kfgen ukf --app

def test_cli_sizes_from_the_app(app_file, tmp_path):
    """--app gives n, m, nw, nv and W0; an explicit option still wins."""
    kfgen("ukf", "--app", f"{app_file}:Small", "--measurement-noise", "2", "--name", "ukf_app",
          "-o", tmp_path / "out")
    man = json.loads((tmp_path / "out" / "ukf_app.json").read_text())
    p = UkfParams(**man["parameters"])
    assert (p.n, p.m, p.nw, p.nv, p.w0) == (3, 1, 2, 2, 0.25)
    assert man["sizes"]["M"] == 7


@pytest.mark.parametrize("spec,says", [
    ("Nanosat", "--app: must be module:Class"),
    ("kfgen_no_such_module:App", "--app: cannot import 'kfgen_no_such_module'"),
    ("{file}:WrongShape", "--app: WrongShape.Q must be"),
    ("{file}:Indefinite", "--app: Indefinite.P0 must be positive definite"),
    ("{file}:NanP0", "--app: NanP0.P0 must be finite, not nan at [0, 1]"),
    ("{file}:SemidefiniteR", "--app: SemidefiniteR.R must be positive definite"),
    ("{file}:Huge", "--states: the number of states must be an integer in 1..255, not 300 (from --app "),
])
def test_cli_bad_app_exits_2(app_file, tmp_path, spec, says):
    proc = kfgen_in_process("ukf", "--app", spec.replace("{file}", str(app_file)), "-o", tmp_path / "x")
    assert proc.returncode == 2 and proc.stderr.startswith(f"kfgen: error: {says}"), proc.stderr
    assert proc.stderr.count("\n") == 1 and not (tmp_path / "x").exists()


def test_cli_pendulum_example(tmp_path, monkeypatch):
    """The docs' command for their example, from the checkout's top: a core sized for it."""
    monkeypatch.chdir(ROOT)
    proc = kfgen_in_process("ukf", "--app", "docs/examples/pendulum.py:Pendulum", "-o", tmp_path / "pendulum")
    assert proc.returncode == 0, proc.stderr
    man = json.loads((tmp_path / "pendulum" / "ukf.json").read_text())
    assert man["sizes"]["M"] == 5 and UkfParams(**man["parameters"]).n == 2


@pytest.mark.parametrize("spec", ["nanosat:Nanosat", "tracker:Tracker"])
def test_cli_short_app_names(tmp_path, spec):
    """kfgen ukf --app takes the shipped applications' short names: the sizes come from them
    (an out-of-range --pes is refused after --app loaded, so nothing is generated)."""
    proc = kfgen_in_process("ukf", "--app", spec, "--pes", "999", "-o", tmp_path / "x")
    assert proc.returncode == 2 and proc.stderr.startswith("kfgen: error: --pes: "), proc.stderr
    assert not (tmp_path / "x").exists()


def test_cli_app_only_for_cores_that_take_one(tmp_path):
    proc = kfgen("castella", "--app", NANOSAT, "-o", tmp_path / "x", check=False)
    assert proc.returncode == 2 and proc.stderr.startswith("kfgen: error: --app: unknown option")


# ---------------------------------------------------------------- Figure 12

def test_figure12_with_an_extra_trace(tmp_path, capsys):
    """``make plots``'s entry point on a short run, with one more trace from a file (as an RTL
    co-simulation's would come)."""
    from kfgen.sim.ukf.plots import main
    np.savez(tmp_path / "more.npz", **{"RTL (Verilator)": np.full(20, 0.05)})
    main(["-o", str(tmp_path / "fig"), "--steps", "20", "--traces", str(tmp_path / "more.npz")])
    png = tmp_path / "fig" / "figure12.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    out = capsys.readouterr().out
    assert "float64 reference" in out and "binary32 golden model" in out


def test_figure12_rtl_needs_the_generated_core(tmp_path, capsys):
    """``--rtl DIR`` co-simulates the core generated into DIR: a directory without it, or with
    another core, is refused in one line before any run."""
    from kfgen.sim.ukf.plots import main

    other = tmp_path / "other"
    other.mkdir()
    (other / "ukf.v").write_text("")
    (other / "ukf.json").write_text(json.dumps({"parameters": {"states": 2, "observations": 1, "form": "ldl",
                                                              "on_chip": False}}))
    for rtl, says in ((tmp_path, "holds no generated cores"),
                      (other, "holds ukf, not the core of `kfgen ukf --app nanosat:Nanosat -o DIR`")):
        with pytest.raises(SystemExit) as info:
            main(["-o", str(tmp_path / "fig"), "--steps", "20", "--rtl", str(rtl)])
        err = capsys.readouterr().err
        assert info.value.code == 2 and err.count("\n") == 1 and says in err, err
    assert not (tmp_path / "fig").exists()
