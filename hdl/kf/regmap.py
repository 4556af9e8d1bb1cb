"""The linear Kalman filter core's registers and memory buffer, declared once as data (the
classes and the placement rules of :mod:`kfgen.hdl.engine.regmap`: registers from 0x0, the
buffer at the next power of two, regions in the engine's order with no gaps)::

    0x0 .. 0x13      registers ID (64 bits), CTRL, STATUS, IRQ_ENABLE (with ``irq``)
    B   .. B + size  the buffer: x, P, F, B, Q, H, R, z, u (with a steady gain x, F, B, H, z, u, K)

``B`` and ``u`` are there with control inputs only (nu > 0); ``u`` follows ``z``, as the
stream ports write them. One ``CTRL.start`` runs one iteration (predict and update,
:mod:`kfgen.hdl.kf.programs`). With a steady gain, CTRL.step names two steps: ``iterate``
and its prologue ``gain``, which the core runs by itself before an iteration that follows a
write to F, B, H or K.
"""

from __future__ import annotations

from ..describe import once_per_params
from ..engine.regmap import Field, Identity, RegisterMap, Value, engine_registers, place_map

__all__ = ["kf_map", "identity", "regions", "steps", "CORE_ID", "MAP_VERSION", "STEADY_VERSION", "CYCLES"]

#: ID.core of the linear Kalman filter (ASCII 'K').
CORE_ID = 0x4B
#: ID.version: raised whenever an offset, field or meaning in this map changes.
MAP_VERSION = 1
#: ID.version of a steady-gain core (K in the buffer, no P, Q, R; CTRL.step).
STEADY_VERSION = 2

#: The manifest's ``cycles`` keys (and with a steady gain the values of CTRL.step).
CYCLES = {
    "iterate": "one iteration (CTRL.start): x^- = F x + B u, P^- = F P F^T + Q, the update by z with K from "
               "the LDL^T of S = H P^- H^T + R, Joseph's covariance update; x and P in place",
    "gain": "the steady gain's A = F - K H F and G = B - K H B; the core runs it before the first iterate after "
            "a write to F, B, H or K (or reset), or software starts it ahead",
}

#: With a steady gain: the steps CTRL.step names.
STEPS = (
    Value("iterate", 0, "one iteration: x = A x + G u + K z, reading z and u"),
    Value("gain", 1, CYCLES["gain"]),
)


def steps(params) -> tuple[Value, ...]:
    """The steps CTRL.step names (a steady gain's), or none (the full filter: one step)."""
    return STEPS if params.steady_gain else ()


def identity(params) -> Identity:
    """What the KF declares for the engine's ID, CTRL and STATUS registers: one start runs an
    iteration."""
    steady = params.steady_gain
    step = Field("step", 4, 1, "rw", "the step that start runs", values=STEPS) if steady else None
    pivot = ("never set by a steady-gain core (no division)" if steady else
             "a pivot D_j of S = H P^- H^T + R's LDL^T was <= 0 or NaN: S is not positive definite; the "
             "iteration ran to its end and the core is idle")
    return Identity(
        CORE_ID, "the linear Kalman filter", STEADY_VERSION if steady else MAP_VERSION,
        (("n", "states n", params.n), ("m", "measurements m", params.m), ("nu", "control inputs nu", params.nu)),
        "iteration", "write 1 to run one iteration (predict and update)" + (" or the step named by step (in the "
                                                                             "same write)" if steady else "")
        + "; refused while busy (STATUS.err_busy)",
        (("done", 1, "the iteration started last has finished"),
         ("err_pivot", 2, pivot),
         ("err_nan", 3, "a NaN or an infinity reached x" + ("" if steady else " or P")),
         ("err_busy", 4, "CTRL.start was written while busy and was refused")),
        step)


def regions(params) -> tuple[tuple[str, int, int, str, str, str, str], ...]:
    """(name, rows, cols, access, role, desc, layout) in buffer order: the engine's (programs);
    role one of :data:`kfgen.hdl.engine.regmap.REGION_ROLES`."""
    n, m, nu, steady = params.n, params.m, params.nu, params.steady_gain

    def column(k, what):
        return f"a column: element i in row i ({what} = {k})"

    def matrix(rows, cols, sym=False):
        """``rows`` and ``cols``: (symbol, value)."""
        sizes = ", ".join(f"{k} = {v}" for k, v in dict((rows, cols)).items())
        both = ", both triangles; the core reads the lower one" if sym else ""
        return f"{rows[0]} x {cols[0]}, row-major{both} ({sizes})"

    N, M, U = ("n", n), ("m", m), ("nu", nu)
    out = [("x", n, 1, "rw", "state", "state estimate x; after an iteration the updated one", column(n, "n"))]
    if not steady:
        out.append(("P", n, n, "rw", "state", "state covariance P; after an iteration the updated one (exactly "
                                              "symmetric)", matrix(N, N, sym=True)))
    out.append(("F", n, n, "rw", "input", "state transition F", matrix(N, N)))
    if nu:
        out.append(("B", n, nu, "rw", "input", "control matrix B", matrix(N, U)))
    if not steady:
        out.append(("Q", n, n, "rw", "input", "process-noise covariance Q", matrix(N, N, sym=True)))
    out.append(("H", m, n, "rw", "input", "measurement matrix H", matrix(M, N)))
    if not steady:
        out.append(("R", m, m, "rw", "input", "measurement-noise covariance R", matrix(M, M, sym=True)))
    out.append(("z", m, 1, "rw", "input", "measurement z of this iteration", column(m, "m")))
    if nu:  # after z: a stream beat writes both
        out.append(("u", nu, 1, "rw", "input", "control input u of this iteration", column(nu, "nu")))
    if steady:
        out.append(("K", n, m, "rw", "input", "the fixed gain K (software writes it, e.g. the steady-state gain "
                                              "of the discrete algebraic Riccati equation)", matrix(N, M)))
    return tuple(out)


@once_per_params
def kf_map(params) -> RegisterMap:
    """The register and memory map of a KF core with parameters ``params`` (a
    :class:`kfgen.hdl.kf.params.KfParams`), built once per parameter object.

    Raises
    ------
    ParamError
        ``address_width`` when ``params.address_width`` is too narrow for the map.
    """
    return place_map(engine_registers(identity(params), params), regions(params), params.fmt,
                     params.address_width)
