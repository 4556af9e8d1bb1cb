"""The formal proofs of ``make formal`` (:mod:`kfgen.gen.formal`): every proof passes (every
cover is reached), and every planted bug makes its proof fail at the property it breaks.

The fast set (BMC at small depths, the covers, a mutant of each kind) runs in ``make test``;
the k-induction, the deeper BMC and every mutant in ``make test-full``. Each run is one single-threaded
SymbiYosys process, so pytest-xdist spreads them."""

import pytest

from kfgen.gen import formal

PROOFS = {p.name: p for p in formal.proofs()}


def _param(p):
    return pytest.param(p.name, id=p.name, marks=[pytest.mark.full] if p.full else [])


@pytest.mark.parametrize("name", [_param(p) for p in formal.proofs()])
def test_proof(name, tmp_path):
    r = formal.run(PROOFS[name], tmp_path / name)
    assert r.status == "PASS", f"{name}: {r.status} {r.failed}\n{r.log[-3000:]}"


@pytest.mark.parametrize("mutant", [pytest.param(mu, id=mu.name, marks=[pytest.mark.full] if mu.full else [])
                                    for mu in formal.mutants()])
def test_mutant_is_caught(mutant, tmp_path):
    r = formal.run(PROOFS[mutant.proof], tmp_path / mutant.name, {mutant.module: formal.mutated(mutant)})
    assert r.status == "FAIL", f"{mutant.name}: the proof did not fail ({r.status})\n{r.log[-3000:]}"
    assert mutant.caught(r), f"{mutant.name}: failed elsewhere: {r.failed}"


def test_mutant_text_must_exist():
    """A mutant whose text is no longer in the design is an error, not a silent pass."""
    bad = formal.Mutant("gone", "kfgen.hdl.bus.axi4", "no such text", "x", "axi4_small_lat1", "")
    with pytest.raises(RuntimeError, match="must occur exactly once"):
        formal.mutated(bad)


def test_docs_name_every_proof_and_mutant():
    """docs/formal.md's tables list every proof (with its method and depth) and every mutant."""
    from helpers import ROOT

    text = (ROOT / "docs" / "formal.md").read_text()
    method = {"bmc": "BMC", "prove": "k-induction", "cover": "cover"}
    for p in formal.proofs():
        row = next((line for line in text.splitlines() if line.startswith(f"| `{p.name}` |")), None)
        assert row, f"docs/formal.md has no row for proof {p.name}"
        cells = [c.strip() for c in row.strip("|").split("|")]
        assert cells[3:6] == [method[p.mode], str(p.depth), "full" if p.full else "test"], (p.name, cells)
    for mu in formal.mutants():
        row = next((line for line in text.splitlines() if line.startswith(f"| `{mu.name}` |")), None)
        assert row and row.rstrip().endswith("| full |" if mu.full else "| test |"), (mu.name, row)
