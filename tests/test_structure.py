"""The package's import structure: no import cycles, no private names across modules.

Every module under ``src/hetmesh`` is parsed with :mod:`ast` (nothing is imported), and
every ``import`` / ``from ... import`` statement is collected, relative and absolute, at
module level or inside a function (a lazy import still ties two modules together). Tests
are checked for private names as well: a test that needs an internal hook should get a
public one.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src"
PACKAGE = "hetmesh"

# Import cycles tolerated for now, each as the pair (importer, imported) that closes it;
# the test fails once such an import is gone, so that the entry goes with it.
KNOWN_CYCLE_EDGES: set[tuple[str, str]] = set()

# Private names still read across modules, as "importing module: imported.module._name";
# the test fails once such a use is gone, so that the entry goes with it.
KNOWN_PRIVATE: set[str] = set()


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(SRC).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted((SRC / PACKAGE).rglob("*.py"))}


MODULES = _modules()


def _resolve(module: str, path: Path, node: ast.ImportFrom) -> str:
    """The absolute name of the module a ``from`` import reads from."""
    if node.level == 0:
        return node.module or ""
    package = module.split(".") if path.name == "__init__.py" else module.split(".")[:-1]
    base = package[: len(package) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _owner(name: str) -> str | None:
    """The longest package module that ``name`` is or lies in (None outside the package)."""
    while name:
        if name in MODULES:
            return name
        name = name.rpartition(".")[0]
    return None


def _runtime_nodes(tree: ast.AST):
    """Every node of ``tree`` except those under ``if TYPE_CHECKING:`` (imports made only
    for type checkers: they never run, so they tie no modules together)."""
    todo = [tree]
    while todo:
        node = todo.pop()
        yield node
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            todo.extend(node.orelse)
            continue
        todo.extend(ast.iter_child_nodes(node))


def imports_of(module: str, path: Path) -> list[tuple[str, str, int]]:
    """(imported module, imported name or "", line) for every import in one file.

    ``from a.b import c`` yields ``("a.b.c", "", line)`` when ``a.b.c`` is a module of the
    package, else ``("a.b", "c", line)``.
    """
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    found = []
    for node in _runtime_nodes(tree):
        if isinstance(node, ast.Import):
            found.extend((alias.name, "", node.lineno) for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            source = _resolve(module, path, node)
            for alias in node.names:
                sub = f"{source}.{alias.name}"
                if sub in MODULES:
                    found.append((sub, "", node.lineno))
                else:
                    found.append((source, alias.name, node.lineno))
    return found


def import_graph() -> dict[str, set[str]]:
    """module -> the package modules it imports (a package's ``__init__`` included)."""
    graph: dict[str, set[str]] = {m: set() for m in MODULES}
    for module, path in MODULES.items():
        for target, _, _ in imports_of(module, path):
            owner = _owner(target)
            if owner is not None and owner != module:
                graph[module].add(owner)
    return graph


def find_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
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
                components.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return components


def test_find_cycles_sees_a_cycle_and_a_lazy_import(tmp_path):
    a = tmp_path / "a.py"
    a.write_text("def f():\n    from .b import g\n")
    assert find_cycles({"a": {"b"}, "b": {"a"}, "c": {"a"}}) == [["a", "b"]]
    assert find_cycles({"a": {"b"}, "b": set()}) == []
    node = ast.parse(a.read_text()).body[0].body[0]
    assert _resolve("hetmesh.tri.x", Path("x.py"), node) == "hetmesh.tri.b"


def test_no_import_cycles():
    graph = import_graph()
    for importer, imported in KNOWN_CYCLE_EDGES:
        assert imported in graph[importer], \
            f"{importer} -> {imported} is gone: drop it from KNOWN_CYCLE_EDGES"
        graph[importer].discard(imported)
    cycles = find_cycles(graph)
    assert not cycles, "import cycles: " + "; ".join(" <-> ".join(c) for c in cycles)


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _private_imports(module: str, path: Path) -> list[tuple[str, int]]:
    """``from other.module import _name`` (or ``import other._module``) in one file."""
    found = []
    for target, name, line in imports_of(module, path):
        owner = _owner(target)
        if owner is None:
            continue
        parts = target.split(".")[len(owner.split(".")) - 1 :] + ([name] if name else [])
        if any(_private(p) for p in parts if p != "__main__"):
            found.append((f"{target}.{name}" if name else target, line))
    return found


def _module_aliases(module: str, path: Path, tree: ast.AST) -> dict[str, str]:
    """Local name -> package module, for the names an import binds to a module."""
    aliases = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.asname:
                    aliases[alias.asname] = alias.name
                else:
                    top = alias.name.partition(".")[0]
                    aliases[top] = top
        elif isinstance(node, ast.ImportFrom):
            source = _resolve(module, path, node)
            for alias in node.names:
                if f"{source}.{alias.name}" in MODULES:
                    aliases[alias.asname or alias.name] = f"{source}.{alias.name}"
    return aliases


def _dotted(node: ast.AST) -> str | None:
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        head = _dotted(node.value)
        return None if head is None else f"{head}.{node.attr}"
    return None


def _private_attributes(module: str, path: Path) -> list[tuple[str, int]]:
    """``mod._name`` where ``mod`` is another package module bound by an import."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    aliases = _module_aliases(module, path, tree)
    found = []
    for node in ast.walk(tree):
        if not (isinstance(node, ast.Attribute) and _private(node.attr)):
            continue
        chain = _dotted(node.value)
        if chain is None or chain.partition(".")[0] not in aliases:
            continue
        head, _, rest = chain.partition(".")
        target = aliases[head] + ("." + rest if rest else "")
        if target in MODULES and target != module:
            found.append((f"{target}.{node.attr}", node.lineno))
    return found


def private_uses(module: str, path: Path) -> list[str]:
    """Every private name of another package module that one file imports or reads, as
    ``file:line: module._name``, the known ones (:data:`KNOWN_PRIVATE`) left out."""
    found = _private_imports(module, path) + _private_attributes(module, path)
    return [f"{path.relative_to(ROOT)}:{line}: {shown}" for shown, line in found
            if f"{module}: {shown}" not in KNOWN_PRIVATE]


def test_known_private_uses_are_still_there():
    for entry in KNOWN_PRIVATE:
        module, _, shown = entry.partition(": ")
        path = MODULES[module]
        found = {s for s, _ in _private_imports(module, path) + _private_attributes(module, path)}
        assert shown in found, f"{entry} is gone: drop it from KNOWN_PRIVATE"


def test_no_private_names_imported_across_modules():
    bad = [b for module, path in MODULES.items() for b in private_uses(module, path)]
    assert not bad, "private names imported from another module:\n" + "\n".join(bad)


@pytest.mark.parametrize("path", sorted((ROOT / "tests").glob("*.py")), ids=lambda p: p.name)
def test_tests_import_no_private_names(path):
    bad = private_uses(f"tests.{path.stem}", path)
    assert not bad, "private names imported by a test:\n" + "\n".join(bad)


def test_private_uses_are_seen(tmp_path):
    """Both spellings are caught: ``from m import _x`` and ``import m as a; a._x``."""
    f = tmp_path / "t.py"
    f.write_text("from hetmesh.io.abaqus import _x, y\n"
                 "import hetmesh.io.atomic as a\n"
                 "def g():\n    return a._y, a.z, a.__name__\n")
    assert _private_imports("tests.t", f) == [("hetmesh.io.abaqus._x", 1)]
    assert _private_attributes("tests.t", f) == [("hetmesh.io.atomic._y", 4)]
