"""docs/ekf.md's tables are what ``python -m kfgen.gen.bench_ekf`` prints (the cycles of the
EKF and the UKF's on-chip iteration, the Jacobians' multiply-adds), and the accuracy run's task
runs (one seed of the tracker; the 100-seed run is the docs' command, not the regression's)."""

import numpy as np

from kfgen.gen.bench_ekf import FILTERS, accuracy_block, cycles_rows, jacobian_rows

from helpers import ROOT


def test_the_docs_tables_are_the_bench():
    text = (ROOT / "docs" / "ekf.md").read_text()
    for r in cycles_rows((1, 2)):
        assert r["ratio"] <= 0.5, r  # issue 35's goal
        line = (f"| {r['app']} | {r['pes']} | {r['ekf']} | {r['ukf']} | {r['ratio']:.2f} | {r['ekf_fma']} | "
                f"{r['ukf_fma']} |")
        assert line in text, line
    for r in jacobian_rows():
        line = (f"| {r['app']} | {r['jacobian']} | {r['shape']} | {r['nonzero']} | {r['constant']} | {r['dense']} | "
                f"{r['sparse']} |")
        assert line in text, line


def test_accuracy_block_runs():
    out = accuracy_block("tracker", 0, 1)
    assert out["ekf_b32_faults"] == out["ukf_b32_faults"] == 0
    figures = np.array([out[k][0] for k in FILTERS])
    assert np.all(np.isfinite(figures)) and np.all(figures < 50), figures


def test_the_docs_map_is_the_tracker_cores():
    from kfgen.hdl.ekf.params import EkfParams
    from kfgen.hdl.ekf.regmap import ekf_map

    text = (ROOT / "docs" / "ekf.md").read_text()
    rmap = ekf_map(EkfParams("tracker:Tracker"))
    offsets = {m.name: m.offset for m in rmap.memories}
    assert f"({2 ** rmap.address_width}\nbytes, the buffer from {rmap.buffer_base:#x}" in text
    assert f"| `x` | {offsets['x']:#X} |".replace("0X", "0x") in text
    assert f"| `Q`, `R` | {offsets['Q']:#X}, {offsets['R']:#X} |".replace("0X", "0x") in text
    assert f"| `z` | {offsets['z']:#X} |".replace("0X", "0x") in text


def test_the_pendulum_figures():
    from kfgen.hdl.ekf.params import EkfParams
    from kfgen.hdl.ekf.steps import schedules
    from kfgen.hdl.linalg.engine import OVERHEAD
    from kfgen.hdl.linalg.schedule import chain_bound

    text = " ".join((ROOT / "docs" / "ekf.md").read_text().split())
    p = EkfParams(f"{ROOT / 'docs' / 'examples' / 'pendulum.py'}:Pendulum")
    sched = schedules(p)["iterate"]
    assert f"`cycles.iterate` is {sched.cycles + OVERHEAD} at P = 1, of which {sched.program.fma_count} " \
           "multiply-adds" in text
    assert f"`bounds.chain` {chain_bound(sched.program, sched.machine)}" in text
    jac = {j.name: j for j in p.models.jacobians.values()}
    assert (len(jac["F"].entries), jac["F"].constants, jac["F"].sparse) == (4, 3, 1)
    assert jac["H"].pattern.tolist() == [[True, False]] and jac["H"].sparse == 0
