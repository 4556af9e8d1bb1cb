"""``python -m kfgen.gen.cosim ekf``: the refusals before anything is generated (exit 2, one
line), and a numerical fault at run time (exit 3, one line)."""

import pytest

from kfgen.gen.cosim import main

#: A square root of a state that the first update drives negative: h and H are NaN from the
#: second iteration on (err_nan, and S's pivot NaN: err_pivot).
SINKING = '''
import numpy as np
from kfgen.hdl.engine.app import UkfApplication
from kfgen.sim.ukf.app import Scenario


class Sinking(UkfApplication):
    n, nw, nv, m = 1, 1, 1, 1
    dt = 1.0
    x0 = np.array([1.0])
    P0 = np.eye(1)
    Q = np.eye(1) * 1e-4
    R = np.eye(1) * 1e-2

    def f(self, x, w, u, dt):
        return x + w

    def h(self, x, v):
        return np.sqrt(x) + v

    def scenario(self, steps, seed):
        t = np.arange(1, steps + 1) * self.dt
        return Scenario(t, np.ones((steps, 1)), None, np.full((steps, 1), -3.0))
'''


@pytest.mark.parametrize("args,says", [
    (["--app", "nowhere:Nothing"], "cosim: error: cannot import 'nowhere'"),
    (["--app", "tracker:Tracker", "--steps", "0"], "cosim: error: --steps must be a positive integer"),
    (["--app", "tracker:Tracker", "--pes", "0"], "cosim: error: pes: "),
    ([], "cosim: error: the following arguments are required: --app"),
])
def test_refused_before_generation(tmp_path, capsys, args, says):
    try:
        rc = main(["ekf", *args, "-o", str(tmp_path / "w")])
    except SystemExit as exc:  # argparse's refusal
        rc = exc.code
    assert rc == 2
    err = capsys.readouterr().err
    assert err.startswith(says) and err.count("\n") == 1, err
    assert not (tmp_path / "w").exists()


@pytest.mark.full
@pytest.mark.verilator
def test_runtime_fault_exits_3(tmp_path, capsys):
    (tmp_path / "sinking.py").write_text(SINKING)
    assert main(["ekf", "--app", f"{tmp_path / 'sinking.py'}:Sinking", "--steps", "3",
                 "-o", str(tmp_path / "w")]) == 3
    err = capsys.readouterr().err
    assert err.startswith("cosim: error: the core raised a numerical fault at iteration 1 (err_pivot") \
        and err.count("\n") == 1, err
