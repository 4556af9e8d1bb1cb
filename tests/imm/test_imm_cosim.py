"""A user's own IMM model set on the RTL (docs/imm.md, "Your own model set on the RTL"): the
application's checks (one line, exit 2, nothing generated or built), the generated C driver
(compiles under -std=c99 -Wall -Wextra -Werror; its ID check is the map's), and the documented
``python -m kfgen.gen.cosim imm`` commands on Verilator, the Python and the C processor on one
build."""

import contextlib
import io
import os
import re
import shlex
import subprocess
import sys

import numpy as np
import pytest

import kfgen.gen.cosim as cosim
from kfgen.gen.cdriver import UKF_ID, id_fields, imm_driver
from kfgen.hdl.imm.params import ImmParams
from kfgen.hdl.imm.regmap import imm_map
from kfgen.hdl.ukf.params import UkfParams
from kfgen.hdl.ukf.regmap import ukf_map
from kfgen.sim.imm.app import checked_scenario, load_imm_app
from kfgen.sim.imm.reference import run_reference

from helpers import ROOT, kfgen_in_process

EXAMPLE = "docs/examples/imm_cv.py:ConstantVelocity"

#: Applications that must be refused: a subclass of the example with one thing wrong.
BAD = '''
import numpy as np
from kfgen.sim.imm.app import ImmModel
from imm_cv import ConstantVelocity as Good, F, G, H


class PiRows(Good):
    pi = np.array([[0.9, 0.2], [0.1, 0.9]])


class Mu0(Good):
    mu0 = np.array([0.5, 0.6])


class P0Indefinite(Good):
    P0 = np.diag([1.0, -4.0])


class P0Shape(Good):
    P0 = np.eye(3)


class RIndefinite(Good):
    models = [Good.models[0], ImmModel("bad", F, G, H, np.array([[-1.0]]))]


class QIndefinite(Good):
    models = [Good.models[0], ImmModel("bad", F, -G, H, np.array([[1.0]]))]


class OneModel(Good):
    models = [Good.models[0]]


class Sizes(Good):
    models = [Good.models[0], ImmModel("wide", np.eye(3), np.eye(3), np.ones((1, 3)), np.eye(1))]


class Raises(Good):
    def scenario(self, steps, seed):
        raise RuntimeError("no data\\ntoday")


class ShortZ(Good):
    def scenario(self, steps, seed):
        sc = super().scenario(steps, seed)
        return sc.z[:-1]
'''


def run_command(*args, cwd):
    """``python -m kfgen.gen.cosim imm ARGS`` as a user runs it: not under pytest (whose
    variable makes cocotb's runner log a failed test itself)."""
    env = {k: v for k, v in os.environ.items() if k != "PYTEST_CURRENT_TEST"}
    return subprocess.run([sys.executable, "-m", "kfgen.gen.cosim", "imm", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, env=env)


def cosim_main(*args):
    """``python -m kfgen.gen.cosim imm ARGS`` in this process: (exit status, stdout, stderr)."""
    with contextlib.redirect_stdout(io.StringIO()) as out, contextlib.redirect_stderr(io.StringIO()) as err:
        try:
            code = cosim.main(["imm", *(str(a) for a in args)])
        except SystemExit as exc:  # argparse's refusals
            code = exc.code
    return code, out.getvalue(), err.getvalue()


@pytest.mark.parametrize("args,says", [
    (["--app", "{tmp}/bad.py:PiRows"], "PiRows: every row of pi must sum to 1"),
    (["--app", "{tmp}/bad.py:Mu0"], "Mu0.mu0 must be non-negative and sum to 1"),
    (["--app", "{tmp}/bad.py:P0Indefinite"], "P0Indefinite.P0 must be positive definite"),
    (["--app", "{tmp}/bad.py:P0Shape"], "P0Shape.P0 must be a finite array of shape (2, 2), not shape (3, 3)"),
    (["--app", "{tmp}/bad.py:RIndefinite"], "RIndefinite: model 'bad': R must be positive definite"),
    (["--app", "{tmp}/bad.py:QIndefinite"], "QIndefinite: model 'bad': Q must be positive semi-definite"),
    (["--app", "{tmp}/bad.py:OneModel"], "OneModel.models must be a list of at least two ImmModel"),
    (["--app", "{tmp}/bad.py:Sizes"], "Sizes: model 'wide' has n = 3, d = 1; model 'steady' has n = 2, d = 1"),
    (["--app", "{tmp}/bad.py:Raises"], "Raises.scenario(20, 1) raised RuntimeError: no data today"),
    (["--app", "{tmp}/bad.py:ShortZ", "--steps", "7"],
     "ShortZ.scenario(7, 1).z must be a finite array of shape (7, 1), not shape (6, 1)"),
    (["--app", "{tmp}/bad.py:Nope"], "module '{tmp}/bad.py' has no 'Nope'"),
    (["--app", "docs/examples/pendulum.py:Pendulum"], "docs/examples/pendulum.py:Pendulum() is a Pendulum, "
                                                      "not a ImmApplication (kfgen.sim.imm.app)"),
    (["--app", EXAMPLE, "--steps", "0"], "--steps must be a positive integer, not 0"),
    (["--app", EXAMPLE, "--format", "binary16", "--processor", "c"],
     "--processor c: the C driver converts binary32 and binary64 elements only, not binary16"),
    (["--app", EXAMPLE, "--pes", "0"], "pes: must be an integer in 1..64, not 0"),
    (["--app", EXAMPLE, "--processor", "arm"], "argument --processor: invalid choice: 'arm'"),
])
def test_rejects_before_building(tmp_path, monkeypatch, args, says):
    """What cannot run is refused in one line, exit 2, before anything is generated or built."""
    def never(*_a, **_k):
        raise AssertionError("generated or built")
    monkeypatch.setattr(cosim, "write_core", never)
    monkeypatch.setattr(cosim, "build_core", never)
    monkeypatch.chdir(ROOT)
    monkeypatch.syspath_prepend(str(ROOT / "docs" / "examples"))  # bad.py imports the example
    (tmp_path / "bad.py").write_text(BAD)
    code, out, err = cosim_main(*(a.replace("{tmp}", str(tmp_path)) for a in args), "-o", tmp_path / "work")
    says = says.replace("{tmp}", str(tmp_path))
    assert code == 2 and err.startswith(f"cosim: error: {says}") and err.count("\n") == 1, err
    assert not out and not (tmp_path / "work").exists()


def test_example_application(monkeypatch):
    """The example sizes the smallest core (R = 2, n = 2, d = 1); its scenario has the truth,
    and the float64 IMM follows it, the manoeuvre model's probability rising as it brakes."""
    monkeypatch.chdir(ROOT)
    app = load_imm_app(EXAMPLE)
    assert app.core_parameters() == {"models": 2, "states": 2, "measurements": 1}
    sc = checked_scenario(app, 60, 1)
    ref = run_reference(app.system(), *app.initial(), sc.z)
    assert np.max(np.abs(ref.x[:, 0] - sc.truth[:, 0])) < 1.5
    assert ref.mu[30:40, 1].max() > 2 * ref.mu[:30, 1].mean()


# ---------------------------------------------------------------- the C driver

def test_driver_id_check_is_the_maps():
    """The drivers check every ID field but pes: the UKF's in its own order, the IMM's in the map's."""
    assert sorted(UKF_ID) == sorted(id_fields(ukf_map(UkfParams())))
    assert id_fields(imm_map(ImmParams())) == ("core", "version", "exp_bits", "frac_bits", "models", "n", "d")
    text = imm_driver("imm", "binary32", id_fields(imm_map(ImmParams())))["imm_driver.c"]
    assert all(f"FIELD(ID, {f.upper()}, id) != IMM__ID__{f.upper()}_reset" in text
               for f in ("core", "version", "exp_bits", "frac_bits", "models", "n", "d"))
    assert "PES" not in text


@pytest.mark.parametrize("fmt", ["binary32", pytest.param("binary64", marks=pytest.mark.full)])
def test_driver_compiles(tmp_path, fmt):
    """``kfgen imm`` writes the driver beside a binary32 or binary64 core; it compiles bare
    metal and with the MMIO hooks under -std=c99 -Wall -Wextra -Werror (and none for binary16)."""
    out = tmp_path / "core"
    assert kfgen_in_process("imm", "--models", "2", "--states", "2", "--measurements", "1", "--format", fmt,
                            "--name", "imm_c", "-o", out).returncode == 0
    for hooks in ([], ["-DKFGEN_MMIO_HOOKS"]):
        proc = subprocess.run(["gcc", "-std=c99", "-Wall", "-Wextra", "-Werror", *hooks, "-I", str(out), "-c",
                               str(out / "imm_c_driver.c"), "-o", str(tmp_path / "d.o")], capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr
    if fmt != "binary64":
        return  # the binary16 core without a driver: in make test-full, beside binary64's
    half = tmp_path / "half"
    assert kfgen_in_process("imm", "--models", "2", "--states", "2", "--measurements", "1", "--format", "binary16",
                            "--name", "imm_h", "-o", half).returncode == 0
    assert not list(half.glob("*_driver.*"))


# ---------------------------------------------------------------- on Verilator

def documented():
    """The page's ``cosim imm`` commands and the output it prints for the first."""
    page = (ROOT / "docs" / "imm.md").read_text()
    commands = re.findall(r"^python -m kfgen\.gen\.cosim imm --app docs/examples/.*$", page, re.M)
    output = re.search(r"^```text\n(\d+ iterations of .*?)^```", page, re.M | re.S).group(1)
    return commands, output


@pytest.mark.verilator
@pytest.mark.xdist_group("imm_cosim")
# make test-full (a Verilator build of the example's core, 65 s of the regression): make test
# runs the IMM core's cocotb cases, its Python driver and its C driver's compile.
@pytest.mark.full
@pytest.mark.parametrize("processors", [1, 2], ids=["python", "python+c"])
def test_documented_commands(build_root, processors):
    """docs/imm.md's two commands as written (the work directory moved under the build root):
    the Python processor, then (make test-full; the UKF's co-simulation runs its C driver in
    make test) the C driver on the same build; each ends with every word equal to the golden
    model's, and prints what the page shows."""
    commands, shown = documented()
    assert len(commands) == 2 and "--processor c" in commands[1]
    work = build_root / "imm_cosim"
    printed = []
    for command in commands[:processors]:
        args = shlex.split(command)
        assert args[:4] == ["python", "-m", "kfgen.gen.cosim", "imm"]
        args[args.index("-o") + 1] = str(work)
        proc = run_command(*args[4:], cwd=ROOT)
        assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
        assert "every word equal to the golden model's" in proc.stdout
        printed.append(proc.stdout)
    first = shown.splitlines()
    got = printed[0].splitlines()
    assert got[0] == first[0]
    assert re.match(r"cycles per iteration: the iteration (\d+),", got[1]).group(1) == \
        re.match(r"cycles per iteration: the iteration (\d+),", first[1]).group(1)
    for text in printed:  # binary32 against float64
        x_err, mu_err = (float(v) for v in re.search(r"reference\| over the run: (\S+); largest \|mu - reference\|: "
                                                     r"(\S+)", text).groups())
        assert x_err < 1e-5 and mu_err < 1e-5, text
    if processors == 2:
        assert printed[1].splitlines()[3] == printed[0].splitlines()[3]  # the C driver's words are the same


#: The example with a measurement beyond binary32's range at iteration 2 (the golden model
#: raises err_pivot and err_nan there).
GLITCH = f'''
import importlib.util

spec = importlib.util.spec_from_file_location("imm_cv_example", {str(ROOT / "docs" / "examples" / "imm_cv.py")!r})
example = importlib.util.module_from_spec(spec)
spec.loader.exec_module(example)


class Glitch(example.ConstantVelocity):
    def scenario(self, steps, seed):
        sc = super().scenario(steps, seed)
        sc.z[2] = 3e38
        return sc
'''


@pytest.mark.verilator
@pytest.mark.xdist_group("imm_cosim")
@pytest.mark.full  # on test_documented_commands' build
@pytest.mark.parametrize("processor", ["python", "c"])
def test_fault_is_one_line_exit_3(build_root, tmp_path, processor):
    """A numerical fault in the core: one line naming the iteration and the bit, exit 3, from
    either processor, and no cosim.npz (the example's core: test_documented_commands' build)."""
    (tmp_path / "glitch.py").write_text(GLITCH)
    work = build_root / "imm_cosim"
    proc = run_command("--app", "glitch.py:Glitch", "--steps", 4, "--processor", processor, "-o", work, cwd=tmp_path)
    assert proc.returncode == 3 and not proc.stdout and proc.stderr.count("\n") == 1, proc.stdout + proc.stderr
    assert proc.stderr.startswith("cosim: error: the core raised a numerical fault at iteration 2: iterate raised "
                                  "err_pivot (a pivot not positive"), proc.stderr
    assert not (work / "imm_app" / "cosim.npz").exists()
