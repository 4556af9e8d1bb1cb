"""Dependencies point down (ARCHITECTURE.md): ``hdl`` imports neither ``gen`` nor ``sim``,
not even inside a function, and the engine layer and a core on it never import another
core's package."""

import ast
from pathlib import Path

import pytest

import kfgen.hdl

HDL = Path(kfgen.hdl.__file__).parent


def imports(path: Path) -> list[tuple[int, str]]:
    """(line, absolute module name) of every import statement in ``path``, at any depth."""
    package = ["kfgen", "hdl", *path.relative_to(HDL).parent.parts]
    out = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = package[:len(package) - node.level + 1] if node.level else []
            name = ".".join(base + ([node.module] if node.module else []))
            out += [(node.lineno, f"{name}.{alias.name}" if not node.module else name) for alias in node.names]
    return out


def offending(path: Path, forbidden: tuple[str, ...]) -> list[str]:
    return [f"{path.relative_to(HDL.parent)}:{line}: {name}" for line, name in imports(path)
            if any(name == f or name.startswith(f + ".") for f in forbidden)]


def test_hdl_imports_neither_gen_nor_sim():
    bad = [hit for path in sorted(HDL.rglob("*.py")) for hit in offending(path, ("kfgen.gen", "kfgen.sim"))]
    assert not bad, "hdl imports gen or sim:\n" + "\n".join(bad)


@pytest.mark.parametrize("package", ["engine", "linalg", "imm"])
def test_engine_layer_and_its_cores_import_no_other_core(package):
    """The engine layer (hdl/engine, hdl/linalg) and a core on it (the IMM) import no core's
    package but their own: a fifth core needs only the engine layer."""
    others = tuple(f"kfgen.hdl.{core}" for core in ("ukf", "imm", "castella") if core != package)
    bad = [hit for path in sorted((HDL / package).rglob("*.py")) for hit in offending(path, others)]
    assert not bad, "\n".join(bad)


def test_the_scan_sees_function_level_and_relative_imports(tmp_path, monkeypatch):
    """The scan would catch a lazy import inside a function, absolute or relative."""
    pkg = tmp_path / "hdl" / "core"
    pkg.mkdir(parents=True)
    (pkg / "descriptor.py").write_text("def f():\n    from kfgen.sim.x import y\n    from ...gen import cli\n")
    monkeypatch.setattr(__import__(__name__), "HDL", tmp_path / "hdl")
    assert offending(pkg / "descriptor.py", ("kfgen.gen", "kfgen.sim")) == [
        "hdl/core/descriptor.py:2: kfgen.sim.x", "hdl/core/descriptor.py:3: kfgen.gen"]


def _module_imports(path: Path, package: list[str]) -> list[tuple[int, str]]:
    """(line, absolute module name) of every import in ``path``, a module of ``package`` (its
    dotted parts), at any depth; a name imported from a package counts as a module of it."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = ".".join((package[:len(package) - node.level + 1] if node.level else [])
                            + ([node.module] if node.module else []))
            out += [(node.lineno, f"{base}.{alias.name}") for alias in node.names]
    return out


def test_no_core_simulates_or_tests_with_another_cores_package():
    """A core's simulation (``sim/<core>``) and tests (``tests/<core>``) import no other core's
    sim or tests package: what two cores share lives in a shared layer (``sim/engine``, the
    engine's harness and Verilator runs). The cores are found, not listed: every package of
    ``hdl`` whose descriptor module defines ``CORE``."""
    import kfgen.sim

    sim, tests = Path(kfgen.sim.__file__).parent, Path(__file__).parents[1]
    cores = sorted(p.parent.name for p in HDL.glob("*/descriptor.py")
                   if any(isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "CORE" for t in node.targets)
                          for node in ast.parse(p.read_text()).body))
    assert {"ukf", "imm"} <= set(cores), cores

    def owner(name: str) -> str | None:
        """The core whose sim or tests package ``name`` (a module) belongs to, if any."""
        parts = name.split(".")
        if parts[:2] == ["kfgen", "sim"] and len(parts) > 2 and parts[2] in cores:
            return parts[2]
        if parts[0] == "tests" and len(parts) > 1 and parts[1] in cores:
            return parts[1]
        return next((c for c in cores if (tests / c / f"{parts[0]}.py").is_file()), None)  # a test module

    bad = []
    for core in cores:
        for root, package in ((sim / core, ["kfgen", "sim", core]), (tests / core, ["tests", core])):
            for path in sorted(root.rglob("*.py")):
                pkg = package + list(path.relative_to(root).parent.parts)
                bad += [f"{path.relative_to(root.parents[1])}:{line}: {name}"
                        for line, name in _module_imports(path, pkg) if owner(name) not in (None, core)]
    assert not bad, "a core's sim or tests import another core's:\n" + "\n".join(bad)


def test_sim_imports_no_gen():
    """Dependencies point gen -> sim -> hdl: sim imports no gen module, not even inside a
    function (a command that generates and then simulates is gen's, :mod:`kfgen.gen.cosim`)."""
    import kfgen.sim

    sim = Path(kfgen.sim.__file__).parent
    bad = [f"{path.relative_to(sim.parent)}:{line}: {name}" for path in sorted(sim.rglob("*.py"))
           for line, name in _module_imports(path, ["kfgen", "sim", *path.relative_to(sim).parent.parts])
           if name == "kfgen.gen" or name.startswith("kfgen.gen.")]
    assert not bad, "sim imports gen:\n" + "\n".join(bad)
