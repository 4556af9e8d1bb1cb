"""The IMM core's registers and memory buffer, declared once as data (the classes and the
placement rules of :mod:`kfgen.hdl.engine.regmap`: registers from 0x0, the buffer at the next
power of two, regions in the engine's order with no gaps).

Model matrices are stacked model by model: ``F`` is an ``R n x n`` matrix whose rows
``r n .. r n + n - 1`` are model r's F (likewise ``Q``, ``P_model``; ``H`` and ``R`` by
``d`` rows); ``x_model`` holds model r's state in row r. One ``CTRL.start`` runs a whole IMM
iteration: mixing, the R Kalman filters and the combination (:mod:`kfgen.hdl.imm.programs`).
"""

from __future__ import annotations

from ..describe import once_per_params
from ..engine.regmap import Identity, RegisterMap, engine_registers, place_map

__all__ = ["imm_map", "identity", "regions", "CORE_ID", "MAP_VERSION", "CYCLES"]

#: ID.core of the IMM (ASCII 'I').
CORE_ID = 0x49
#: ID.version: raised whenever an offset, field or meaning in this map changes.
MAP_VERSION = 1

EVENTS = (
    ("done", 1, "the iteration started last has finished"),
    ("err_pivot", 2, "a pivot was <= 0 or NaN: a predicted model probability c_j, a Schur pivot or the "
                     "determinant of an innovation covariance S_j (not positive definite), or the sum of "
                     "the scaled likelihoods; the iteration ran to its end and the core is idle"),
    ("err_nan", 3, "a NaN or an infinity reached mu, a model's x or P, or the combined x or P"),
    ("err_busy", 4, "CTRL.start was written while busy and was refused"),
)


def identity(params) -> Identity:
    """What the IMM declares for the engine's ID, CTRL and STATUS registers: one start runs an
    iteration."""
    return Identity(
        CORE_ID, "the IMM", MAP_VERSION,
        (("models", "models R", params.R), ("n", "states n of every model", params.n),
         ("d", "measurements d", params.d)),
        "iteration", "write 1 to run one IMM iteration (mixing, the R filters, the combination); refused while "
                     "busy (STATUS.err_busy)", EVENTS)


def regions(params) -> tuple[tuple[str, int, int, str, str, str, str], ...]:
    """(name, rows, cols, access, role, desc, layout) in buffer order: the engine's (programs);
    role one of :data:`kfgen.hdl.engine.regmap.REGION_ROLES`."""
    R, n, d = params.R, params.n, params.d

    def stacked(rows, cols):
        sizes = ", ".join(f"{k} = {v}" for k, v in (("R", R), ("n", n), ("d", d)) if k in ("R", rows, cols))
        return (f"R models stacked by rows: model r's {rows} x {cols} matrix, row-major, in rows r {rows} .. "
                f"r {rows} + {rows} - 1 ({sizes})")

    return (
        ("pi", R, R, "rw", "input", "transition matrix: element (i, j) the probability of a switch from model i to "
                                    "model j (rows sum to 1)",
         f"R x R, row-major: row i from model i, column j to model j (R = {R})"),
        ("mu", R, 1, "rw", "state", "model probabilities mu; after an iteration the updated ones",
         f"a column: model r's probability in row r (R = {R})"),
        ("F", R * n, n, "rw", "input", "state transition F of each model", stacked("n", "n")),
        ("Q", R * n, n, "rw", "input", "process-noise covariance Q of each model",
         stacked("n", "n")),
        ("H", R * d, n, "rw", "input", "measurement matrix H of each model", stacked("d", "n")),
        ("R", R * d, d, "rw", "input", "measurement-noise covariance R of each model",
         stacked("d", "d")),
        ("x_model", R, n, "rw", "state", "each model's state estimate; after an iteration the updated ones",
         f"R rows of n elements: model r's state in row r (R = {R}, n = {n})"),
        ("P_model", R * n, n, "rw", "state", "each model's covariance, full; after an iteration the updated ones "
                                             "(exactly symmetric)", stacked("n", "n")),
        ("z", d, 1, "rw", "input", "measurement z of this iteration",
         f"a column: element i in row i (d = {d})"),
        ("x", n, 1, "ro", "output", "combined state estimate (written by the iteration)",
         f"a column: element i in row i (n = {n})"),
        ("P", n, n, "ro", "output", "combined covariance, full (written by the iteration, exactly symmetric)",
         f"n x n, row-major, both triangles (n = {n})"),
    )


#: The manifest's ``cycles`` keys.
CYCLES = {
    "iterate": "one IMM iteration (CTRL.start): mixing, the R Kalman filters and the combination, "
               "mu, x_model and P_model updated in place, x and P written",
}


@once_per_params
def imm_map(params) -> RegisterMap:
    """The register and memory map of an IMM core with parameters ``params`` (a
    :class:`kfgen.hdl.imm.params.ImmParams`), built once per parameter object.

    Raises
    ------
    ParamError
        ``address_width`` when ``params.address_width`` is too narrow for the map.
    """
    return place_map(engine_registers(identity(params), params), regions(params), params.fmt,
                     params.address_width)
