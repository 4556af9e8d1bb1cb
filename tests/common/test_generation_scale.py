"""Generation scales: every engine core the CLI accepts generates in 60 s and 2 GB, and what
would not is refused at validation, at once, with exit 2 (issue 19)."""

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
    # sizes: refused from a lower bound on the programs' multiply-adds, before they are built
    (["ukf", "--states", "255"], "--states: these sizes' programs hold at least 3,208,138 multiply-adds"),
    (["imm", "--models", "255", "--states", "255"], "--states: these sizes' programs hold at least"),
    (["imm", "--models", "7", "--states", "9", "--pes", "16", "--banks", "8"],
     "--pes: these sizes' programs hold at least 10,206 multiply-adds: at P = 16"),
]


def _refused_before(monkeypatch, tmp_path, argv, says, stage, modules, names):
    """``kfgen ARGV`` exits 2 with one line saying ``says`` and writes nothing, without ever
    reaching ``stage``: each of ``names`` in ``modules`` replaced by a function that fails."""
    def reached(*a, **k):
        raise AssertionError(f"a refused configuration reached the {stage}")

    for module, name in zip(modules, names):
        monkeypatch.setattr(module, name, reached)
    proc = kfgen_in_process(*argv, "-o", tmp_path)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("kfgen: error: --") and says in lines[0], proc.stderr
    assert "60 s or 2 GB" in lines[0]
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize("argv,says", REFUSED, ids=[" ".join(a) for a, _ in REFUSED])
def test_refused_at_once(tmp_path, monkeypatch, argv, says):
    # Structurally before any build: the cores' constructors must never be reached.
    import kfgen.hdl.imm.core as imm_core
    import kfgen.hdl.ukf.core as ukf_core

    _refused_before(monkeypatch, tmp_path, argv, says, "build", (imm_core, ukf_core), ("Imm", "Ukf"))


# Sizes whose lower bound passes but whose programs, counted exactly, do not: refused after
# the programs are built (a tenth of a second) and before the scheduler runs.
REFUSED_EXACT = [
    (["ukf", "--states", "13", "--observations", "12", "--process-noise", "13", "--measurement-noise", "12"],
     "--states: these sizes' programs hold 20,591 multiply-adds, more than generates"),
    (["imm", "--models", "7", "--states", "9", "--pes", "5"],
     "--pes: these sizes' programs hold 17,894 multiply-adds: at P = 5 that is more than generates "
     "(multiply-adds x max(4, P) / 4 must be at most 20,000: P <= 4 for these sizes"),
]


@pytest.mark.parametrize("argv,says", REFUSED_EXACT, ids=[" ".join(a) for a, _ in REFUSED_EXACT])
def test_refused_before_scheduling(tmp_path, monkeypatch, argv, says):
    import kfgen.hdl.imm.steps as imm_steps
    import kfgen.hdl.ukf.steps as ukf_steps

    _refused_before(monkeypatch, tmp_path, argv, says, "scheduler", (imm_steps, ukf_steps),
                    ("engine_schedules", "engine_schedules"))


# (core, sizes) over a grid of small shapes: the lower bound the parameters check before any
# program is built never exceeds the programs' exact multiply-adds, so it refuses nothing the
# exact count would let through.
def _fma(progs):
    return sum(prog.fma_count for prog in progs.steps.values())


@pytest.mark.parametrize("n,m", [(1, 1), (2, 8), (5, 3), (8, 16), (12, 2)])
def test_ukf_lower_bound_is_below_the_count(n, m):
    from kfgen.hdl.ukf.steps import programs
    for nw in (1, n, 2 * n):
        for nv in (1, m):
            p = UkfParams(states=n, observations=m, process_noise=nw, measurement_noise=nv)
            assert max(p.M ** 3, p.m ** 3) // 6 <= _fma(programs(p)), (n, m, nw, nv)


@pytest.mark.parametrize("models", [2, 3, 8])
def test_imm_lower_bound_is_below_the_count(models):
    from kfgen.hdl.imm.steps import programs
    for n in (1, 2, 5, 9):
        for d in (1, 2, 8):
            p = ImmParams(models=models, states=n, measurements=d)
            assert 2 * p.R * p.n ** 3 <= _fma(programs(p)), (models, n, d)


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
    ["imm", "--pes", "16", "--banks", "8", "--format", "binary64"],
    # the largest programs, near the multiply-add limit
    ["ukf", "--states", "12", "--observations", "12", "--process-noise", "12", "--measurement-noise", "12"],
    ["imm", "--models", "7", "--states", "9", "--pes", "4"],
]


@pytest.mark.full
@pytest.mark.parametrize("argv", LARGEST, ids=[" ".join(a) for a in LARGEST])
def test_largest_accepted_generates_within_the_limits(tmp_path, argv):
    r = measure(argv, str(tmp_path / "out"))
    assert r["code"] == 0, r["error"]
    assert r["seconds"] < LIMIT_SECONDS and r["mb"] < LIMIT_MB, r
