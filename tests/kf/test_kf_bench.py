"""``python -m kfgen.gen.bench_kf``: the cycles table of docs/kf.md, each row the manifest's
count (the schedule and the engine's overhead)."""

import pytest

from kfgen.gen.bench_kf import CONFIGS, main, row
from kfgen.hdl.kf.params import KfParams
from kfgen.hdl.kf.steps import schedules
from kfgen.hdl.linalg.engine import OVERHEAD


def test_small_rows_are_the_manifests(capsys):
    """``--small`` (n = 4): each row's cycles are the core's own schedule's, as the manifest's."""
    assert main(["--small"]) == 0
    out = capsys.readouterr().out
    for n, m, nu, pes, steady in CONFIGS:
        if n == 4:
            want = schedules(KfParams(states=n, measurements=m, inputs=nu, pes=pes))["iterate"].cycles + OVERHEAD
            assert row(n, m, nu, pes)["cycles"] == want
            assert f"| {n} | {m} | {nu} | {pes} | Joseph | {want:,} |" in out


@pytest.mark.full
def test_bench_prints_the_table(capsys):
    """The docs' command: every row, n = 16 at P = 4 at least 10x Vitis' 0.55 ms with m = 2
    at the engine's Fmax, m = nu = 16 marked as not generated."""
    assert main([]) == 0
    out = capsys.readouterr().out
    assert "| 16 | 2 | 1 | 4 | Joseph | 4,239 |" in out and "(not generated)" in out
    assert row(16, 2, 1, 4)["cycles"] / 95.8 * 10 <= 550
