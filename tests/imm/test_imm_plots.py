"""``make plots``'s IMM figures on a short run, with one more trace as a co-simulation of the
core would bring it."""

from __future__ import annotations

import numpy as np
import pytest

from kfgen.sim.imm import plots
from kfgen.sim.imm.reference import run_reference
from kfgen.sim.imm.scenario import satlink

PNG = b"\x89PNG\r\n\x1a\n"


def test_figures_with_an_extra_trace(tmp_path, capsys):
    sc = satlink(120, 5)
    ref = run_reference(sc.system, sc.mu0, sc.xs0, sc.Ps0, sc.zs)
    np.savez(tmp_path / "more.npz", **{"RTL core:mu": ref.mu, "RTL core:x": ref.x + 0.01})
    plots.main(["-o", str(tmp_path / "fig"), "--steps", "120", "--seed", "5",
                "--traces", str(tmp_path / "more.npz")])
    for name in ("imm_probabilities.png", "imm_snr.png"):
        assert (tmp_path / "fig" / name).read_bytes()[:8] == PNG
    out = capsys.readouterr().out
    assert "identification:" in out
    rows = {line[:26].strip(): line[26:].split() for line in out.splitlines()}
    for name in ("float64 IMM", "clear sky", "multipath fading", "RTL core", "measurements"):
        assert name in rows, name
    # the extra trace is the reference shifted by 0.01 dB, and its error says so
    assert float(rows["RTL core"][0]) != float(rows["float64 IMM"][0])


def test_bad_traces(tmp_path):
    with pytest.raises(ValueError, match=r"trace 'x': mu must be of shape \(30, 5\)"):
        plots.figures(tmp_path, 30, extra={"x": (np.zeros((29, 5)), np.zeros((30, 6)))})
    np.savez(tmp_path / "half.npz", **{"core:mu": np.zeros((30, 5))})
    with pytest.raises(ValueError, match="missing \\['core:x'\\]"):
        plots.main(["-o", str(tmp_path), "--steps", "30", "--traces", str(tmp_path / "half.npz")])
