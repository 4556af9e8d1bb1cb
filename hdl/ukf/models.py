"""An application's f and h compiled for the engine (``kfgen ukf --app MODULE:CLASS --on-chip``).

The application is the user's Python (:class:`kfgen.hdl.engine.app.UkfApplication`), loaded
here by :func:`~kfgen.hdl.engine.app.load_app`. The functions are traced once per
configuration (:func:`kfgen.hdl.engine.trace.trace`):

* f(x, w, u, dt) with ``x`` (n), ``w`` (nw) the sigma point's parts and ``u`` (nu) the control
  input, ``dt`` the application's: a value that reads only ``u`` and constants is computed
  once for all points;
* h(x, v) with ``x`` (n) the moved point and ``v`` (nv) the point's measurement-noise part.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

from ..describe import ParamError
from ..engine.app import load_app
from ..engine.trace import Model, TraceError, trace

__all__ = ["UkfModels", "compile_models"]


@dataclass(frozen=True)
class UkfModels:
    """The traced f and h of an application, and its control input's length."""

    nu: int
    f: Model
    h: Model

    @property
    def fma_count(self) -> int:
        """Multiply-adds of one point's f and h."""
        return self.f.fma_count + self.h.fma_count


@lru_cache(maxsize=16)
def compile_models(spec: str, sizes: tuple[int, int, int, int]) -> UkfModels:
    """The application ``spec``'s f and h traced for a core of ``sizes`` (n, nw, nv, m).

    Raises
    ------
    ParamError
        ``app``: an application that does not load or does not fit the sizes, or
        a construct that does not trace (its file and line named).
    """
    try:
        app = load_app(spec)
    except ValueError as exc:
        raise ParamError("app", " ".join(str(exc).split())) from None
    n, nw, nv, m = sizes
    have = (app.n, app.nw, app.nv, app.m)
    if have != sizes:
        raise ParamError("app", f"{spec} has n, nw, nv, m = {have}, the core {sizes}: --on-chip needs the "
                                "application's sizes")
    nu = int(getattr(app, "nu", 0))
    cls = type(app)
    try:
        f = trace(lambda x, w, u: app.f(x, w, u, app.dt), {"x": n, "w": nw, "u": nu},
                  varying=("x", "w"), name=f"{cls.__name__}.f", scope=cls.f)
        h = trace(app.h, {"x": n, "v": nv}, name=f"{cls.__name__}.h", scope=cls.h)
    except TraceError as exc:
        raise ParamError("app", str(exc)) from None
    for what, model, want in (("f", f, n), ("h", h, m)):
        if model.outputs != want:
            raise ParamError("app", f"{cls.__name__}.{what} returns {model.outputs} numbers, not {want}")
    return UkfModels(nu, f, h)
