"""The layering of kfgen's packages (the folders of docs/development.md, "Layout"), every
import counted, at module level or inside a function:

- dependencies point down: ``hdl`` imports neither ``gen`` nor ``sim``, ``sim`` does not
  import ``gen``;
- no import circle anywhere: what two modules both need lives in a third below them;
- a core's package (every ``hdl`` package but the shared layers of :data:`SHARED`, and every
  one whose ``descriptor.py`` defines ``CORE``) is imported by no other package of ``hdl``, but
  for the building blocks :data:`BLOCKS` names with the reason: the engine layer
  (``hdl/engine``, ``hdl/linalg``) takes no core but those blocks, so a new core on it needs
  only it;
- a core's simulation and tests (``sim/<core>``, ``tests/<core>``) import no other core's."""

import ast
from pathlib import Path

import pytest

import kfgen.hdl
import kfgen.sim

HDL = Path(kfgen.hdl.__file__).parent
SIM = Path(kfgen.sim.__file__).parent
TESTS = Path(__file__).resolve().parents[1]

#: The top-level packages, each a folder beside ``hdl``.
TOPS = ("hdl", "gen", "sim")

#: The packages of ``hdl`` that every core shares; every other package of ``hdl`` is a core's
#: (one with a descriptor, or one on its way to having one) and held to the cores' rule.
SHARED = ("kfgen.hdl.arith", "kfgen.hdl.bus", "kfgen.hdl.describe", "kfgen.hdl.engine", "kfgen.hdl.linalg")

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


def _package(path: Path) -> list[str]:
    """The dotted parts of the package ``path`` (a module) lies in: ``tests...`` under the
    tests, else ``kfgen...`` (its folder under the one holding ``hdl``)."""
    if path.is_relative_to(TESTS):
        return ["tests", *path.relative_to(TESTS).parent.parts]
    return ["kfgen", *path.relative_to(HDL.parent).parent.parts]


def imports(path: Path) -> list[tuple[int, str, str]]:
    """(line, module, name) of every import statement in ``path``, at any depth, absolute:
    ``import a.b`` gives ``a.b`` twice; ``from p import m`` (``p`` absolute or relative)
    gives ``p`` and ``p.m``, ``m`` being a module of ``p`` or a name defined in it."""
    out = []
    package = _package(path)
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out += [(node.lineno, alias.name, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = ".".join((package[:len(package) - node.level + 1] if node.level else [])
                            + ([node.module] if node.module else []))
            out += [(node.lineno, base, f"{base}.{alias.name}") for alias in node.names]
    return out


def _inside(name: str, package: str) -> bool:
    return name == package or name.startswith(package + ".")


def offending(path: Path, forbidden: tuple[str, ...]) -> list[str]:
    """``path:line: name`` of each import in ``path`` of a module inside one of ``forbidden``."""
    return [f"{path.relative_to(HDL.parent)}:{line}: {name}" for line, _, name in imports(path)
            if any(_inside(name, f) for f in forbidden)]


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

    return {name: {module_of(m) for _, base, full in imports(path) for m in (base, full)} - {"", name}
            for name, path in mods.items()}


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
    """Every core's package, found: each package of ``hdl`` whose ``descriptor.py`` assigns
    ``CORE``, and each top-level package of ``hdl`` that is not one of the shared layers of
    :data:`SHARED` (a core whose descriptor is still to come)."""
    found = set()
    for path in sorted(HDL.rglob("descriptor.py")):
        body = ast.parse(path.read_text(), str(path)).body
        if any(isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "CORE" for t in node.targets)
               for node in body):
            found.add(".".join(_package(path)))
    found |= {f"kfgen.hdl.{path.name}" for path in HDL.iterdir()
              if (path / "__init__.py").is_file() and f"kfgen.hdl.{path.name}" not in SHARED}
    return sorted(found)


@pytest.mark.parametrize("package, below", [("hdl", ("gen", "sim")), ("sim", ("gen",))])
def test_dependencies_point_down(package, below):
    """``hdl`` imports neither ``gen`` nor ``sim``; ``sim`` does not import ``gen``, not even
    inside a function (a command that generates and then simulates is gen's,
    :mod:`kfgen.gen.cosim`)."""
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
    of :data:`BLOCKS` for the importers it names. Every core package is scanned, as found
    (with a descriptor or not yet: every package of ``hdl`` but the shared layers)."""
    cores = core_packages()
    assert {"kfgen.hdl.ukf", "kfgen.hdl.imm", "kfgen.hdl.castella", "kfgen.hdl.schur", "kfgen.hdl.arith.float",
            "kfgen.hdl.kf", "kfgen.hdl.ekf"} <= set(cores), cores
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
    """The scan would catch a lazy import inside a function, absolute or relative, and a
    package imported by name from its parent."""
    pkg = tmp_path / "hdl" / "core"
    pkg.mkdir(parents=True)
    (pkg / "descriptor.py").write_text("def f():\n    from kfgen.sim.x import y\n    from ...gen import cli\n"
                                       "from kfgen import sim\n")
    monkeypatch.setattr(__import__(__name__), "HDL", tmp_path / "hdl")
    assert offending(pkg / "descriptor.py", ("kfgen.gen", "kfgen.sim")) == [
        "hdl/core/descriptor.py:4: kfgen.sim", "hdl/core/descriptor.py:2: kfgen.sim.x.y",
        "hdl/core/descriptor.py:3: kfgen.gen.cli"]


def test_no_core_simulates_or_tests_with_another_cores_package():
    """A core's simulation (``sim/<core>``) and tests (``tests/<core>``) import no other core's
    sim or tests package: what two cores share lives in a shared layer (``sim/engine``, the
    engine's harness and Verilator runs). The cores are found, not listed: every top-level
    package of ``hdl`` whose descriptor module defines ``CORE``."""
    cores = sorted(c.split(".")[2] for c in core_packages() if c.count(".") == 2
                   and (HDL / c.split(".")[2] / "descriptor.py").is_file())
    assert {"ukf", "imm", "castella", "schur"} <= set(cores), cores

    def owner(name: str) -> str | None:
        """The core whose sim or tests package ``name`` (a module) belongs to, if any."""
        parts = name.split(".")
        if parts[:2] == ["kfgen", "sim"] and len(parts) > 2 and parts[2] in cores:
            return parts[2]
        if parts[0] == "tests" and len(parts) > 1 and parts[1] in cores:
            return parts[1]
        return next((c for c in cores if (TESTS / c / f"{parts[0]}.py").is_file()), None)  # a test module

    bad = [f"{path.relative_to(root.parents[1])}:{line}: {name}"
           for core in cores for root in (SIM / core, TESTS / core) for path in sorted(root.rglob("*.py"))
           for line, _, name in imports(path) if owner(name) not in (None, core)]
    assert not bad, "a core's sim or tests import another core's:\n" + "\n".join(bad)
