"""Vectors of the Schur-complement unit's smoke testbench (``TOP_tb.v``): the status cases (a
zero or negative pivot, NaN, infinity) and positive-definite matrices, their inverses and
status words from the bit-exact golden model."""

from __future__ import annotations

import numpy as np

from kfgen.hdl.schur.program import schur_program

from .model import golden_many, stimulus

__all__ = ["smoke_plan"]

#: Matrices in the smoke test.
COUNT = 16


def _pack(words: list[int], width: int) -> int:
    return sum(w << (k * width) for k, w in enumerate(words))


def smoke_plan(params, manifest: dict) -> dict:
    """A ``stream`` plan (:mod:`kfgen.gen.smoke`) of ``COUNT`` matrices and their results."""
    fmt = params.fmt
    matrices = stimulus(fmt, params.d, COUNT, np.random.default_rng(1))[:COUNT]
    results, status = golden_many(schur_program(params.d), fmt, matrices)
    return {
        "kind": "stream",
        "about": f"{len(matrices)} {params.d}x{params.d} matrices in {fmt.name} against the bit-exact golden model",
        "inputs": {"valid": "s_axis_tvalid", "ready": "s_axis_tready", "ports": ["s_axis_tdata"],
                   "words": [[_pack(m, fmt.width)] for m in matrices]},
        "outputs": {"valid": "m_axis_tvalid", "ready": "m_axis_tready", "ports": ["m_axis_tdata", "m_axis_tuser"],
                    "words": [[_pack(r, fmt.width), s.word] for r, s in zip(results, status)]},
    }
