"""``kfgen kf`` at the command line: every bad value one line on stderr and exit 2, before
anything is written; a steady-gain core's manifest (its prologue and steps) and map."""

import json

import pytest

from helpers import kfgen_in_process


@pytest.mark.parametrize("args,says", [
    (["--states", "0"], "--states: "),
    (["--states", "256"], "--states: "),
    (["--states", "40"], "--states: "),
    (["--measurements", "0"], "--measurements: "),
    (["--inputs", "-1"], "--inputs: "),
    (["--pes", "0"], "--pes: "),
    (["--pes", "17"], "--pes: "),
    (["--banks", "1"], "--banks: "),
    (["--div-sqrt", "fast"], "--div-sqrt: "),
    (["--format", "binary128"], "--format: "),
    (["--address-width", "5"], "--address-width: "),
    (["--address-width", "33"], "--address-width: "),
    (["--target-mhz", "-5"], "--target-mhz: "),
    (["--name", "module"], "--name: "),
    (["--states", "four"], ""),
])
def test_bad_values_exit_2(tmp_path, args, says):
    proc = kfgen_in_process("kf", *args, "-o", tmp_path / "x")
    assert proc.returncode == 2 and proc.stderr.startswith(f"kfgen: error: {says}"), proc.stderr
    assert proc.stderr.count("\n") == 1 and not (tmp_path / "x").exists()


def test_steady_gain_manifest(tmp_path):
    """K in the buffer instead of P, Q, R; CTRL.step names iterate and gain; gain is
    iterate's prologue after writes of F, B, H or K."""
    proc = kfgen_in_process("kf", "--states", "3", "--measurements", "1", "--inputs", "1", "--steady-gain",
                            "--name", "kfs", "-o", tmp_path)
    assert proc.returncode == 0, proc.stderr
    man = json.loads((tmp_path / "kfs.json").read_text())
    assert [m["name"] for m in man["memories"]] == ["x", "F", "B", "H", "z", "u", "K"]
    step = next(f for f in man["registers"][1]["fields"] if f["name"] == "step")
    assert step["values"] == {"iterate": 0, "gain": 1}
    assert man["prologue"]["step"] == "gain" and man["prologue"]["after_writes_to"] == ["F", "B", "H", "K"]
    assert set(man["cycles"]) == set(man["cycles_keys"]) == {"iterate", "gain"}
    assert man["bounds"]["fma"] == 3 * (3 + 1 + 1)
