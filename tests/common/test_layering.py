"""The layering of kfgen's packages (the folders of docs/development.md, "Layout"), every
import counted, at module level or inside a function:

- dependencies point down: ``hdl`` imports neither ``gen`` nor ``sim``, ``sim`` does not
  import ``gen``;
- no import circle anywhere: what two modules both need lives in a third below them;
- a core's package (every ``hdl`` package whose ``descriptor.py`` defines ``CORE``) is imported
  by no other package of ``hdl``, but for the building blocks :data:`BLOCKS` names with the
  reason: the engine layer (``hdl/engine``, ``hdl/linalg``) takes no core but those blocks,
  so a new core on it needs only it."""

import ast
from pathlib import Path

import pytest

import kfgen.hdl

HDL = Path(kfgen.hdl.__file__).parent

#: The top-level packages, each a folder beside ``hdl``.
TOPS = ("hdl", "gen", "sim")

#: The cores that other ``hdl`` packages may build on: imported module (a prefix) -> (the
#: importers, a prefix; why). Nothing else of a core's package is imported from outside it.
BLOCKS = {
    "kfgen.hdl.arith.float": (
        "kfgen.hdl", "the IEEE-754 units are the arithmetic layer under every floating-point "
        "block (the engine's units, the Schur unit); the fpu core is one of them alone"),
    "kfgen.hdl.schur.program": (
        "kfgen.hdl.imm", "the IMM inverts S by the Schur-complement unit's graph (paper 004), "
        "scheduled on the engine: the graph is pure Python, none of the Schur core's hardware, "
        "and one graph makes the two inversions the same"),
}


def _base(path: Path, node: ast.ImportFrom) -> str:
    """The absolute module name of ``from <module> import ...`` in ``path``."""
    package = ["kfgen", *path.relative_to(HDL.parent).parent.parts]
    base = package[:len(package) - node.level + 1] if node.level else []
    return ".".join(base + ([node.module] if node.module else []))


def imports(path: Path) -> list[tuple[int, str]]:
    """(line, absolute module name) of every import statement in ``path``, at any depth."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            name = _base(path, node)
            out += [(node.lineno, f"{name}.{alias.name}" if not node.module else name) for alias in node.names]
    return out


def offending(path: Path, forbidden: tuple[str, ...]) -> list[str]:
    return [f"{path.relative_to(HDL.parent)}:{line}: {name}" for line, name in imports(path)
            if any(name == f or name.startswith(f + ".") for f in forbidden)]


def _inside(name: str, package: str) -> bool:
    return name == package or name.startswith(package + ".")


def modules() -> dict[str, Path]:
    """Every module of kfgen by its name (a package by its ``__init__.py``)."""
    out = {}
    for top in TOPS:
        for path in sorted((HDL.parent / top).rglob("*.py")):
            parts = path.relative_to(HDL.parent).with_suffix("").parts
            out[".".join(["kfgen", *(parts[:-1] if parts[-1] == "__init__" else parts)])] = path
    return out


def import_graph() -> dict[str, set[str]]:
    """Module -> the kfgen modules it imports anywhere in its code: ``from p import m`` imports
    ``p`` and, if it is a module, ``p.m``."""
    mods = modules()

    def module_of(name):  # the module a dotted name lies in ("" if none of kfgen)
        while name and name not in mods:
            name = name.rpartition(".")[0]
        return name

    graph = {}
    for name, path in mods.items():
        targets = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                targets |= {module_of(alias.name) for alias in node.names}
            elif isinstance(node, ast.ImportFrom):
                base = _base(path, node)
                targets |= {module_of(base), *(module_of(f"{base}.{alias.name}") for alias in node.names)}
        graph[name] = targets - {"", name}
    return graph


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan's algorithm), each
    sorted: the import circles."""
    index, low, stack, on_stack, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                out.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(out)


def core_packages() -> list[str]:
    """Every core's package: each ``hdl`` package whose ``descriptor.py`` assigns ``CORE``."""
    found = []
    for path in sorted(HDL.rglob("descriptor.py")):
        body = ast.parse(path.read_text(), str(path)).body
        if any(isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "CORE" for t in node.targets)
               for node in body):
            found.append(".".join(["kfgen", *path.relative_to(HDL.parent).parent.parts]))
    return found


@pytest.mark.parametrize("package, below", [("hdl", ("gen", "sim")), ("sim", ("gen",))])
def test_dependencies_point_down(package, below):
    """``hdl`` imports neither ``gen`` nor ``sim``; ``sim`` does not import ``gen``."""
    forbidden = tuple(f"kfgen.{top}" for top in below)
    bad = [hit for path in sorted((HDL.parent / package).rglob("*.py")) for hit in offending(path, forbidden)]
    assert not bad, f"{package} imports {' or '.join(below)}:\n" + "\n".join(bad)


def test_no_import_circle():
    """No module of kfgen imports itself around a loop of imports, within a package or across
    them (a function-level import counts: it hides a circle, it does not break it)."""
    found = circles(import_graph())
    assert not found, "import circles:\n" + "\n".join(" <-> ".join(c) for c in found)


def test_the_circle_finder():
    """A loop of three is one circle; a module that only reaches it, or a chain, is none."""
    assert circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert circles({"a": {"b"}, "b": set()}) == []


def test_no_core_imports_another_core():
    """No ``hdl`` module imports a core's package but its own core's, except a building block
    of :data:`BLOCKS` for the importers it names. Every core package is scanned, as found."""
    cores = core_packages()
    assert {"kfgen.hdl.ukf", "kfgen.hdl.imm", "kfgen.hdl.castella", "kfgen.hdl.schur",
            "kfgen.hdl.arith.float"} <= set(cores), cores
    bad = []
    for name, targets in sorted(import_graph().items()):
        if not _inside(name, "kfgen.hdl"):
            continue
        for target in sorted(targets):
            core = next((c for c in cores if _inside(target, c)), None)
            if core is None or _inside(name, core):
                continue
            if not any(_inside(target, block) and _inside(name, importer) for block, (importer, _) in BLOCKS.items()):
                bad.append(f"{name} imports {target} (core {core})")
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
