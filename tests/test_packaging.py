"""The Makefile's bootstrap: the Python it accepts."""

import re
import subprocess
import sys
import tomllib

import pytest

from conftest import ROOT

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

