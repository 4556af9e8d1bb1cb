"""docs/engine-core.md builds what it says: its code blocks, written out as a package, are a
core on the engine that generates, whose program the golden model runs to numpy's answer,
and that imports the engine layer only."""

import importlib
import re
import sys
from pathlib import Path

import numpy as np
import pytest

from kfgen.gen.cli import generate
from kfgen.sim.linalg.exec import from_words, run, to_words

PAGE = Path(__file__).resolve().parents[2] / "docs" / "engine-core.md"
PACKAGE = "kf_doc_core"  # no clash with an installed name


@pytest.fixture(scope="module")
def kf(tmp_path_factory):
    blocks = re.findall(r"```python\n# hdl/kf/(\w+)\.py\n(.*?)```", PAGE.read_text(), re.S)
    assert [name for name, _ in blocks] == ["params", "programs", "steps", "regmap", "core", "descriptor"]
    root = tmp_path_factory.mktemp("doc")
    (root / PACKAGE).mkdir()
    (root / PACKAGE / "__init__.py").write_text("")
    for name, text in blocks:
        assert "kfgen.hdl.ukf" not in text and "kfgen.hdl.imm" not in text, name
        (root / PACKAGE / f"{name}.py").write_text(text)
    sys.path.insert(0, str(root))
    try:
        yield {name: importlib.import_module(f"{PACKAGE}.{name}") for name, _ in blocks}
    finally:
        sys.path.remove(str(root))
        for mod in [m for m in sys.modules if m == PACKAGE or m.startswith(PACKAGE + ".")]:
            del sys.modules[mod]


def test_the_page_core_generates(kf):
    params = kf["params"].KfParams(states=3, pes=2)
    files = generate(kf["descriptor"].CORE, params)
    assert "module kf(" in files["kf.v"] and '"predict"' in files["kf.json"]


def test_the_page_program_matches_numpy(kf):
    params = kf["params"].KfParams(states=3)
    progs = kf["programs"].build_kf(params)
    lay, fmt = progs.layout, params.fmt
    rng = np.random.default_rng(3)
    A = rng.normal(size=(3, 3))
    val = {"x": rng.normal(size=3), "P": A @ A.T + np.eye(3), "F": np.eye(3) + 0.1 * rng.normal(size=(3, 3)),
           "Q": 0.01 * np.eye(3)}
    mem = lay.initial_memory()
    for name, v in val.items():
        reg = lay[name]
        mem[reg.base:reg.base + reg.size] = to_words(fmt, np.ravel(v))
    st = run(progs.predict, mem)
    assert not (st.pivot or st.nan)
    out = {k: np.array(from_words(fmt, mem[lay[k].base:lay[k].base + lay[k].size])) for k in ("x", "P")}
    F, P, Q = val["F"], val["P"], val["Q"]
    assert np.allclose(out["x"], F @ val["x"], rtol=1e-5)
    P1 = out["P"].reshape(3, 3)
    assert np.allclose(P1, F @ P @ F.T + Q, rtol=1e-5) and (P1 == P1.T).all()
