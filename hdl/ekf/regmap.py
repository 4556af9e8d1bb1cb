"""The EKF core's registers and memory buffer, declared once as data (the classes and the
placement rules of :mod:`kfgen.hdl.engine.regmap`: registers from 0x0, the buffer at the next
power of two, regions in the engine's order with no gaps)::

    0x0 .. 0x13      registers ID (64 bits), CTRL, STATUS, IRQ_ENABLE (with ``irq``)
    B   .. B + size  the buffer: x, P, Q, R, z, u (u when the application has a control input)

One ``CTRL.start`` runs one whole iteration (:mod:`kfgen.hdl.ekf.programs`): software writes
z (and u), starts, and reads the estimate back from x and P.
"""

from __future__ import annotations

from ..describe import once_per_params
from ..engine.regmap import Identity, RegisterMap, engine_registers, place_map

__all__ = ["ekf_map", "identity", "regions", "CORE_ID", "MAP_VERSION", "CYCLES"]

#: ID.core of the EKF (ASCII 'E').
CORE_ID = 0x45
#: ID.version: raised whenever an offset, field or meaning in this map changes.
MAP_VERSION = 1

EVENTS = (
    ("done", 1, "the iteration started last has finished"),
    ("err_pivot", 2, "a pivot D_j of the innovation covariance's LDL^T factorisation was <= 0 or NaN: S = H P^- "
                     "H^T + M R M^T is not positive definite; the iteration ran to its end (x and P hold "
                     "what it computed from the bad pivot) and the core is idle"),
    ("err_nan", 3, "a NaN or an infinity reached x or P"),
    ("err_busy", 4, "CTRL.start was written while busy and was refused"),
)

#: The manifest's ``cycles`` keys.
CYCLES = {
    "iterate": "one EKF iteration (CTRL.start): x^- = f(x, 0, u) with F and L, P^- = F P F^T + L Q L^T, h and "
               "H, M at x^-, S = H P^- H^T + M R M^T, its LDL^T, the gain and the update of x and P in place",
}


def identity(params) -> Identity:
    """What the EKF declares for the engine's ID, CTRL and STATUS registers: one start runs an
    iteration (the control input's length nu is the size of region u)."""
    return Identity(
        CORE_ID, "the EKF", MAP_VERSION,
        (("n", "states n", params.n), ("nw", "process-noise terms nw", params.nw),
         ("nv", "measurement-noise terms nv", params.nv), ("m", "observations m", params.m)),
        "iteration", "write 1 to run one EKF iteration (predict by f and its Jacobians, update by z and h's); "
                     "refused while busy (STATUS.err_busy)", EVENTS)


def regions(params) -> tuple[tuple[str, int, int, str, str, str, str], ...]:
    """(name, rows, cols, access, role, desc, layout) in buffer order: the engine's (the
    programs' ``bus`` regions, from word 0); role one of
    :data:`kfgen.hdl.engine.regmap.REGION_ROLES`."""
    n, m, nw, nv, nu = params.n, params.m, params.nw, params.nv, params.nu
    column = "a column: element i in row i"
    out = (
        ("x", n, 1, "rw", "state", "state estimate x; after an iteration x^+", f"{column} (n = {n})"),
        ("P", n, n, "rw", "state", "state covariance P, full; after an iteration P^+ (exactly symmetric)",
         f"n x n, row-major, both triangles (n = {n})"),
        ("Q", nw, nw, "rw", "input", "process-noise covariance Q (of f's w), full",
         f"nw x nw, row-major, both triangles (nw = {nw})"),
        ("R", nv, nv, "rw", "input", "measurement-noise covariance R (of h's v), full",
         f"nv x nv, row-major, both triangles (nv = {nv})"),
        ("z", m, 1, "rw", "input", "measurement z of this iteration", f"{column} (m = {m})"),
    )
    if nu:
        out += (("u", nu, 1, "rw", "input", "control input u of this iteration's f", f"{column} (nu = {nu})"),)
    return out


@once_per_params
def ekf_map(params) -> RegisterMap:
    """The register and memory map of an EKF core with parameters ``params`` (a
    :class:`kfgen.hdl.ekf.params.EkfParams`), built once per parameter object.

    Raises
    ------
    ParamError
        ``address_width`` when ``params.address_width`` is too narrow for the map.
    """
    return place_map(engine_registers(identity(params), params), regions(params), params.fmt,
                     params.address_width)
