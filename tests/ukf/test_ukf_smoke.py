"""The UKF's shipped-testbench plan (:mod:`kfgen.sim.ukf.smoke`) on the golden model alone: the
script replays on a fresh golden device to the same words, and a start's cycles count the
prologue it runs (the square-root form's noise before the first sig_gen)."""

import pytest

from kfgen.hdl.ukf.params import UkfParams
from kfgen.hdl.ukf.steps import programs
from kfgen.sim.engine.device import GoldenDevice
from kfgen.sim.engine.script import END, ITERATION, READ, START, WRITE
from kfgen.sim.ukf.smoke import ITERATIONS, smoke_plan

from helpers import python_driver

SMALL = dict(states=2, observations=1, process_noise=1, measurement_noise=1, pes=1, w0=0.25)


def replay(ops, man):
    """Every operation on a fresh golden device: each read the word the script expects."""
    dev = GoldenDevice(man, UkfParams, programs)
    for op, address, data, _, note in ops:
        if op in (WRITE, START):
            dev.write(address, data)
        elif op == READ:
            assert dev.read(address) == data, note
    return dev


@pytest.mark.parametrize("form", ["ldl", "sqrt"])
def test_plan_replays_and_counts_the_prologue(tmp_path, form):
    man, _ = python_driver(tmp_path, "ukf", name="ukf_plan", form=form, **SMALL)
    plan = smoke_plan(UkfParams(**man["parameters"]), man)
    ops = plan["ops"]
    assert ops[-1][:3] == (END, 0, len(ops) - 1)
    assert [op[3] for op in ops if op[0] == ITERATION] == list(range(ITERATIONS))
    cycles = man["cycles"]
    steps = [cycles["sig_gen"], cycles["predict"], cycles["update"]]
    want = steps * ITERATIONS
    if form == "sqrt":  # Q and R were written: the first sig_gen runs noise first
        want[0] += cycles["noise"]
    assert [op[3] for op in ops if op[0] == START] == want
    dev = replay(ops[:-1], man)
    assert dev.steps == ["sig_gen", "predict", "update"] * ITERATIONS
    # every read of the estimate is in the script: x and the covariance after each iteration
    region = {"ldl": "P", "sqrt": "sqrtP"}[form]
    assert sum(note.startswith(f"{region}[") and op == READ for op, _, _, _, note in ops) == ITERATIONS * 4
