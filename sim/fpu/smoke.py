"""Vectors of a floating-point unit's smoke testbench (``TOP_tb.v``): special and random
operands, results and flags from the exact reference (:mod:`kfgen.sim.float_ref`; ``exp``
from its bit-exact model, on inputs at the edges of its range; ``sin``, ``cos`` and ``atan2``
from theirs, on specials and random words)."""

from __future__ import annotations

import numpy as np

from kfgen.hdl.arith.float.format import FloatFormat

from ..float_ref import directed_corpus, random_operands, ref_op
from .exp_exact import directed_words
from .exp_model import exp_model
from .trig_model import trig_model

__all__ = ["smoke_plan"]

#: Operations of each kind in the smoke test.
DIRECTED, RANDOM = 8, 8


def smoke_plan(params, manifest: dict) -> dict:
    """A ``stream`` plan (:mod:`kfgen.gen.smoke`): ``DIRECTED`` special operand sets and
    ``RANDOM`` random ones, back to back, and the reference's word and flags for each."""
    fmt = FloatFormat.parse(params.format)
    ports = {p["name"] for p in manifest["ports"]}
    names = [k for k in ("i_a", "i_b", "i_c") if k in ports]
    if params.op == "exp":
        words = directed_words(fmt)
        sets = [(int(w),) for w in words[::max(1, len(words) // (DIRECTED + RANDOM))][:DIRECTED + RANDOM]]
        ys, flags = exp_model(fmt, [s[0] for s in sets], params.subnormals)
        results = [(int(y), int(f)) for y, f in zip(ys, flags)]
    elif params.op in ("sin", "cos", "atan2"):
        arity = len(names)
        special = [0, fmt.sign_mask, fmt.inf(0), fmt.canonical_nan, fmt.min_normal, fmt.max_finite,
                   fmt.pack(0, fmt.bias, 0), fmt.pack(1, fmt.bias + 1, 1)]
        rng = np.random.default_rng(1)
        words = special + [int(w) >> max(0, 62 - fmt.width) for w in rng.integers(0, 1 << 62, size=RANDOM)]
        sets = [tuple(int(words[(i + 3 * k) % len(words)]) for k in range(arity)) for i in range(len(words))]
        ys, flags = trig_model(params.op, fmt, [s[0] for s in sets],
                               [s[1] for s in sets] if arity == 2 else None, params.subnormals)
        results = [(int(y), int(f)) for y, f in zip(ys, flags)]
    else:
        corpus = directed_corpus(fmt, params.op)
        step = max(1, len(corpus) // DIRECTED)
        sets = corpus[::step][:DIRECTED] + random_operands(fmt, RANDOM, np.random.default_rng(1), params.op)
        results = [ref_op(params.op, fmt, *s, subnormals=params.subnormals) for s in sets]
    return {
        "kind": "stream",
        "about": f"{len(sets)} {params.op} operations in {fmt.name} against the exact reference",
        "inputs": {"valid": "i_valid", "ready": "i_ready" if "i_ready" in ports else None,
                   "ports": names, "words": [[int(w) for w in s] for s in sets]},
        "outputs": {"valid": "o_valid", "ready": None, "ports": ["o_y", "o_flags"],
                    "words": [[y, f] for y, f in results]},
    }
