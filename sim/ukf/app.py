"""A UKF application: the user's half of the chapter's HW/SW codesign.

The core computes everything that does not depend on the system (sigma points, means,
covariances, gain); the application supplies what does: the sizes, the process model f and
the observation model h (run in software on the processor, eqs. 1-2, 9, 12), the filter's
parameters (W0, x0, P0, Q, R) and, for simulation, a seeded scenario. One class describes
it; ``kfgen ukf --app module:Class`` sizes a core for it, and the float64 reference, the
bit-exact golden model and a co-simulation run it unchanged.

Write one subclass of :class:`UkfApplication`::

    class Pendulum(UkfApplication):
        n, nw, nv, m = 2, 2, 1, 1
        dt = 0.01
        x0 = [0.1, 0.0]
        P0 = np.eye(2)
        Q = np.eye(2) * 1e-4
        R = [[1e-2]]

        def f(self, x, w, u, dt):
            return x + dt * np.array([x[1], -9.81 * np.sin(x[0])]) + w

        def h(self, x, v):
            return np.array([np.sin(x[0])]) + v

        def scenario(self, steps, seed):
            ...

(``docs/examples/pendulum.py`` is this example complete, with its scenario) and load it
with :func:`load_app` (``"my_module:Pendulum"``, ``"path/to/file.py:Pendulum"``, or for the
applications shipped in :mod:`kfgen.sim.ukf.apps` the short ``"nanosat:Nanosat"``).
"""

from __future__ import annotations

import importlib
import importlib.util
import math
import sys
from pathlib import Path
from typing import NamedTuple

import numpy as np

__all__ = ["AppError", "Scenario", "UkfApplication", "load_app", "portable_spec", "checked_scenario", "check_models"]


class AppError(ValueError):
    """A bad application or application spec; the message is one line."""


class Scenario(NamedTuple):
    """A seeded run of ``K`` filter iterations.

    Iteration k (from 0) predicts with the control input ``u[k]`` over ``dt``, then updates
    with the measurement ``z[k]`` taken at time ``t[k]`` of the true state ``truth[k]``: the
    filter's estimate after iteration k is to be compared with ``truth[k]``.

    Without a control input ``u`` is ``None`` (or an array of shape (K, 0)): f then gets an
    empty array, shape (0,), as its ``u`` (:meth:`inputs`).
    """

    t: np.ndarray  #: (K,) time of each measurement, s (the first at dt)
    truth: np.ndarray  #: (K, n) the true states
    u: np.ndarray | None  #: (K, p) control inputs passed to f (None or p = 0: none)
    z: np.ndarray  #: (K, m) measurements

    def inputs(self):
        """``(u[k], z[k])`` for each iteration k, ``u[k]`` an empty array when ``u`` is None."""
        z = np.asarray(self.z, dtype=np.float64)
        u = np.zeros((len(z), 0)) if self.u is None else np.asarray(self.u, dtype=np.float64)
        return zip(u, z)


class UkfApplication:
    """Base class of a UKF application.

    Attributes
    ----------
    n, nw, nv, m : int
        Lengths of the state x, the process noise w, the measurement noise v and the
        observation z (M = n + nw + nv is the augmented state's length, eq. 3).
    nu : int
        Length of the control input u that f takes (0, the default: none). A core with f
        and h on chip (``kfgen ukf --app ... --on-chip``) has a buffer region ``u`` of nu words.
    W0 : float
        Weight of the centre sigma point, 0 <= W0 < 1 (eq. 5); 0 by default.
    dt : float
        Time between iterations, s, passed to :meth:`f`.
    x0, P0 : array_like
        Initial estimate (n,) and its covariance (n, n).
    Q, R : array_like
        Covariances of w (nw, nw) and of v (nv, nv) (eq. 4).

    Subclasses set these (as class attributes or in ``__init__``, which takes no
    arguments when the class is loaded by :func:`load_app`) and define :meth:`f`,
    :meth:`h` and :meth:`scenario`.
    """

    n: int
    nw: int
    nv: int
    m: int
    nu: int = 0
    W0: float = 0.0
    dt: float
    x0 = P0 = Q = R = None

    def f(self, x: np.ndarray, w: np.ndarray, u: np.ndarray, dt: float) -> np.ndarray:
        """Process model: the state (n,) one step of ``dt`` after ``x`` (n,), with the
        process noise ``w`` (nw,) and the control input ``u`` (eq. 1)."""
        raise NotImplementedError

    def h(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Observation model: the observation (m,) of the state ``x`` (n,) with the
        measurement noise ``v`` (nv,) (eq. 2)."""
        raise NotImplementedError

    def scenario(self, steps: int, seed: int) -> Scenario:
        """A simulated run of ``steps`` iterations, reproducible from ``seed``."""
        raise NotImplementedError

    def core_parameters(self) -> dict:
        """The UKF core's parameters this application fixes: its sizes and W0.

        ``kfgen ukf --app`` starts from these (then ``--config`` and the command line
        override them), and the co-simulation sizes its core with them.

        Returns
        -------
        dict
            Keyword arguments of :class:`kfgen.hdl.ukf.params.UkfParams`: ``states`` (n),
            ``observations`` (m), ``process_noise`` (nw), ``measurement_noise`` (nv) and
            ``w0`` (W0). The format, the processing elements and the name are not the
            application's: pass them beside these,
            ``UkfParams(**app.core_parameters(), format="binary64", pes=2)``.
        """
        return {"states": int(self.n), "observations": int(self.m), "process_noise": int(self.nw),
                "measurement_noise": int(self.nv), "w0": float(self.W0)}

    def check(self) -> None:
        """Validate the sizes, W0, dt, x0 (finite, shape (n,)) and P0, Q, R: finite, of
        their shapes, symmetric and positive definite (the core's ``sig_gen`` factorises
        diag(P, Q, R) and raises ``err_pivot`` on a pivot that is not positive, so a
        semi-definite Q or R would fail on the first iteration).

        Raises
        ------
        AppError
            Naming the first attribute that is wrong and what it should be.
        """
        name = type(self).__name__
        for key in ("n", "nw", "nv", "m"):
            v = getattr(self, key, None)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
                raise AppError(f"{name}.{key} must be a positive integer, not {v!r}")
        nu = self.nu
        if isinstance(nu, bool) or not isinstance(nu, (int, np.integer)) or nu < 0:
            raise AppError(f"{name}.nu must be an integer >= 0 (the control input's length), not {nu!r}")
        w0 = self.W0
        if isinstance(w0, bool) or not isinstance(w0, (int, float)) or not 0 <= w0 < 1:
            raise AppError(f"{name}.W0 must be a number with 0 <= W0 < 1, not {w0!r}")
        dt = getattr(self, "dt", None)
        if isinstance(dt, bool) or not isinstance(dt, (int, float)) or not (math.isfinite(dt) and dt > 0):
            raise AppError(f"{name}.dt must be a positive number of seconds, not {dt!r}")
        for key, shape in (("x0", (self.n,)), ("P0", (self.n, self.n)), ("Q", (self.nw, self.nw)),
                           ("R", (self.nv, self.nv))):
            a = _array(f"{name}.{key}", getattr(self, key), shape)
            if key != "x0":
                _positive_definite(f"{name}.{key}", a)


def _array(what: str, value, shape: tuple) -> np.ndarray:
    """``value`` as a float64 array of ``shape`` with finite entries, or an AppError."""
    try:
        a = None if value is None else np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        a = None
    if a is None or a.shape != shape:
        got = "None" if value is None else "not numbers" if a is None else f"shape {a.shape}"
        raise AppError(f"{what} must be a finite array of shape {shape}, not {got}")
    bad = np.argwhere(~np.isfinite(a))
    if len(bad):
        at = tuple(int(i) for i in bad[0])
        raise AppError(f"{what} must be finite, not {float(a[at])} at {list(at)}")
    return a


def _positive_definite(what: str, a: np.ndarray) -> None:
    """An AppError unless ``a`` is symmetric (to 1e-9 of its largest entry) and positive
    definite (numpy's Cholesky factorisation succeeds)."""
    if np.max(np.abs(a - a.T)) > 1e-9 * np.max(np.abs(a)):
        i, j = (int(k) for k in np.unravel_index(np.argmax(np.abs(a - a.T)), a.shape))
        raise AppError(f"{what} must be symmetric, not {float(a[i, j])} at [{i}, {j}] "
                       f"and {float(a[j, i])} at [{j}, {i}]")
    try:
        np.linalg.cholesky(a)
    except np.linalg.LinAlgError:
        low = float(np.linalg.eigvalsh(a).min())
        raise AppError(f"{what} must be positive definite (a covariance the filter can factorise), "
                       f"not with eigenvalue {low:.3g}") from None


def checked_scenario(app: UkfApplication, steps: int, seed: int) -> Scenario:
    """``app.scenario(steps, seed)``, checked: exactly ``steps`` iterations, ``t`` (K,),
    ``truth`` (K, n), ``u`` None or (K, p), ``z`` (K, m), u and z finite.

    Raises
    ------
    AppError
        With a one-line message: no ``scenario`` method, one that raises, or arrays that do
        not fit.
    """
    name = type(app).__name__
    if getattr(type(app), "scenario", None) is UkfApplication.scenario:
        raise AppError(f"{name} defines no scenario(steps, seed): a run needs its measurements "
                       f"(see kfgen.sim.ukf.app.Scenario)")
    try:
        sc = app.scenario(steps, seed)
    except Exception as exc:  # the user's code: whatever it raises, one line
        raise AppError(f"{name}.scenario({steps}, {seed}) failed: {type(exc).__name__}: {_one_line(exc)}") from None
    if not isinstance(sc, tuple) or len(sc) != 4:
        raise AppError(f"{name}.scenario() must return a Scenario(t, truth, u, z), not {type(sc).__name__}")
    t, truth, u, z = sc
    what = f"{name}.scenario({steps}, {seed})"
    out = Scenario(_array(f"{what}.t", t, (steps,)), _array(f"{what}.truth", truth, (steps, app.n)),
                   None, _array(f"{what}.z", z, (steps, app.m)))
    if u is not None:
        try:
            shape = np.shape(u)
        except (TypeError, ValueError):
            shape = None
        if shape is None or len(shape) != 2:
            got = "not numbers" if shape is None else f"shape {shape}"
            raise AppError(f"{what}.u must be None (no control input) or an array of shape ({steps}, p), not {got}")
        width = shape[1]
        out = out._replace(u=_array(f"{what}.u", u, (steps, width)))
    return out


def _one_line(text) -> str:
    return " ".join(str(text).split())


#: Where the applications shipped with kfgen live: ``nanosat:Nanosat`` is short for
#: ``kfgen.sim.ukf.apps.nanosat:Nanosat`` unless a module ``nanosat`` of the user's imports.
SHIPPED = "kfgen.sim.ukf.apps"


def _find_file(module: str) -> Path:
    """The file ``module`` names: a path from the current directory (or absolute); a bare file
    name (``ctrv.py``, as generated files record it, :func:`portable_spec`) is also looked
    for in the directories of ``sys.path``, where a runner puts the application's directory."""
    path = Path(module)
    if path.is_file():
        return path
    if path.name == module:
        found = next((Path(d or ".") / module for d in sys.path if (Path(d or ".") / module).is_file()), None)
        if found is not None:
            return found
    raise AppError(f"no such file {module!r}")


def _import(module: str):
    """Import ``module`` (a dotted name, found from the current directory too, or a .py file,
    :func:`_find_file`; failing that, a shipped application's module of that name,
    :data:`SHIPPED`)."""
    if module.endswith(".py"):
        path = _find_file(module)
        spec = importlib.util.spec_from_file_location(path.stem, path)
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        return mod
    # A console script's sys.path starts at its own directory, not the user's.
    sys.path.insert(0, str(Path.cwd()))
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as exc:
        if exc.name != module or "." in module or importlib.util.find_spec(f"{SHIPPED}.{module}") is None:
            raise
    finally:
        sys.path.remove(str(Path.cwd()))
    return importlib.import_module(f"{SHIPPED}.{module}")


def load_app(spec: str) -> UkfApplication:
    """The application ``spec`` names, instantiated with no arguments and checked.

    Parameters
    ----------
    spec : str
        ``"module:Class"`` (a dotted module name, importable or found from the current
        directory; a name neither finds is looked up among the shipped applications, so
        ``"nanosat:Nanosat"`` and ``"tracker:Tracker"`` work) or
        ``"path/to/file.py:Class"``; ``Class`` is a subclass of
        :class:`UkfApplication` (or anything callable with no arguments that returns an
        instance of one).

    Raises
    ------
    AppError
        With a one-line message: a spec not of that form, a module that does not import, a
        missing class, an instance that is not a :class:`UkfApplication` or does not pass
        :meth:`UkfApplication.check`.
    """
    if not isinstance(spec, str) or spec.count(":") != 1 or not all(spec.split(":")):
        raise AppError(f"must be module:Class (or file.py:Class), not {spec!r}")
    module, attr = spec.split(":")
    if not attr.isidentifier():
        raise AppError(f"{attr!r} in {spec!r} is not a class name")
    try:
        mod = _import(module)
    except AppError:
        raise
    except Exception as exc:  # the user's module: whatever it raises, one line
        raise AppError(f"cannot import {module!r}: {type(exc).__name__}: {_one_line(exc)}") from None
    cls = getattr(mod, attr, None)
    if cls is None:
        raise AppError(f"module {module!r} has no {attr!r}")
    if not callable(cls):
        raise AppError(f"{spec} is a {type(cls).__name__}, not a UkfApplication class")
    try:
        app = cls()
    except Exception as exc:
        raise AppError(f"{spec}() failed: {type(exc).__name__}: {_one_line(exc)}") from None
    if not isinstance(app, UkfApplication):
        raise AppError(f"{spec}() is a {type(app).__name__}, not a UkfApplication (kfgen.sim.ukf.app)")
    app.check()
    return app


def portable_spec(spec: str) -> tuple[str, Path | None]:
    """``spec`` as the generated files record it, and the directory it is found from.

    A file's spec (``myapps/ctrv.py:Ctrv``, relative to the current directory, or absolute)
    is recorded by the file's name, ``ctrv.py:Ctrv``, and comes with the file's directory
    (absolute): the manifest and its "regenerate it with" command then do not depend on the
    directory a command ran in nor on how the path was spelt (one file, one recording), and the
    command regenerates the core when run from the application's directory. A module's spec
    (``nanosat:Nanosat``) is returned as it is, with None.

    Raises
    ------
    AppError
        When the file does not exist.
    """
    module, _, cls = spec.rpartition(":")
    if not module.endswith(".py"):
        return spec, None
    path = Path(module)
    if not path.is_file():
        raise AppError(f"no such file {module!r}")
    return f"{path.name}:{cls}", path.resolve().parent


def _where(fn, tb=None) -> str:
    """``file:line`` of ``fn``'s definition, or of the last line of ``tb`` in ``fn``'s file
    (the file from the current directory when it lies under it)."""
    code = getattr(fn, "__code__", None)
    if code is None:
        return "?"
    line = code.co_firstlineno
    while tb is not None:
        if tb.tb_frame.f_code.co_filename == code.co_filename:
            line = tb.tb_lineno
        tb = tb.tb_next
    path = Path(code.co_filename)
    if path.is_relative_to(Path.cwd()):
        path = path.relative_to(Path.cwd())
    return f"{path}:{line}"


def _probe(app: UkfApplication, name: str, args: tuple, size: str, what: str) -> None:
    fn = getattr(app, name)
    length = getattr(app, size)
    label = f"{type(app).__name__}.{name}"
    try:
        out = fn(*args)
    except Exception as exc:  # the user's function: whatever it raises, one line
        raise AppError(f"{label} ({_where(fn, exc.__traceback__)}) raised {type(exc).__name__}: "
                       f"{_one_line(exc)} (called on {what})") from None
    try:
        a = None if out is None else np.asarray(out, dtype=np.float64)
    except (TypeError, ValueError):
        a = None
    if a is None or a.size != length:
        got = "None" if out is None else "something that is not numbers" if a is None else f"shape {a.shape}"
        raise AppError(f"{label} ({_where(fn)}) returned {got}, not {size} = {length} values (called on {what})")
    if not np.all(np.isfinite(a)):
        raise AppError(f"{label} ({_where(fn)}) returned {np.ravel(a).tolist()}: not finite (called on {what})")


def check_models(app: UkfApplication) -> None:
    """Call the application's f and h once on x0 (zero noise, a zero control input) and once
    on a sigma point, x0 plus the first column of chol(P0): a function that raises or returns
    the wrong number of values is found before a core is generated and built.

    Raises
    ------
    AppError
        One line naming the function, its ``file:line`` (where it raised, else where it is
        defined) and what was wrong.
    """
    x0 = np.asarray(app.x0, dtype=np.float64)
    point = x0 + np.linalg.cholesky(np.asarray(app.P0, dtype=np.float64))[:, 0]
    for x, what in ((x0, "x0"), (point, "x0 + chol(P0)[:, 0]")):
        _probe(app, "f", (x, np.zeros(app.nw), np.zeros(app.nu), app.dt), "n", what)
        _probe(app, "h", (x, np.zeros(app.nv)), "m", what)


def _register() -> None:
    # hdl imports neither gen nor sim: it is handed the loader for ``kfgen ukf --on-chip``.
    from kfgen.hdl.ukf.models import set_loader
    set_loader(load_app)


_register()
