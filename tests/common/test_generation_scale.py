"""Generation scales: every engine core the CLI accepts generates in 60 s and 2 GB, and what
would not is refused at validation, at once, with exit 2 (issue 19)."""

import time

import pytest

from kfgen.gen.bench_gen import LIMIT_MB, LIMIT_SECONDS, measure
from kfgen.hdl.describe import ParamError
from kfgen.hdl.imm.params import ImmParams
from kfgen.hdl.engine.params import GEN_CROSSBAR_MAX, GEN_PES_MAX
from kfgen.hdl.ukf.params import UkfParams

from helpers import kfgen_in_process

# (arguments, what the one error line must say)
REFUSED = [
    (["imm", "--models", "2", "--pes", "64"], f"--pes: at most {GEN_PES_MAX}, not 64"),
    (["imm", "--pes", "9"], f"P x banks must be at most {GEN_CROSSBAR_MAX} (P <= 8 with the default banks"),
    (["imm", "--pes", "4", "--banks", "33"], "4 x 33 crossbar"),
    (["ukf", "--pes", "17"], f"--pes: at most {GEN_PES_MAX}, not 17"),
    (["ukf", "--pes", "16", "--banks", "9"], "16 x 9 crossbar"),
]


@pytest.mark.parametrize("argv,says", REFUSED, ids=[" ".join(a) for a, _ in REFUSED])
def test_refused_at_once(tmp_path, monkeypatch, argv, says):
    # Structurally before any build: the cores' constructors must never be reached.
    import kfgen.hdl.imm.core as imm_core
    import kfgen.hdl.ukf.core as ukf_core

    def no_build(*a, **k):
        raise AssertionError("a refused configuration reached the build")

    monkeypatch.setattr(imm_core, "Imm", no_build)
    monkeypatch.setattr(ukf_core, "Ukf", no_build)
    t0 = time.monotonic()
    proc = kfgen_in_process(*argv, "-o", tmp_path)
    assert time.monotonic() - t0 < 5
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("kfgen: error: --pes: ") and says in lines[0], proc.stderr
    assert "60 s or 2 GB" in lines[0]
    assert not any(tmp_path.iterdir())


def test_params_refuse_and_accept_at_the_limits():
    with pytest.raises(ParamError, match="at most 16"):
        ImmParams(models=2, pes=64)
    with pytest.raises(ParamError, match="crossbar"):
        ImmParams(pes=9)
    with pytest.raises(ParamError, match="crossbar"):
        UkfParams(pes=16, banks=9)
    # the largest accepted: P x banks sits exactly on the limit
    assert ImmParams(pes=8).banks * 8 == GEN_CROSSBAR_MAX
    assert ImmParams(pes=16, banks=8).banks * 16 == GEN_CROSSBAR_MAX
    assert UkfParams(pes=16).banks * 16 == GEN_CROSSBAR_MAX


def test_bench_measures_a_refusal_as_a_subprocess(tmp_path):
    r = measure(["imm", "--pes", "64"], str(tmp_path / "out"))
    assert r["code"] == 2 and "--pes: at most" in r["error"] and r["seconds"] < 30 and r["mb"] > 10


# The largest accepted configurations: the defaults' sizes at the most PEs the limits let through.
LARGEST = [
    ["ukf", "--pes", "16"],
    ["imm", "--pes", "8"],
    ["imm", "--pes", "16", "--banks", "8"],
]


@pytest.mark.full
@pytest.mark.parametrize("argv", LARGEST, ids=[" ".join(a) for a in LARGEST])
def test_largest_accepted_generates_within_the_limits(tmp_path, argv):
    r = measure(argv, str(tmp_path / "out"))
    assert r["code"] == 0, r["error"]
    assert r["seconds"] < LIMIT_SECONDS and r["mb"] < LIMIT_MB, r
