"""The regression's scheduling holds: under ``pytest -n 2 --dist loadgroup`` (what ``make test``
runs) the tests of one ``xdist_group`` run on one worker, so a core built by a module-scoped
fixture or a shared Verilator build is made once. With pytest 9.2 and pytest-xdist 3.8 the
groups were silently dropped (pytest-xdist issue 1386): nothing failed, every worker just
rebuilt what the group shares."""

import subprocess
import sys


def test_a_group_runs_on_one_worker(tmp_path):
    (tmp_path / "test_grouped.py").write_text(
        "import os, pytest\n"
        + "".join(f"@pytest.mark.xdist_group('shared')\n"
                  f"def test_{k}():\n"
                  f"    open('worker_{k}', 'w').write(os.environ['PYTEST_XDIST_WORKER'])\n" for k in range(6)))
    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-n", "2",
                           "--dist", "loadgroup", "test_grouped.py"], cwd=tmp_path, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    workers = {(tmp_path / f"worker_{k}").read_text() for k in range(6)}
    assert len(workers) == 1, f"one group ran on workers {sorted(workers)}"
