"""The UKF's covariance forms, which its parameters check and its register map names (below
both, so neither imports the other)."""

from __future__ import annotations

__all__ = ["FORMS", "covariance_region"]

#: The covariance forms: ``ldl``, the chapter's (P in the buffer, factored by LDL^T each
#: sig_gen), and ``sqrt``, the square-root form (the Cholesky factor of P in the buffer,
#: kept by orthogonal transformations: :mod:`kfgen.hdl.ukf.programs`).
FORMS = ("ldl", "sqrt")


def covariance_region(form: str) -> str:
    """The buffer region of the state's covariance in ``form``: ``P``, or ``sqrtP`` (its
    Cholesky factor S, P = S S^T) in the square-root form."""
    return "sqrtP" if form == "sqrt" else "P"
