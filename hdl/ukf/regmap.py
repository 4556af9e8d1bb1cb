"""The UKF core's registers and memory buffer, declared once as data (the classes and the
placement rules of :mod:`kfgen.hdl.engine.regmap`: registers from 0x0, the buffer at the next
power of two, regions in the engine's order with no gaps)::

    0x0 .. 0x13      registers ID (64 bits), CTRL, STATUS, IRQ_ENABLE (with ``irq``)
    B   .. B + size  the buffer: x, P, Q, R, sigma_points, sigma_points_f, sigma_points_h, z

``sigma_points`` holds N points of M words, point by point, as an N x M matrix; it is the
one read-only region.

Regions
-------
Each region is declared with its description, its ``role`` (:data:`REGION_ROLES`: ``input``
software writes and the core only reads, ``state`` the core reads and overwrites in place,
``output`` the core writes) and its ``layout`` (what its rows and columns hold); the manifest,
the C header and the Markdown document all print them from the declaration.
"""

from __future__ import annotations

from ..describe import once_per_params
from ..engine.regmap import Field, Identity, RegisterMap, Value, engine_registers, place_map
from .forms import covariance_region

__all__ = ["ukf_map", "identity", "steps", "CORE_ID", "MAP_VERSION", "MAP_VERSION_ON_CHIP", "SQRT_VERSIONS", "STEPS",
           "ON_CHIP_STEPS", "SQRT_NOISE"]

#: ID.core of the UKF (ASCII 'U').
CORE_ID = 0x55
#: ID.version: raised whenever an offset, field or meaning in this map changes.
MAP_VERSION = 1
#: ID.version of a core with f and h on chip (``on_chip``): one step, ``iteration``, and ``u``.
MAP_VERSION_ON_CHIP = 2
#: ID.version of the square-root form (``form = "sqrt"``: region ``sqrtP`` instead of ``P``,
#: and the step ``noise``), three-step and on chip.
SQRT_VERSIONS = {False: 3, True: 4}


#: The steps CTRL.step names, and the manifest's ``cycles`` keys.
STEPS = (
    Value("sig_gen", 0, "sigma points of (x, P, Q, R) into sigma_points (eqs. 3-8, 21-24)"),
    Value("predict", 1, "x, P <- mean and covariance of sigma_points_f (eqs. 10-11)"),
    Value("update", 2, "x, P <- the update by z and sigma_points_h (eqs. 13-19)"),
)


#: The steps of a core with f and h on chip (``on_chip``); CTRL.step 0..2 are reserved there
#: (start does nothing).
ON_CHIP_STEPS = (
    Value("iteration", 3, "one whole iteration: sig_gen, f on every point, predict, h on every moved point "
                          "and update, reading z and u; x, P <- the estimate (after a write to Q or R, "
                          "noise runs first, by itself)"),
    Value("noise", 4, "the factors of Q and R and the sigma points' noise rows; the core runs it before the "
                      "first iteration after a write to Q or R (or reset), or software starts it ahead"),
)


#: The fourth step of the three-step core in the square-root form.
SQRT_NOISE = Value("noise", 3, "the factors of Q and R and the sigma points' noise rows; the core runs it before "
                               "the first sig_gen after a write to Q or R (or reset), or software starts it ahead")


def steps(params) -> tuple[Value, ...]:
    """The steps CTRL.step names for ``params``: :data:`ON_CHIP_STEPS`, or :data:`STEPS`
    (and :data:`SQRT_NOISE` in the square-root form)."""
    if params.on_chip:
        return ON_CHIP_STEPS
    return STEPS + (SQRT_NOISE,) if params.form == "sqrt" else STEPS


def _version(params) -> int:
    if params.form == "sqrt":
        return SQRT_VERSIONS[params.on_chip]
    return MAP_VERSION_ON_CHIP if params.on_chip else MAP_VERSION


def identity(params) -> Identity:
    """What the UKF declares for the engine's ID, CTRL and STATUS registers."""
    sqrt = params.form == "sqrt"
    if params.on_chip:
        step = Field("step", 4, 3, "rw", "the step that start runs; 0..2 and 5..7 are reserved (start does nothing)",
                     values=steps(params))
    else:
        step = Field("step", 4, 2, "rw", "the step that start runs" if sqrt else
                     "the step that start runs; 3 is reserved (start does nothing)", values=steps(params))
    return Identity(
        CORE_ID, "the UKF", _version(params),
        (("n", "states n", params.n), ("nw", "process-noise terms nw", params.nw),
         ("nv", "measurement-noise terms nv", params.nv), ("m", "observations m", params.m)),
        "step", "write 1 to start the step named by step (in the same write); refused while busy (STATUS.err_busy)",
        (("done", 1, "the step started last has finished"),
         ("err_pivot", 2, "a pivot was <= 0 or NaN: a pivot of Q's or R's Cholesky factorisation (not positive "
                          "definite), or the squared norm of an innovation row in update's Householder "
                          "triangularisation (the innovation covariance singular); the step ran to its end"
          if sqrt else
          "a pivot D_j of the LDL^T factorisation (eqs. 23-24) was <= 0 or NaN: P^a or S is "
          "not positive definite; the step ended early and the core is idle"),
         ("err_nan", 3, "a NaN or an infinity reached x or " + covariance_region(params.form)),
         ("err_busy", 4, "CTRL.start was written while busy and was refused")),
        step)


def _regions(params) -> tuple[tuple[str, int, int, str, str, str, str], ...]:
    """(name, rows, cols, access, role, desc, layout) in buffer order: the engine's order
    (programs); role one of REGION_ROLES."""
    n, m, nw, nv, M, N = params.n, params.m, params.nw, params.nv, params.M, params.N
    column = "a column: element i in row i"
    regions = (
        ("x", n, 1, "rw", "state", "state estimate x; after predict x^-, after update x^+",
         f"{column} (n = {n})"),
        ("sqrtP", n, n, "rw", "state", "the Cholesky factor S of the state covariance (lower triangular, positive "
                                       "diagonal), P = S S^T; after predict S^-, after update S^+; software writes "
                                       "chol(P0)",
         f"n x n, row-major; the core reads and writes the lower triangle and diagonal only (n = {n})")
        if params.form == "sqrt" else
        ("P", n, n, "rw", "state", "state covariance P, full; after predict P^-, after update P^+",
         f"n x n, row-major, both triangles (n = {n})"),
        ("Q", nw, nw, "rw", "input", "process-noise covariance Q, full",
         f"nw x nw, row-major, both triangles (nw = {nw})"),
        ("R", nv, nv, "rw", "input", "measurement-noise covariance R, full",
         f"nv x nv, row-major, both triangles (nv = {nv})"),
        ("sigma_points", N, M, "ro", "output", "sigma points chi_i of x^a = [x; w; v], point by point "
                                               "(written by sig_gen, eq. 8)",
         f"N points of M elements, point i in row i: columns 0 .. n - 1 its x, then nw of w, then nv of v "
         f"(N = {N}, M = {M}, n = {n}, nw = {nw}, nv = {nv})"),
        ("sigma_points_f", N, n, "rw", "input", "f(chi_i), point by point (written by software after sig_gen)",
         f"N points of n elements, f(chi_i) in row i (N = {N}, n = {n})"),
        ("sigma_points_h", N, m, "rw", "input", "h(chi_i^-), point by point (written by software after predict)",
         f"N points of m elements, h(chi_i^-) in row i (N = {N}, m = {m})"),
        ("z", m, 1, "rw", "input", "measurement z", f"{column} (m = {m})"),
    )
    return _on_chip(regions, params.nu, column) if params.on_chip else regions


def _on_chip(regions, nu, column):
    """The regions of a core with f and h on chip: the core writes the moved points, and the
    control input ``u`` follows ``z`` (when nu > 0)."""
    out = []
    for name, rows, cols, access, role, desc, layout in regions:
        if name == "sigma_points_f":
            access, role, desc = "ro", "output", "f(chi_i), point by point (written by iteration: f on chip)"
        elif name == "sigma_points_h":
            access, role, desc = "ro", "output", "h(chi_i^-), point by point (written by iteration: h on chip)"
        out.append((name, rows, cols, access, role, desc, layout))
    if nu:
        out.append(("u", nu, 1, "rw", "input", "control input u of the iteration's f", f"{column} (nu = {nu})"))
    return tuple(out)


@once_per_params
def ukf_map(params) -> RegisterMap:
    """The register and memory map of a UKF core with parameters ``params`` (a
    :class:`kfgen.hdl.ukf.params.UkfParams`), built once per parameter object.

    Raises
    ------
    ParamError
        ``address_width`` when ``params.address_width`` is too narrow for the map.
    """
    return place_map(engine_registers(identity(params), params), _regions(params), params.fmt,
                     params.address_width)
