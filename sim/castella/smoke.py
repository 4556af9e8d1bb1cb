"""Vectors of the Castella core's smoke testbench (``TOP_tb.v``): a few measurements of two
tracks (a target closing in, one in a manoeuvre) through the fixed-point golden model."""

from __future__ import annotations

import numpy as np

from .model import expected_stream
from .scenarios import to_codes

__all__ = ["smoke_plan"]

#: Measurements per track: the first restarts the track, the second initialises it, the
#: rest track (every phase of the filter, and q rising in the manoeuvre).
STEPS = 8


def _pack(manifest: dict, port: str, values: dict) -> int:
    spec = next(p for p in manifest["ports"] if p["name"] == port)
    return sum((int(values[f["name"]]) & ((1 << f["width"]) - 1)) << f["lsb"] for f in spec["fields"])


def smoke_plan(params, manifest: dict) -> dict:
    """A ``stream`` plan (:mod:`kfgen.gen.smoke`) of ``STEPS`` measurements on each of up to two
    tracks, round robin, and the outputs the golden model gives for them."""
    tracks = min(2, params.tracks)
    t = np.arange(STEPS) * params.period
    paths = [3000.0 - 40.0 * t, 2000.0 + 25.0 * t + 60.0 * np.maximum(t - 3 * params.period, 0) ** 2]
    y = to_codes(params, np.array(paths[:tracks]))
    tids = [k % tracks for k in range(STEPS * tracks)]
    ys = [int(y[k % tracks, k // tracks]) for k in range(STEPS * tracks)]
    restarts = [k < tracks for k in range(STEPS * tracks)]
    rows, _ = expected_stream(params, tids, ys, restarts)
    return {
        "kind": "stream",
        "about": f"{len(ys)} measurements of {tracks} track(s) against the fixed-point golden model",
        "inputs": {"valid": "s_axis_tvalid", "ready": "s_axis_tready",
                   "ports": ["s_axis_tdata", "s_axis_tid", "s_axis_tuser"],
                   "words": [[_pack(manifest, "s_axis_tdata", {"range": yk}), tid,
                              _pack(manifest, "s_axis_tuser", {"restart": rs})]
                             for yk, tid, rs in zip(ys, tids, restarts)]},
        "outputs": {"valid": "m_axis_tvalid", "ready": "m_axis_tready",
                    "ports": ["m_axis_tdata", "m_axis_tid", "m_axis_tuser"],
                    "words": [[_pack(manifest, "m_axis_tdata", row), tid, _pack(manifest, "m_axis_tuser", row)]
                              for row, tid in zip(rows, tids)]},
    }
