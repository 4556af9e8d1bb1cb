"""docs/engine-core.md builds what it says: its code blocks, written out as two packages (the
core's ``hdl`` package and its ``sim`` package), are a core on the engine that imports only the
shared layers, generates, whose golden model gives numpy's answer, and whose testbench passes
on the generated Verilog in Verilator."""

import ast
import importlib
import re
import sys
from pathlib import Path

import numpy as np
import pytest

import kfgen.gen.cores as cores
from helpers import EVERY_ELABORATABLE_USED, VERILATOR_CACHE
from kfgen.gen.output import generate, write_files
from kfgen.sim.engine.run import build_core, run_tb

pytestmark = EVERY_ELABORATABLE_USED

PAGE = Path(__file__).resolve().parents[2] / "docs" / "engine-core.md"
#: The page's packages -> the names they are written out under (no clash with an installed name).
PACKAGES = {"kfgen.hdl.propagate": "propagate_doc_core", "kfgen.sim.propagate": "propagate_doc_sim"}
#: What a core's packages may import of kfgen besides their own: the shared layers.
SHARED = ("kfgen.hdl.arith", "kfgen.hdl.bus", "kfgen.hdl.describe", "kfgen.hdl.engine", "kfgen.hdl.linalg",
          "kfgen.sim.engine", "kfgen.sim.linalg")


def _blocks() -> list[tuple[str, str, str]]:
    """(top, module, text) of each of the page's code blocks headed ``# hdl/propagate/X.py``
    or ``# sim/propagate/X.py``."""
    return re.findall(r"```python\n# (hdl|sim)/propagate/(\w+)\.py\n(.*?)```", PAGE.read_text(), re.S)


@pytest.fixture(scope="module")
def page(tmp_path_factory):
    """The page's modules, imported from the packages written out: ``{"params": module, ...}``."""
    blocks = _blocks()
    assert [(top, name) for top, name, _ in blocks] == [
        ("hdl", "params"), ("hdl", "programs"), ("hdl", "steps"), ("hdl", "regmap"), ("hdl", "core"),
        ("hdl", "descriptor"), ("sim", "golden"), ("sim", "tb"), ("sim", "smoke")]
    root = tmp_path_factory.mktemp("doc")
    for package in PACKAGES.values():
        (root / package).mkdir()
        (root / package / "__init__.py").write_text("")
    for top, name, text in blocks:
        for page_name, written in PACKAGES.items():
            text = text.replace(page_name, written)
        (root / PACKAGES[f"kfgen.{top}.propagate"] / f"{name}.py").write_text(text)
    sys.path.insert(0, str(root))
    try:
        yield {name: importlib.import_module(f"{PACKAGES[f'kfgen.{top}.propagate']}.{name}")
               for top, name, _ in blocks}
    finally:
        sys.path.remove(str(root))
        for mod in [m for m in sys.modules if m.partition(".")[0] in PACKAGES.values()]:
            del sys.modules[mod]


def test_the_page_core_imports_only_the_shared_layers():
    """Every import of kfgen in the page's blocks is of the core's own packages or of a shared
    layer: no other core, no ``gen``; the ``hdl`` blocks import no ``sim``."""
    for top, name, text in _blocks():
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.ImportFrom) and node.level == 0:
                modules = [node.module]
            elif isinstance(node, ast.Import):
                modules = [alias.name for alias in node.names]
            else:
                continue
            for module in modules:
                if not module.startswith("kfgen"):
                    continue
                own = tuple(p for p in PACKAGES if top == "sim" or p.startswith("kfgen.hdl"))
                assert any(module == p or module.startswith(p + ".")
                           for p in own + tuple(s for s in SHARED if top == "sim" or s.startswith("kfgen.hdl"))), \
                    f"{top}/propagate/{name}.py imports {module}"




def test_the_page_golden_model_matches_numpy(page):
    params = page["params"].PropagateParams(states=3)
    rng = np.random.default_rng(3)
    A = rng.normal(size=(3, 3))
    values = {"x": rng.normal(size=3), "P": A @ A.T + np.eye(3), "F": np.eye(3) + 0.1 * rng.normal(size=(3, 3)),
              "Q": 0.01 * np.eye(3)}
    out, status = page["golden"].predict(params, values)
    assert not (status.pivot or status.nan)
    F, P, Q = values["F"], values["P"], values["Q"]
    assert np.allclose(out["x"].ravel(), F @ values["x"], rtol=1e-5)
    assert np.allclose(out["P"], F @ P @ F.T + Q, rtol=1e-5) and (out["P"] == out["P"].T).all()


def _hook_line() -> str:
    """The page's line for ``_HOOKS`` in gen/cores.py (the page's packages by their written names)."""
    (line,) = re.findall(r'^"propagate": \{.*\},$', PAGE.read_text(), re.M)
    for page_name, written in PACKAGES.items():
        line = line.replace(page_name, written)
    return line


def _bound(page, monkeypatch):
    """The page's descriptor with its ``_HOOKS`` line bound."""
    hooks = eval("{" + _hook_line() + "}", {**vars(cores), "propagate_map": page["regmap"].propagate_map})
    monkeypatch.setitem(cores._HOOKS, "propagate", hooks["propagate"])
    monkeypatch.setattr(cores, "_BOUND", {})
    return page["descriptor"].CORE


def test_the_page_core_generates(page, monkeypatch):
    """With the page's hooks, the core generates, and writes TOP_tb.v and the vectors of the
    page's session: two starts at the manifest's cycles, the reads of x and P."""
    files = generate(_bound(page, monkeypatch), page["params"].PropagateParams(states=3, pes=2))
    assert "module propagate(" in files["propagate.v"] and '"predict"' in files["propagate.json"]
    cycles = re.search(r'"predict": (\d+)', files["propagate.json"]).group(1)
    ops = [line.split() for line in files["propagate_vectors.hex"].splitlines() if not line.startswith("//")]
    assert [op[3] for op in ops if op[0] == "3"] == [f"{int(cycles):08x}"] * 2
    assert sum(op[0] == "2" for op in ops) == 2 + 1 + 2 * (2 + 3 + 9)  # ID, IRQ_ENABLE; STATUS x2, x, P
    assert "module propagate_tb;" in files["propagate_tb.v"]


@pytest.mark.full  # a Verilator build of its own; make test generates the core and runs its golden model
@pytest.mark.verilator
def test_the_page_testbench_passes(page, tmp_path, monkeypatch):
    """The page's ``_HOOKS`` line bound, the core generated, built on Verilator and its
    testbench run."""
    params = page["params"].PropagateParams(states=3, pes=2)
    write_files(tmp_path, generate(_bound(page, monkeypatch), params))
    model = build_core(tmp_path, "propagate", VERILATOR_CACHE)
    run_tb(model, tmp_path, "propagate", page["tb"].__name__, ["steps"], "steps")
