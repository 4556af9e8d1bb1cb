"""An application's f and h with their Jacobians, compiled for the EKF (``kfgen ekf --app``).

The application is the UKF's (an object with ``n, nw, nv, m, nu, dt, f, h``): the same file
generates a UKF or an EKF. Both functions are traced once and differentiated
(:func:`~.jacobian.linearise`):

* f(x, w, u, dt) at w = 0: x^- = f(x, 0, u) and F = df/dx, L = df/dw;
* h(x, v) at v = 0: z^ = h(x^-, 0) and H = dh/dx, M = dh/dv.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..describe import ParamError
from ..engine.trace import TraceError
from .jacobian import Jacobian, Linearised, linearise

__all__ = ["EkfModels", "ekf_models"]


@dataclass(frozen=True)
class EkfModels:
    """The linearised f and h of an application, and its sizes (n, nw, nv, m, nu)."""

    sizes: tuple[int, int, int, int, int]
    f: Linearised
    h: Linearised

    @property
    def F(self) -> Jacobian:
        return self.f.jacobians["x"]

    @property
    def L(self) -> Jacobian:
        return self.f.jacobians["w"]

    @property
    def H(self) -> Jacobian:
        return self.h.jacobians["x"]

    @property
    def M(self) -> Jacobian:
        return self.h.jacobians["v"]

    @property
    def jacobians(self) -> dict:
        """F, L, H and M by name."""
        return {j.name: j for j in (self.F, self.L, self.H, self.M)}


def ekf_models(app) -> EkfModels:
    """``app``'s f and h linearised (f at w = 0, h at v = 0).

    Raises
    ------
    ParamError
        ``app``: a construct that does not trace or does not differentiate (one line, its
        file and line), or a function that returns the wrong number of values.
    """
    n, nw, nv, m, nu = (int(getattr(app, k, 0)) for k in ("n", "nw", "nv", "m", "nu"))
    cls = type(app)
    try:
        f = linearise(lambda x, w, u: app.f(x, w, u, app.dt), {"x": n, "w": nw, "u": nu}, {"x": "F", "w": "L"},
                      zero=("w",), name=f"{cls.__name__}.f", scope=cls.f)
        h = linearise(app.h, {"x": n, "v": nv}, {"x": "H", "v": "M"}, zero=("v",), name=f"{cls.__name__}.h",
                      scope=cls.h)
    except TraceError as exc:
        raise ParamError("app", str(exc)) from None
    for what, lin, want in (("f", f, n), ("h", h, m)):
        if lin.model.outputs != want:
            raise ParamError("app", f"{cls.__name__}.{what} returns {lin.model.outputs} numbers, not {want}")
    return EkfModels((n, nw, nv, m, nu), f, h)
