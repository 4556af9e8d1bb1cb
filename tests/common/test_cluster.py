"""The benches' runner (kfgen.sim.cluster): the same results in this process, on a LocalCluster
and on a scheduler started apart, with dependencies followed and a task's failure kept in its
row; a bad scheduler address is a one-line error."""

import argparse
import os
import sys
from pathlib import Path

import pytest

from kfgen.gen.synth import write_cores
from kfgen.sim.cluster import Runner, add_arguments, collect, failed, open_runner, runner_argv, timed


def square(x):
    return {"value": x * x, "pid": os.getpid()}


def plus(a, b):
    return {"value": a["value"] + b, "pid": os.getpid()}


def broken(x):
    raise RuntimeError(f"nextpnr failed on {x}\nsecond line")


def _run(runner):
    rows = [{"name": "a"}, {"name": "b"}, {"name": "c"}]
    first = runner.submit(square, 3, name="square")
    seen = []
    collect([(rows[0], "sum", runner.submit(plus, first, 4)),  # after its dependency
             (rows[1], "sq", runner.submit(timed, square, 5)),
             (rows[2], "pnr", runner.submit(broken, "x", name="broken"))],
            label=lambda r: r["name"], each=lambda r: seen.append(r["name"]))
    return rows, seen


def _check(rows, seen, here: bool):
    assert rows[0]["value"] == 13 and rows[1]["value"] == 25
    assert rows[1]["sq_seconds"] >= 0 and "seconds" not in rows[1]
    assert rows[2]["pnr_error"] == "RuntimeError: nextpnr failed on x", "the failure's first line, in its row"
    assert sorted(seen) == ["a", "b", "c"]
    assert failed(rows) and not failed(rows[:2]), "the bench's exit status sees the failed row"
    assert (rows[0]["pid"] == os.getpid()) == here, "in this process only when serial"


def test_serial_runs_here():
    runner = Runner(serial=True)
    _check(*_run(runner), here=True)


def _generate(runner, out: Path):
    """Two small cores, as a bench generates them (:func:`kfgen.gen.synth.write_cores`): the
    results, every file's bytes, and the tasks handed to ``runner``."""
    from kfgen.hdl.arith.float.descriptor import CORE
    from kfgen.hdl.arith.float.params import FpuParams

    names = []
    submit = runner.submit
    runner.submit = lambda fn, *a, name=None, **k: names.append(name) or submit(fn, *a, name=name, **k)
    configs = [FpuParams(op=op, format="binary16", name=f"gen_{op}") for op in ("add", "mul")]
    made = write_cores(CORE, configs, out, runner)
    runner.submit = submit
    files = {p.relative_to(out).as_posix(): p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()}
    return [(w.relative_to(out), m) for w, m in made], files, names


def test_local_cluster(tmp_path):
    """A LocalCluster the runner starts: the same rows, computed in its worker process; the
    cores a bench generates there are the ones generated here, byte for byte."""
    here = _generate(Runner(serial=True), tmp_path / "here")
    assert [w for w, _ in here[0]] == [Path("gen_add"), Path("gen_mul")] and here[2] == [], \
        "serial: in order, in this process"
    with open_runner(argparse.Namespace(workers=1)) as runner:
        assert "LocalCluster of 1 worker process" in runner.where
        _check(*_run(runner), here=False)
        there = _generate(runner, tmp_path / "there")
        # a core of an application (--app): the worker loads it as the command line does
        from kfgen.hdl.ukf.descriptor import CORE
        from kfgen.hdl.ukf.params import UkfParams
        from kfgen.sim.ukf.app import load_app
        app = "tracker:Tracker"  # (the smallest shipped application: a few seconds to generate)
        params = UkfParams(**load_app(app).core_parameters(), app=app, on_chip=True, name="gen_oc")
        [(work, manifest)] = write_cores(CORE, [params], tmp_path / "app", runner)
    assert there[2] == ["generate-gen_add", "generate-gen_mul"], "one task a core"
    assert there[:2] == here[:2] and len(here[1]) > 4
    assert manifest["cycles"]["iteration"] > 0 and (work / "gen_oc.v").is_file()


#: docs/benchmarks.md's commands for a cluster started apart (its own scheduler and worker).
SCHEDULER_DOCS = (".venv/bin/dask scheduler --port 8786 &",
                  ".venv/bin/dask worker tcp://127.0.0.1:8786 --nworkers 1 --nthreads 1 &",
                  ".venv/bin/python -m kfgen.gen.bench_fpu --ops f2i --formats binary16 --no-pnr "
                  "--scheduler tcp://127.0.0.1:8786 -o build/bench_dask")


@pytest.mark.full  # 18 s: a scheduler, a worker and a bench apart; make test's Dask is test_local_cluster
def test_scheduler_commands_in_the_docs(tmp_path):
    """The commands as docs/benchmarks.md gives them (the work directory moved): a scheduler and
    a worker started apart, and a bench whose synthesis runs on that worker."""
    import shlex
    import subprocess

    from helpers import ROOT

    text = (ROOT / "docs" / "benchmarks.md").read_text()
    assert all(c in text for c in SCHEDULER_DOCS)
    venv = Path(sys.executable).parent
    daemons = []
    try:
        for command in SCHEDULER_DOCS[:2]:
            argv = shlex.split(command.rstrip(" &"))
            daemons.append(subprocess.Popen([str(venv / Path(argv[0]).name), *argv[1:]], cwd=tmp_path,
                                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        argv = shlex.split(SCHEDULER_DOCS[2])
        argv[-1] = str(tmp_path / "bench_dask")
        # (the tasks wait at the scheduler until the worker has joined)
        proc = subprocess.run([sys.executable, *argv[1:]], capture_output=True, text=True, timeout=300)
    finally:
        for d in daemons:
            d.terminate()
            d.wait(timeout=30)
    assert proc.returncode == 0, proc.stderr
    assert "jobs run on the Dask scheduler tcp://127.0.0.1:8786" in proc.stderr
    assert "| f2i | binary16 |" in proc.stdout and (tmp_path / "bench_dask" / "bench_fpu.json").exists()


@pytest.mark.parametrize("argv, says", [
    (["--scheduler", "tcp://127.0.0.1:9"], "--scheduler: no Dask scheduler answers at 'tcp://127.0.0.1:9'"),
    (["--workers", "0"], "must be at least 1"),
    (["--jobs", "x"], "expected a whole number"),
])
def test_bad_runner_options(capsys, monkeypatch, argv, says):
    from kfgen.gen import bench_fpu
    from kfgen.sim import cluster

    monkeypatch.setattr(cluster, "CONNECT_TIMEOUT", "1s")  # nothing listens on port 9: the wait is all the time

    with pytest.raises(SystemExit) as exc:
        bench_fpu.main(["--ops", "f2i", "--formats", "binary16", "--no-pnr", *argv])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and says in err.strip().splitlines()[-1], err


@pytest.mark.parametrize("module", ["bench", "bench_castella", "bench_fpu", "bench_imm", "bench_schur", "bench_sqrt",
                                    "bench_ukf", "bench_timing"])
def test_options_on_every_bench(capsys, module):
    import importlib

    with pytest.raises(SystemExit) as exc:
        importlib.import_module(f"kfgen.gen.{module}").main(["--help"])
    out = capsys.readouterr().out
    assert exc.value.code == 0 and "--scheduler ADDRESS" in out and "--serial" in out, module


def test_jobs_is_workers():
    ap = argparse.ArgumentParser()
    add_arguments(ap)
    assert ap.parse_args(["--jobs", "3"]).workers == 3, "--jobs stays, as --workers"
    args = ap.parse_args(["--scheduler", "tcp://h:8786", "--workers", "2", "--serial"])
    assert runner_argv(args) == ["--scheduler=tcp://h:8786", "--workers=2", "--serial"], "what a bench passes on"
