"""The application API of the engine's cores: the base class a user's application subclasses
(:class:`UkfApplication`: sizes, f, h, W0, x0, P0, Q, R) and :func:`load_app`, which loads one
from ``module:Class`` or ``file.py:Class``.

The core loads and traces an application itself (``kfgen ukf --app ... --on-chip``,
:mod:`kfgen.hdl.ukf.models`), so this is pure Python and numpy, below ``gen`` and ``sim``. The
simulation half of an application (its seeded :class:`~kfgen.sim.ukf.app.Scenario`, the
references) lives in :mod:`kfgen.sim.ukf.app`, which re-exports these names: users write
``from kfgen.sim.ukf.app import Scenario, UkfApplication``.
"""

from __future__ import annotations

import importlib
import importlib.util
import math
import sys
from pathlib import Path

import numpy as np

__all__ = ["AppError", "UkfApplication", "load_app", "portable_spec", "recorded_spec", "resolved_spec", "check_models", "checked_array", "one_line",
           "SHIPPED"]


class AppError(ValueError):
    """A bad application or application spec; the message is one line."""


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

    def scenario(self, steps: int, seed: int):
        """A simulated run of ``steps`` iterations, reproducible from ``seed``: a
        :class:`kfgen.sim.ukf.app.Scenario` (simulation's, not the core's)."""
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
            a = checked_array(f"{name}.{key}", getattr(self, key), shape)
            if key != "x0":
                _positive_definite(f"{name}.{key}", a)


def checked_array(what: str, value, shape: tuple) -> np.ndarray:
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


def one_line(text) -> str:
    """``text`` (a user's exception, say) on one line, for an error message."""
    return " ".join(str(text).split())


#: Where the applications shipped with kfgen live: ``nanosat:Nanosat`` is short for
#: ``kfgen.sim.ukf.apps.nanosat:Nanosat`` unless a module ``nanosat`` of the user's imports.
#: Named, not imported: like a user's module, it is imported only when a spec names it.
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
    """Import ``module`` (a dotted name, found from the current directory too, or a .py file;
    failing that, a shipped application's module of that name, :data:`SHIPPED`)."""
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


def load_app(spec: str, base: type = UkfApplication, where: str = "kfgen.sim.ukf.app"):
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
    base : type
        The class the application must be an instance of (another core's application class,
        :class:`kfgen.sim.imm.app.ImmApplication`), with a ``check()`` method; ``where``
        names the module users import it from, for the messages.

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
        raise AppError(f"cannot import {module!r}: {type(exc).__name__}: {one_line(exc)}") from None
    cls = getattr(mod, attr, None)
    if cls is None:
        raise AppError(f"module {module!r} has no {attr!r}")
    if not callable(cls):
        raise AppError(f"{spec} is a {type(cls).__name__}, not a {base.__name__} class")
    try:
        app = cls()
    except Exception as exc:
        raise AppError(f"{spec}() failed: {type(exc).__name__}: {one_line(exc)}") from None
    if not isinstance(app, base):
        raise AppError(f"{spec}() is a {type(app).__name__}, not a {base.__name__} ({where})")
    app.check()
    return app


def recorded_spec(spec: str) -> str:
    """``spec`` as generated files record it: a file's spec (``myapps/ctrv.py:Ctrv``, relative
    or absolute) by the file's name, ``ctrv.py:Ctrv``, so that the manifest and its "regenerate
    it with" command depend neither on the directory a command ran in nor on how the path was
    spelt (one file, one recording; the command regenerates the core when run from the
    application's directory); a module's spec (``nanosat:Nanosat``) as it is."""
    module, _, cls = spec.rpartition(":")
    return f"{Path(module).name}:{cls}" if module.endswith(".py") else spec


def resolved_spec(spec: str) -> str:
    """``spec`` with a relative file's path made absolute, so that it loads from any directory
    (a simulation runs in another one); a module's spec as it is."""
    module, _, cls = spec.rpartition(":")
    if module.endswith(".py") and Path(module).is_file():
        return f"{Path(module).resolve()}:{cls}"
    return spec


def portable_spec(spec: str) -> tuple[str, Path | None]:
    """``spec`` as the generated files record it (:func:`recorded_spec`), and the absolute
    directory of its file (None for a module's spec).

    Raises
    ------
    AppError
        When the file does not exist.
    """
    module = spec.rpartition(":")[0]
    if not module.endswith(".py"):
        return spec, None
    path = Path(module)
    if not path.is_file():
        raise AppError(f"no such file {module!r}")
    return recorded_spec(spec), path.resolve().parent


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
                       f"{one_line(exc)} (called on {what})") from None
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
