"""The package's layering (ARCHITECTURE §1): imports point down only, and no import circle.

Every module under ``src/missiontree`` is parsed (not imported) and its imports collected:

- **cycles** — imports under ``if TYPE_CHECKING:`` left out; any strongly connected component of
  more than one module is a circle. Checked twice: module-level imports (those run at import time)
  and every import, also inside functions (a lazy import that closes a circle is still a circle:
  the world loader importing the generator inside a function while the generator imports the
  loader was one).
- **upward imports** — every import, also inside functions, again leaving out ``TYPE_CHECKING``.
  A module may import its own part of the package, any part of a lower layer, a part of its own
  layer unless :data:`FORBIDDEN_SAME_LAYER` says otherwise, and :mod:`missiontree.plugins.hookspecs`
  (the hook markers plugins implement).
"""

from __future__ import annotations

import ast
from collections import defaultdict
from pathlib import Path

import missiontree

PACKAGE_DIR = Path(missiontree.__file__).parent

#: Layer of each top-level part of the package; a module may import parts of a lower layer and of
#: its own layer (circles are caught by the cycle tests), never of a higher one.
LAYERS: dict[str, int] = {
    # under everything
    "": 0, "types": 0, "errors": 0, "events": 0, "yamlio": 0, "paths": 0, "options": 0,
    "file_limits": 0,  # model files' size limits and allow-list (constants only)
    "startup": 0,  # records a Ctrl-C during the command's start-up (signal only)
    "redact": 0,  # secrets and control characters out of every output (text functions only)
    "files": 0,  # writing a file whole (standard library only)
    "robot": 1,  # the abstract robot
    # domain logic (no engine, no plugins); reasoning may read semantics, never the reverse
    "perception": 2, "mapping": 2, "semantics": 2, "reasoning": 2,
    "backends": 3,  # implementations of the robot; only the session wires them
    "engine": 4,
    "behaviours": 5,
    "plugins": 6,   # registers behaviours, providers and backends
    "runlog": 7, "session": 7,
    "evaluation": 8,  # batch runs call the session
    "cli": 9,
    "__main__": 9,  # `python -m missiontree` and the console script: the command line's entry
    "testing": 10,  # helpers for tests of the layers above
    "testing_models": 10,  # conformance suites for model providers
}
#: Pairs inside one layer that are forbidden in one direction only: (importer, imported).
FORBIDDEN_SAME_LAYER = {("semantics", "reasoning")}
#: Modules any layer may import.
OPEN_TO_ALL = {"missiontree.plugins.hookspecs"}

def module_files() -> dict[str, Path]:
    """Dotted module name → file, for every module of the package."""
    found: dict[str, Path] = {}
    for path in sorted(PACKAGE_DIR.rglob("*.py")):
        parts = list(path.relative_to(PACKAGE_DIR.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        found[".".join(parts)] = path
    return found


def _is_type_checking(node: ast.If) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def imports_of(name: str, path: Path, modules: dict[str, Path]) -> list[tuple[str, int, bool]]:
    """(imported module, line, at module level) for each import of ``missiontree`` in the file."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    found: list[tuple[str, int, bool]] = []

    def resolve(base: str, names: list[str]) -> list[str]:
        targets = []
        for alias in names:
            full = f"{base}.{alias}"
            targets.append(full if full in modules else base)
        return targets

    def visit(body: list[ast.stmt], top: bool) -> None:
        for node in body:
            if isinstance(node, ast.If) and _is_type_checking(node):
                visit(node.orelse, top)
                continue
            if isinstance(node, ast.Import):
                found.extend((alias.name, node.lineno, top) for alias in node.names)
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    parent = package[: len(package) - (node.level - 1)]
                    base = ".".join([*parent, base] if base else parent)
                found.extend((t, node.lineno, top) for t in resolve(base, [a.name for a in node.names]))
            elif isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda):
                visit(node.body if isinstance(node.body, list) else [], False)
            else:
                for field in ("body", "orelse", "finalbody", "handlers"):
                    sub = getattr(node, field, None)
                    if isinstance(sub, list):
                        visit(sub, top)

    visit(tree.body, True)
    return [(target, line, top) for target, line, top in found
            if target == "missiontree" or target.startswith("missiontree.")]


def import_graph() -> tuple[dict[str, set[str]], list[tuple[str, str, int, bool]]]:
    """Module-level edges (for cycles) and every edge with its line (for layering)."""
    modules = module_files()
    edges: dict[str, set[str]] = defaultdict(set)
    every: list[tuple[str, str, int, bool]] = []
    for name, path in modules.items():
        for target, line, top in imports_of(name, path, modules):
            # "import missiontree.a.b" also runs missiontree.a's __init__: the importing chain counts
            while target not in modules and "." in target:
                target = target.rsplit(".", 1)[0]
            if target == name:
                continue
            every.append((name, target, line, top))
            if top:
                edges[name].add(target)
    return edges, every


def strongly_connected(edges: dict[str, set[str]]) -> list[list[str]]:
    """Tarjan's algorithm, iterative: every component of more than one module (or a self-loop)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    components: list[list[str]] = []
    counter = 0
    nodes = sorted(set(edges) | {t for ts in edges.values() for t in ts})
    for start in nodes:
        if start in index:
            continue
        work: list[tuple[str, list[str]]] = [(start, sorted(edges.get(start, ())))]
        index[start] = low[start] = counter
        counter += 1
        stack.append(start)
        on_stack.add(start)
        while work:
            node, todo = work[-1]
            if todo:
                nxt = todo.pop()
                if nxt not in index:
                    index[nxt] = low[nxt] = counter
                    counter += 1
                    stack.append(nxt)
                    on_stack.add(nxt)
                    work.append((nxt, sorted(edges.get(nxt, ()))))
                elif nxt in on_stack:
                    low[node] = min(low[node], index[nxt])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1 or node in edges.get(node, ()):
                    components.append(sorted(component))
    return components


def describe_cycle(component: list[str], edges: dict[str, set[str]]) -> str:
    """The component with the imports that hold it together."""
    inside = set(component)
    links = [f"{a} -> {b}" for a in component for b in sorted(edges.get(a, ())) if b in inside]
    return f"circle of {len(component)} modules: " + "; ".join(links)


def part_of(module: str) -> str:
    """The top-level part of the package a module belongs to ('' for missiontree itself)."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def upward_imports(every: list[tuple[str, str, int, bool]], files: dict[str, Path]) -> list[str]:
    """Every import in ``every`` that points up, as ``file:line: a imports b``."""
    found = []
    for importer, imported, line, _top in every:
        if imported in OPEN_TO_ALL:
            continue
        a, b = part_of(importer), part_of(imported)
        if a == b:
            continue
        if a not in LAYERS or b not in LAYERS:
            found.append(f"{files[importer]}:{line}: {importer} imports {imported}: "
                         f"part {a if a not in LAYERS else b!r} has no layer in test_architecture.LAYERS")
            continue
        if LAYERS[b] > LAYERS[a] or (a, b) in FORBIDDEN_SAME_LAYER:
            found.append(f"{files[importer]}:{line}: {importer} (layer {LAYERS[a]}, {a}) imports {imported} "
                         f"(layer {LAYERS[b]}, {b})")
    return found


# -- the checker itself -------------------------------------------------------------------------------


def test_finds_a_circle_and_ignores_a_chain() -> None:
    edges = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": {"e"}}
    assert strongly_connected(edges) == [["a", "b", "c"], ["e"]]
    assert strongly_connected({"a": {"b"}, "b": {"c"}}) == []


def test_reads_imports_at_module_level_but_not_type_checking_or_functions(tmp_path: Path) -> None:
    source = tmp_path / "mod.py"
    source.write_text(
        "from typing import TYPE_CHECKING\n"
        "import missiontree.errors\n"
        "from missiontree import types\n"
        "if TYPE_CHECKING:\n"
        "    from missiontree.engine import runner\n"
        "try:\n"
        "    from missiontree.robot import interface\n"
        "except ImportError:\n"
        "    pass\n"
        "def later():\n"
        "    from missiontree.session import mission\n", encoding="utf-8")
    modules = {"missiontree.types": source, "missiontree.robot.interface": source,
               "missiontree.session.mission": source}
    found = imports_of("missiontree.x", source, modules)
    assert ("missiontree.errors", 2, True) in found
    assert ("missiontree.types", 3, True) in found
    assert ("missiontree.robot.interface", 7, True) in found
    assert ("missiontree.session.mission", 11, False) in found
    assert all("engine" not in target for target, _, _ in found)


def test_an_upward_import_is_reported() -> None:
    fake = [("missiontree.reasoning.calls", "missiontree.engine.context", 12, False),
            ("missiontree.semantics.graph", "missiontree.reasoning.calls", 3, True),
            ("missiontree.engine.runner", "missiontree.robot.interface", 40, True)]
    found = upward_imports(fake, {name: Path(name) for name, *_ in fake})
    assert len(found) == 2
    assert "reasoning.calls (layer 2, reasoning) imports missiontree.engine.context" in found[0]
    assert "semantics" in found[1]


def test_every_part_of_the_package_has_a_layer() -> None:
    parts = {part_of(m) for m in module_files()}
    assert parts <= set(LAYERS), f"add these parts to LAYERS: {sorted(parts - set(LAYERS))}"


# -- the package ----------------------------------------------------------------------------------------


def all_edges() -> dict[str, set[str]]:
    """Edges of every import (module level and inside functions), TYPE_CHECKING left out."""
    _, every = import_graph()
    edges: dict[str, set[str]] = defaultdict(set)
    for importer, imported, _line, _top in every:
        edges[importer].add(imported)
    return edges


def test_no_module_level_import_circle() -> None:
    edges, _ = import_graph()
    circles = [describe_cycle(c, edges) for c in strongly_connected(edges)]
    assert not circles, "\n".join(circles)


def test_no_import_circle_even_through_imports_inside_functions() -> None:
    edges = all_edges()
    circles = [describe_cycle(c, edges) for c in strongly_connected(edges)]
    assert not circles, "\n".join(circles)


def test_imports_point_down_only() -> None:
    _, every = import_graph()
    found = upward_imports(every, module_files())
    assert not found, "\n".join(found)


def test_reasoning_imports_neither_the_engine_nor_the_plugins() -> None:
    _, every = import_graph()
    bad = [f"{a} imports {b}" for a, b, _, _ in every
           if part_of(a) == "reasoning" and part_of(b) in {"engine", "plugins", "session"}]
    assert not bad, "\n".join(bad)
