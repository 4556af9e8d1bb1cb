"""The IMM core's registers and memory buffer, declared once as data (the classes and the
placement rules of :mod:`kfgen.hdl.engine.regmap`: registers from 0x0, the buffer at the next
power of two, regions in the engine's order with no gaps).

Model matrices are stacked model by model: ``F`` is an ``R n x n`` matrix whose rows
``r n .. r n + n - 1`` are model r's F (likewise ``Q``, ``P_model``; ``H`` and ``R`` by
``d`` rows); ``x_model`` holds model r's state in row r. One ``CTRL.start`` runs a whole IMM
iteration: mixing, the R Kalman filters and the combination (:mod:`kfgen.hdl.imm.programs`).
"""

from __future__ import annotations

from ..engine.regmap import Field, Register, RegisterMap, place_map, status_registers

__all__ = ["imm_map", "CORE_ID", "MAP_VERSION"]

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


def _registers(params) -> tuple[Register, ...]:
    fmt = params.fmt
    regs = [
        Register("ID", 0x0, 64, "What the core is and how it was generated, so software can discover its "
                 "configuration. Two bus words, low word first.", (
                     Field("core", 0, 8, "ro", f"core identifier, {CORE_ID:#04x} ('I') for the IMM", reset=CORE_ID),
                     Field("version", 8, 4, "ro", "version of this register and memory map", reset=MAP_VERSION),
                     Field("exp_bits", 12, 4, "ro", "float format of the buffer: exponent bits", reset=fmt.exp_bits),
                     Field("frac_bits", 16, 6, "ro", "float format of the buffer: stored fraction bits",
                           reset=fmt.frac_bits),
                     Field("pes", 22, 10, "ro", "processing elements P", reset=params.pes),
                     Field("models", 32, 8, "ro", "models R", reset=params.R),
                     Field("n", 40, 8, "ro", "states n of every model", reset=params.n),
                     Field("d", 48, 8, "ro", "measurements d", reset=params.d),
                 )),
        Register("CTRL", 0x8, 32, "Starts an iteration, or resets the core to idle.", (
            Field("start", 0, 1, "w1p", "write 1 to run one IMM iteration (mixing, the R filters, the "
                                        "combination); refused while busy (STATUS.err_busy)"),
            Field("reset", 1, 1, "w1p", "write 1 for a soft reset: a running iteration stops, the core is "
                                        "idle, STATUS is cleared; the buffer is kept"),
        )),
        *status_registers(EVENTS, "iteration", params.irq),
    ]
    return tuple(regs)


def regions(params) -> tuple[tuple[str, int, int, str, str], ...]:
    """(name, rows, cols, access, desc) in buffer order: the engine's (programs)."""
    R, n, d = params.R, params.n, params.d
    return (
        ("pi", R, R, "rw", "transition matrix: pi[i][j] the probability of a switch from model i to model j "
                           "(rows sum to 1)"),
        ("mu", R, 1, "rw", "model probabilities mu; after an iteration the updated ones"),
        ("F", R * n, n, "rw", "state transition F of each model, stacked: model r in rows r n .. r n + n - 1"),
        ("Q", R * n, n, "rw", "process-noise covariance Q of each model, stacked as F"),
        ("H", R * d, n, "rw", "measurement matrix H of each model, stacked: model r in rows r d .. r d + d - 1"),
        ("R", R * d, d, "rw", "measurement-noise covariance R of each model, stacked as H"),
        ("x_model", R, n, "rw", "each model's state estimate, model r in row r; after an iteration the "
                                "updated ones"),
        ("P_model", R * n, n, "rw", "each model's covariance, full, stacked as F; after an iteration the "
                                    "updated ones (exactly symmetric)"),
        ("z", d, 1, "rw", "measurement z of this iteration"),
        ("x", n, 1, "ro", "combined state estimate (written by the iteration)"),
        ("P", n, n, "ro", "combined covariance, full (written by the iteration, exactly symmetric)"),
    )


def imm_map(params) -> RegisterMap:
    """The register and memory map of an IMM core with parameters ``params`` (a
    :class:`kfgen.hdl.imm.params.ImmParams`).

    Raises
    ------
    ParamError
        ``address_width`` when ``params.address_width`` is too narrow for the map.
    """
    return place_map(_registers(params), regions(params), params.fmt, params.address_width)
