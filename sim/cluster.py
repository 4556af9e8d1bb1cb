"""The benches' independent jobs as tasks on Dask distributed.

Every bench (``python -m kfgen.gen.bench*``) and the Monte Carlo runs of ``make plots`` hand
their independent jobs (a configuration's synthesis, each place-and-route seed, each
Verilator measurement, each Monte Carlo run; the engine cores' generation,
:func:`kfgen.gen.synth.write_cores`) to a :class:`Runner`:

- by default a Dask ``LocalCluster`` sized to the machine (one single-threaded worker process
  per core: the jobs are Yosys, nextpnr and Verilator processes, or numpy);
- ``--scheduler ADDRESS`` (``tcp://host:8786``) uses a cluster the user already runs. Its
  workers must import this kfgen and see the work directory at the same path (a shared
  filesystem, as an EDA farm has): a task reads the Verilog and writes its logs and reports
  there;
- ``--serial`` runs every task in this process, one after another, in submission order (the
  baseline the bench's wall time is compared with, and what a machine without Dask does).

A task's failure does not stop the others: :func:`collect` puts its first line into the
row it belongs to (``<key>_error``), so the table shows it where the figure would be.
``python -m kfgen.gen.bench`` opens one runner for every core's bench (:func:`shared`), so
one core's long last jobs overlap the next core's first.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import time
import uuid

__all__ = ["Runner", "add_arguments", "runner_argv", "open_runner", "shared", "collect", "failed", "timed", "task_seconds"]

#: How long ``--scheduler ADDRESS`` waits for the scheduler to answer.
CONNECT_TIMEOUT = "10s"

_SHARED: list["Runner"] = []


class _Done:
    """A finished task of the serial runner, with the interface of a Dask future we use."""

    def __init__(self, fn, args, kwargs):
        self._exc = None
        try:
            self._value = fn(*_resolve(args), **{k: _resolve(v) for k, v in kwargs.items()})
        except Exception as exc:  # noqa: BLE001 - kept for .result(), as a future keeps it
            self._exc = exc

    def result(self):
        if self._exc is not None:
            raise self._exc
        return self._value

    def exception(self):
        return self._exc

    def done(self):
        return True


def _resolve(value):
    """A serial task's arguments with the results of the tasks among them (as Dask does)."""
    if isinstance(value, _Done):
        return value.result()
    if isinstance(value, (list, tuple)):
        return type(value)(_resolve(v) for v in value)
    if isinstance(value, dict):
        return {k: _resolve(v) for k, v in value.items()}
    return value


class Runner:
    """Where a bench's tasks run: a Dask client, or this process (``serial``)."""

    def __init__(self, scheduler: str | None = None, workers: int | None = None, serial: bool = False):
        self.serial = serial
        self.client = self.cluster = None
        self.where = "serial, in this process"
        if serial:
            return
        try:
            from dask.distributed import Client, LocalCluster  # deferred: Dask (the [dev] extras), not --serial's
        except ImportError as exc:  # the [dev] extras bring it
            _usage(f"Dask distributed is not installed ({exc}); make dev installs it, or run with --serial")
        if scheduler:
            try:
                self.client = Client(scheduler, timeout=CONNECT_TIMEOUT)
            except (OSError, ValueError, TypeError) as exc:
                _usage(f"--scheduler: no Dask scheduler answers at {scheduler!r} ({str(exc).splitlines()[0]})")
            n = len(self.client.scheduler_info().get("workers", {}))
            self.where = f"the Dask scheduler {scheduler} ({n} worker{'s' * (n != 1)})"
        else:
            n = workers or os.cpu_count() or 1
            # Processes, one thread each: Verilator builds and numpy hold the GIL in part, and a
            # worker's memory is what its tools use. No memory limit: the tools' memory is in
            # their own processes, which the nanny does not see anyway.
            self.cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                        memory_limit=0, dashboard_address=":0")
            self.client = Client(self.cluster)
            self.where = f"a Dask LocalCluster of {n} worker process{'es' * (n != 1)}"

    def submit(self, fn, *args, name: str | None = None, priority: int = 0, **kwargs):
        """Run ``fn(*args, **kwargs)`` as a task; futures among the arguments are waited for and
        replaced by their results. ``priority``: higher first among the tasks ready to run."""
        if self.client is None:
            return _Done(fn, args, kwargs)
        key = f"{name or getattr(fn, '__name__', 'task')}-{uuid.uuid4().hex[:8]}"
        return self.client.submit(fn, *args, key=key, pure=False, priority=priority, **kwargs)

    def close(self):
        if self.client is not None:
            self.client.close()
        if self.cluster is not None:
            self.cluster.close()


def _usage(message: str):
    """A one-line error and exit code 2, as every command line of kfgen gives."""
    print(f"error: {message}", file=sys.stderr)
    raise SystemExit(2)


def add_arguments(ap) -> None:
    """``--scheduler``, ``--workers`` and ``--serial`` on a bench's parser."""
    group = ap.add_argument_group("where the jobs run (Dask distributed)")
    group.add_argument("--scheduler", metavar="ADDRESS",
                       help="a running Dask scheduler (tcp://host:8786); default: a LocalCluster on this machine")
    group.add_argument("--workers", "--jobs", type=_positive, metavar="N", dest="workers",
                       help="worker processes of the LocalCluster (default: one per core)")
    group.add_argument("--serial", action="store_true",
                       help="run every job in this process, one after another (no Dask)")


def _positive(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def runner_argv(args) -> list[str]:
    """The options of :func:`add_arguments` that ``args`` set, for a bench that runs another."""
    return ([f"--scheduler={args.scheduler}"] if getattr(args, "scheduler", None) else []) + \
        ([f"--workers={args.workers}"] if getattr(args, "workers", None) else []) + \
        (["--serial"] if getattr(args, "serial", False) else [])


@contextlib.contextmanager
def open_runner(args=None):
    """The runner ``args`` ask for (from :func:`add_arguments`), or the one :func:`shared`
    opened for every bench; closed on exit if opened here."""
    if _SHARED and not (args is not None and (getattr(args, "scheduler", None) or getattr(args, "serial", False))):
        yield _SHARED[-1]
        return
    runner = Runner(getattr(args, "scheduler", None), getattr(args, "workers", None), getattr(args, "serial", False))
    print(f"jobs run on {runner.where}", file=sys.stderr, flush=True)
    try:
        yield runner
    finally:
        runner.close()


@contextlib.contextmanager
def shared(args=None):
    """One runner for every bench run inside (``python -m kfgen.gen.bench``)."""
    with open_runner(args) as runner:
        _SHARED.append(runner)
        try:
            yield runner
        finally:
            _SHARED.pop()


def timed(fn, *args, **kwargs) -> dict:
    """``fn``'s result (a dict) with ``seconds``, the task's own time: run as the task itself."""
    t0 = time.monotonic()
    out = dict(fn(*args, **kwargs))
    out["seconds"] = time.monotonic() - t0
    return out


def failed(rows) -> bool:
    """Whether any row holds a task's failure (a ``<key>_error`` that :func:`collect` put there)."""
    return any(v for r in rows for k, v in r.items() if k.endswith("_error"))


def collect(jobs, label=lambda row: "", tool: str = "bench", each=None) -> None:
    """Wait for ``jobs``, ``(row, key, future)`` whose future gives a dict, in the order they
    finish, and put each into its row: the dict (less ``seconds``, kept as
    ``<key>_seconds``), or ``<key>_error`` with the first line of what failed. ``each(row)``
    is called after each."""
    pending = list(jobs)
    futures = [f for _, _, f in pending]
    order = _as_completed(futures)
    index = {_ident(f): i for i, f in enumerate(futures)}
    for f in order:
        row, key, _ = pending[index[_ident(f)]]
        try:
            result = dict(f.result())
        except Exception as exc:  # noqa: BLE001 - one task's failure goes into its row
            text = str(exc).strip().splitlines()
            row[f"{key}_error"] = f"{type(exc).__name__}: {text[0] if text else ''}".rstrip(": ")
            print(f"{tool}: {label(row)} {key} failed: {row[f'{key}_error']}", file=sys.stderr, flush=True)
        else:
            seconds = result.pop("seconds", None)
            row.update(result)
            if seconds is not None:
                row[f"{key}_seconds"] = seconds
            print(f"{tool}: {label(row)} {key} done" + (f" in {seconds:.0f} s" if seconds is not None else ""),
                  file=sys.stderr, flush=True)
        if each is not None:
            each(row)


def task_seconds(rows, kinds) -> dict:
    """``{"<what> (task time)": seconds}``: the jobs' own time summed over ``rows`` for each
    ``(key, what)`` of ``kinds`` that has any (the ``<key>_seconds`` :func:`collect` wrote)."""
    totals = {f"{what} (task time)": sum(r.get(f"{key}_seconds", 0) for r in rows) for key, what in kinds}
    return {k: v for k, v in totals.items() if v}


def _ident(future):
    return getattr(future, "key", None) or id(future)


def _as_completed(futures):
    if futures and not isinstance(futures[0], _Done):
        from dask.distributed import as_completed  # deferred: Dask (the [dev] extras), not --serial's
        return as_completed(futures)
    return iter(futures)
