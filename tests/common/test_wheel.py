"""The wheel a user installs: every package is in it, and its ``kfgen`` works on its own.

The editable install every other test uses maps whole directories, so it cannot notice a
package the wheel leaves out. Here the wheel is built from the files a clone would have (plus
new files not yet added to git), installed into a clean venv, and run from outside the
repository.
"""

import os
import re
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import pytest

from helpers import ROOT, kfgen, kfgen_in_process

# One worker builds the wheel and its venv for every test here.
pytestmark = pytest.mark.xdist_group("wheel")

TOP = ("hdl", "gen", "sim")  # installed as kfgen.hdl, kfgen.gen, kfgen.sim


def _run(*args, **kw):
    proc = subprocess.run([str(a) for a in args], capture_output=True, text=True, **kw)
    assert proc.returncode == 0, f"{' '.join(map(str, args))} failed ({proc.returncode}):\n{proc.stderr}"
    return proc


def _source_files() -> list[str]:
    """Tracked files and new ones not ignored: what the wheel would be built from after a commit."""
    out = _run("git", "ls-files", "--cached", "--others", "--exclude-standard", "-z", cwd=ROOT).stdout
    return [f for f in out.split("\0") if f and (ROOT / f).is_file()]


def _package_dirs() -> dict[str, Path]:
    """Import name -> directory, for every directory with __init__.py under the top level."""
    return {".".join(["kfgen", *d.relative_to(ROOT).parts]): d
            for top in TOP for d in sorted(init.parent for init in (ROOT / top).rglob("__init__.py"))}


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    src = tmp_path_factory.mktemp("src")  # a copy: no stale build/lib from an earlier build
    for name in _source_files():
        (src / name).parent.mkdir(parents=True, exist_ok=True)
        (src / name).write_bytes((ROOT / name).read_bytes())
    dist = tmp_path_factory.mktemp("dist")
    _run(sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "--disable-pip-version-check", "-w", dist, src)
    (whl,) = dist.glob("kfgen-*.whl")
    return whl


@pytest.fixture(scope="module")
def venv(wheel, tmp_path_factory) -> Path:
    """A venv with only the wheel installed; its dependencies are the project venv's, seen
    through a .pth (a path in a .pth goes on sys.path without that directory's own .pth files
    running, so the project's editable kfgen stays invisible)."""
    venv = tmp_path_factory.mktemp("venv")
    _run(sys.executable, "-m", "venv", "--without-pip", venv)
    python = venv / "bin" / "python"
    # Before the .pth: pip must not see (and replace) the project's kfgen.
    _run(sys.executable, "-m", "pip", "--python", python, "install", "-q", "--no-deps", "--no-index",
         "--disable-pip-version-check", wheel)
    site = Path(_run(python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])").stdout.strip())
    (site / "kfgen-test-deps.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    return venv


def test_every_package_is_in_the_wheel(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    missing = [f"{pkg}: {d.relative_to(ROOT)}/{f.name}" for pkg, d in _package_dirs().items() for f in d.glob("*.py")
               if "/".join([*pkg.split("."), f.name]) not in names]
    assert not missing, "not in the wheel:\n" + "\n".join(missing)
    stray = sorted({n.split("/")[0] for n in names} - {"kfgen", wheel.name.split("-py")[0] + ".dist-info"})
    assert not stray, f"the wheel installs more than kfgen: {stray}"


def _outside(venv, tmp_path, *args):
    """Run a command of the venv from a directory outside the repository, nothing pointing back."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV")}
    env["PATH"] = os.pathsep.join([str(venv / "bin"), env.get("PATH", "")])
    return _run(venv / "bin" / args[0], *args[1:], cwd=tmp_path, env=env)


def test_wheel_imports_from_itself(venv, tmp_path):
    where = _outside(venv, tmp_path, "python", "-c",
                     "import kfgen.hdl, kfgen.gen, kfgen.sim; print(kfgen.gen.__file__); print(kfgen.gen.__version__)")
    file, version = where.stdout.split()
    assert Path(file).is_relative_to(venv), f"kfgen imported from {file}, not from the wheel"
    assert version != "0.0.0", "the wheel's metadata was not found"


#: The engine cores at a small size (their defaults take seconds each to schedule and emit,
#: twice here; make verilog and test_cores build the defaults).
SMALL = {"ukf": ["--states", "2", "--observations", "1", "--process-noise", "1", "--measurement-noise", "1"],
         "imm": ["--models", "2", "--states", "2", "--measurements", "1"], "ekf": ["--app", "tracker:Tracker"]}


@pytest.mark.full
def test_wheel_generates_every_core(venv, tmp_path):
    from kfgen.gen.cores import discover

    usage = _outside(venv, tmp_path, "kfgen", "--help").stdout
    listed = re.findall(r"^    (\w+)(?:\s|$)", usage, re.M)  # the CORE list, one per line
    cores = [c for c in listed if c not in ("lint", "fusesoc")]
    assert cores == list(discover()) and {"lint", "fusesoc"} <= set(listed), usage
    for core in cores:
        out = tmp_path / core
        args = SMALL.get(core, [])
        written = _outside(venv, tmp_path, "kfgen", core, *args, "-o", out).stdout.split()
        assert {".json", ".v", ".vlt"} <= {Path(w).suffix for w in written}, written
        # Byte-identical to the editable install's output for the same parameters, file for file
        # (a core with a register map adds TOP.rdl, TOP.h and TOP.md).
        ref = tmp_path / f"{core}-editable"
        assert kfgen_in_process(core, *args, "-o", ref).returncode == 0
        assert sorted(Path(w).name for w in written) == sorted(p.name for p in ref.iterdir()), written
        for w in written:
            path = tmp_path / w
            assert path.parent == out and path.stat().st_size > 0, w
            assert path.read_bytes() == (ref / path.name).read_bytes(), f"{core}: {path.name} differs"
