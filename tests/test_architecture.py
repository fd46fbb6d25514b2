"""The package's floor plan (ARCHITECTURE §1 and §11, issue 31): imports point down, no circle.

Every module under ``src/missiontree`` is parsed (not imported) and its imports of the package
collected, each marked as made at import time (module level), inside a function, or under
``if TYPE_CHECKING:``. The checks:

- **circles** — any strongly connected component of more than one module. Checked twice: over the
  imports that run at import time, and over every import (inside functions and under
  ``TYPE_CHECKING`` too: a lazy or type-only import that closes a circle still ties the modules
  into one).
- **upward imports** — every import, type-only ones included. A module may import its own part of
  the package, a part of a lower layer (:data:`LAYERS`), and :data:`OPEN_TO_ALL`; never a higher
  layer, never a part of its own layer, and never across :data:`APART` (the engine and the domain
  stand beside each other; the CLI reaches the backends only through the session).
- **private names** — no module takes a ``_name`` from another module, neither as
  ``from m import _name`` nor as ``m._name`` on an imported module, nor as ``x._name`` on an object
  when only other modules define ``_name`` (a function, class, module variable or ``self._name``
  attribute): what another module needs is public, or lives where it is needed.

Violations that belong to work in progress elsewhere are listed in :data:`ALLOWED`, each with its
reason and issue; an entry whose violation no longer exists fails the test, so the list only shrinks.
"""

from __future__ import annotations

import ast
import functools
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

import missiontree

PACKAGE_DIR = Path(missiontree.__file__).parent

#: Layer of each top-level part of the package: a part may import a part of a lower layer only.
LAYERS: dict[str, int] = {
    # under everything
    "": 0, "types": 0, "errors": 0,
    "file_limits": 0,  # model files' size limits and allow-list (constants only)
    "startup": 0,  # records a Ctrl-C during the command's start-up (signal only)
    "redact": 0,  # secrets and control characters out of every output (text functions only)
    "files": 0,  # writing a file whole (standard library only)
    "events": 0,  # the event-sink protocol every layer writes to
    "services": 0,  # the scene and model-call protocols a mission context carries (typing only)
    # reading files and options, raising the package's errors
    "yamlio": 1, "paths": 1,
    "options": 2,  # a provider's options checked, worded by yamlio's one translation of pydantic errors
    "robot": 2,  # the abstract robot
    # the domain, one concept a floor: per-frame geometry < the learned map < what is where < words
    "perception": 3, "mapping": 4, "semantics": 5, "reasoning": 6,
    # the engine stands beside the domain (APART): it knows py_trees and the robot, no maps or models
    "engine": 3,
    "backends": 7,  # implementations of the robot; only the session wires them
    "behaviours": 8,
    "plugins": 9,  # registers behaviours, providers and backends
    "runlog": 10, "session": 10,
    "evaluation": 11,  # batch runs call the session
    "cli": 12,
    "__main__": 13,  # `python -m missiontree` and the console script: the command line's entry
    "testing": 14,  # helpers for tests of the layers above
    "testing_models": 14,  # conformance suites for model providers
    "testing_runs": 14,  # synthetic run directories for tests and the viewer benchmark
}
#: Parts that never import each other in either direction, whatever their layers.
APART: set[frozenset[str]] = {
    *(frozenset({"engine", domain}) for domain in ("perception", "mapping", "semantics", "reasoning")),
    frozenset({"cli", "backends"}),  # the command line goes through the session
}
#: Modules any layer may import.
OPEN_TO_ALL = {"missiontree.plugins.hookspecs"}


@dataclass(frozen=True)
class Allowed:
    """One known violation, allowed while the work named by ``issue`` is under way elsewhere."""

    owner: str  # the area whose files hold the violation
    reason: str
    issue: int


#: Known violations by their key (see :func:`violations`); grouped by the area that owns the files.
ALLOWED: dict[str, Allowed] = {}


# -- reading the imports -----------------------------------------------------------------------------


@dataclass(frozen=True)
class Import:
    """One import of a package module by another."""

    importer: str
    imported: str
    line: int
    top: bool  # at module level: runs at import time
    type_only: bool  # under ``if TYPE_CHECKING:``
    names: tuple[str, ...] = ()  # the names a ``from ... import`` takes that are not modules


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


def _is_private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


class _ImportReader:
    """Collects a file's imports of the package and the private names it reads off imported modules."""

    def __init__(self, name: str, path: Path, modules: dict[str, Path]) -> None:
        self.name = name
        self.modules = modules
        self.package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
        self.imports: list[Import] = []
        self.bound: dict[str, str] = {}  # local name → package module it stands for
        self.tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))

    def _base(self, node: ast.ImportFrom) -> str:
        base = node.module or ""
        if node.level:
            parent = self.package[: len(self.package) - (node.level - 1)]
            base = ".".join([*parent, base] if base else parent)
        return base

    def _add(self, imported: str, node: ast.stmt, top: bool, type_only: bool,
             names: tuple[str, ...] = ()) -> None:
        self.imports.append(Import(self.name, imported, node.lineno, top, type_only, names))

    def _import_from(self, node: ast.ImportFrom, top: bool, type_only: bool) -> None:
        base = self._base(node)
        plain: list[str] = []
        for alias in node.names:
            full = f"{base}.{alias.name}"
            if full in self.modules:
                self._add(full, node, top, type_only)
                self.bound[alias.asname or alias.name] = full
            else:
                plain.append(alias.name)
        if plain or not node.names:
            self._add(base, node, top, type_only, tuple(plain))

    def visit(self, body: list[ast.stmt], top: bool, type_only: bool) -> None:
        """Walk statements, keeping whether they run at import time and whether they are type-only."""
        for node in body:
            if isinstance(node, ast.If) and _is_type_checking(node):
                self.visit(node.body, top, True)
                self.visit(node.orelse, top, type_only)
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    self._add(alias.name, node, top, type_only)
                    if alias.asname:
                        self.bound[alias.asname] = alias.name
            elif isinstance(node, ast.ImportFrom):
                self._import_from(node, top, type_only)
            elif isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                self.visit(node.body, False, type_only)
            else:
                for field in ("body", "orelse", "finalbody", "handlers"):
                    sub = getattr(node, field, None)
                    if isinstance(sub, list):
                        self.visit(sub, top, type_only)

    def private_attributes(self) -> list[tuple[str, str, int]]:
        """(module, private name, line) for each ``m._name`` read off an imported package module."""
        found = []
        for node in ast.walk(self.tree):
            if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                    and node.value.id in self.bound and _is_private(node.attr)):
                found.append((self.bound[node.value.id], node.attr, node.lineno))
        return found

    def object_attributes(self) -> list[tuple[str, int]]:
        """(private name, line) for each ``x._name`` on anything but ``self``, ``cls`` or a module."""
        found = []
        for node in ast.walk(self.tree):
            if not (isinstance(node, ast.Attribute) and _is_private(node.attr)):
                continue
            value = node.value
            if isinstance(value, ast.Name) and (value.id in ("self", "cls") or value.id in self.bound):
                continue
            found.append((node.attr, node.lineno))
        return found

    def private_definitions(self) -> set[str]:
        """Private names this file defines: functions, classes, module variables, ``self._x`` attributes."""
        names: set[str] = set()
        for node in ast.walk(self.tree):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
                names.add(node.name)
            elif (isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store)
                  and isinstance(node.value, ast.Name) and node.value.id in ("self", "cls")):
                names.add(node.attr)
            elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
                names.add(node.id)
        return {name for name in names if _is_private(name)}


def _in_package(target: str) -> bool:
    return target == "missiontree" or target.startswith("missiontree.")


def read_file(
    name: str, path: Path, modules: dict[str, Path],
) -> tuple[list[Import], list[tuple[str, str, int]]]:
    """The file's imports of the package and its private attribute reads (see :class:`_ImportReader`)."""
    return _read(_ImportReader(name, path, modules))


def _read(reader: _ImportReader) -> tuple[list[Import], list[tuple[str, str, int]]]:
    reader.visit(reader.tree.body, True, False)
    imports = [i for i in reader.imports if _in_package(i.imported)]
    private = [p for p in reader.private_attributes() if _in_package(p[0])]
    return imports, private


def object_crossings(readers: dict[str, _ImportReader]) -> list[tuple[str, str, int]]:
    """(reader, private name, line) for each ``x._name`` whose name only other modules define."""
    owners: dict[str, set[str]] = defaultdict(set)
    for name, reader in readers.items():
        for private in reader.private_definitions():
            owners[private].add(name)
    return [(name, attr, line) for name, reader in readers.items()
            for attr, line in reader.object_attributes() if owners.get(attr) and name not in owners[attr]]


def imports_of(name: str, path: Path, modules: dict[str, Path]) -> list[Import]:
    """Every import of the package in one file."""
    return read_file(name, path, modules)[0]


def _owning_module(target: str, modules: dict[str, Path]) -> str:
    # "import missiontree.a.b" also runs missiontree.a's __init__: the importing chain counts
    while target not in modules and "." in target:
        target = target.rsplit(".", 1)[0]
    return target


def package_imports() -> tuple[list[Import], list[tuple[str, str, str, int]]]:
    """Every import between two modules of the package, and every private name read across modules.

    The second list holds (importer, module, private name, line), from ``from m import _x``, ``m._x``
    and ``x._name`` on an object (module ``""``: the name is only defined elsewhere).
    """
    modules = module_files()
    every: list[Import] = []
    private: list[tuple[str, str, str, int]] = []
    readers = {name: _ImportReader(name, path, modules) for name, path in modules.items()}
    for name, reader in readers.items():
        imports, attributes = _read(reader)
        for item in imports:
            target = _owning_module(item.imported, modules)
            if target == name:
                continue
            every.append(Import(name, target, item.line, item.top, item.type_only, item.names))
            private.extend((name, target, n, item.line) for n in item.names if _is_private(n))
        private.extend((name, m, attr, line) for m, attr, line in attributes if m != name)
    private.extend((name, "", attr, line) for name, attr, line in object_crossings(readers))
    return every, private


def edges_of(every: list[Import], *, runtime_only: bool) -> dict[str, set[str]]:
    """Import edges: those that run at import time only, or all of them."""
    edges: dict[str, set[str]] = defaultdict(set)
    for item in every:
        if not runtime_only or (item.top and not item.type_only):
            edges[item.importer].add(item.imported)
    return edges


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


def upward_imports(every: list[Import]) -> dict[str, str]:
    """Every import in ``every`` that breaks the floor plan: key ``upward A -> B`` → why."""
    found: dict[str, str] = {}
    for item in every:
        if item.imported in OPEN_TO_ALL:
            continue
        a, b = part_of(item.importer), part_of(item.imported)
        if a == b:
            continue
        key = f"upward {item.importer} -> {item.imported}"
        kind = " (type only)" if item.type_only else ""
        if a not in LAYERS or b not in LAYERS:
            found[key] = f"line {item.line}: part {a if a not in LAYERS else b!r} has no layer in LAYERS"
        elif frozenset({a, b}) in APART:
            found[key] = f"line {item.line}{kind}: {a} and {b} stand apart"
        elif LAYERS[b] >= LAYERS[a]:
            found[key] = f"line {item.line}{kind}: {a} (layer {LAYERS[a]}) imports {b} (layer {LAYERS[b]})"
    return found


def private_crossings(private: list[tuple[str, str, str, int]]) -> dict[str, str]:
    """Key ``private A -> B._name`` → where, for each private name taken across modules."""
    return {f"private {importer} -> {module}.{name}": f"line {line}"
            for importer, module, name, line in private}


@functools.cache
def violations() -> dict[str, str]:
    """Every violation of the floor plan in the package today: key → where and why.

    Keys name modules, never lines, so an allow-list entry survives edits elsewhere in a file:
    ``circle A, B, C``, ``upward A -> B``, ``private A -> B._name``.
    """
    every, private = package_imports()
    found: dict[str, str] = {}
    for runtime_only in (True, False):
        edges = edges_of(every, runtime_only=runtime_only)
        for component in strongly_connected(edges):
            found.setdefault("circle " + ", ".join(component), describe_cycle(component, edges))
    found.update(upward_imports(every))
    found.update(private_crossings(private))
    return found


def _report(keys: list[str], found: dict[str, str]) -> str:
    files = module_files()
    lines = []
    for key in keys:
        module = key.split(" ", 1)[1].split(" ", 1)[0].rstrip(",")
        lines.append(f"{files.get(module, module)}: {key}: {found[key]}")
    return "\n".join(lines)


# -- the checker itself -------------------------------------------------------------------------------


def test_finds_a_circle_and_ignores_a_chain() -> None:
    """A loop of three modules and a self-import are circles; a chain is not."""
    edges = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": {"e"}}
    assert strongly_connected(edges) == [["a", "b", "c"], ["e"]]
    assert strongly_connected({"a": {"b"}, "b": {"c"}}) == []


def test_reads_imports_at_every_level_and_marks_type_checking_and_functions(tmp_path: Path) -> None:
    """Imports at module level, under try, under TYPE_CHECKING and inside functions are all read."""
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
               "missiontree.session.mission": source, "missiontree.engine.runner": source}
    found = {(i.imported, i.line, i.top, i.type_only) for i in imports_of("missiontree.x", source, modules)}
    assert ("missiontree.errors", 2, True, False) in found
    assert ("missiontree.types", 3, True, False) in found
    assert ("missiontree.engine.runner", 5, True, True) in found
    assert ("missiontree.robot.interface", 7, True, False) in found
    assert ("missiontree.session.mission", 11, False, False) in found


def test_a_type_checking_import_closes_a_circle_only_in_the_full_graph() -> None:
    """A type-only import back is left out of the import-time graph but counted in the full one."""
    every = [Import("m.a", "m.b", 1, True, False), Import("m.b", "m.a", 3, True, True)]
    assert strongly_connected(edges_of(every, runtime_only=True)) == []
    assert strongly_connected(edges_of(every, runtime_only=False)) == [["m.a", "m.b"]]


def test_private_names_are_found_in_from_imports_and_on_modules(tmp_path: Path) -> None:
    """``from m import _x`` and ``m._y`` on an imported module are private crossings; ``m.__doc__`` is not."""
    source = tmp_path / "mod.py"
    source.write_text(
        "from missiontree.perception import fusion\n"
        "from missiontree.perception.fusion import _Track, track\n"
        "import missiontree.mapping.grid as grid\n"
        "x = fusion._outline_centre(grid._k, fusion.__doc__)\n", encoding="utf-8")
    modules = {"missiontree.perception.fusion": source, "missiontree.mapping.grid": source}
    imports, attributes = read_file("missiontree.x", source, modules)
    taken = {(i.imported, n) for i in imports for n in i.names}
    assert taken == {("missiontree.perception.fusion", "_Track"), ("missiontree.perception.fusion", "track")}
    assert sorted((m, a) for m, a, _ in attributes) == [
        ("missiontree.mapping.grid", "_k"), ("missiontree.perception.fusion", "_outline_centre")]


def test_a_private_attribute_defined_only_elsewhere_is_a_crossing(tmp_path: Path) -> None:
    """``other._k`` counts when only another module defines ``_k``; ``self._k`` and own names do not."""
    owner, reader, own = tmp_path / "owner.py", tmp_path / "reader.py", tmp_path / "own.py"
    owner.write_text("class Fusion:\n    def __init__(self):\n        self._k = 1\n", encoding="utf-8")
    reader.write_text("def merge(fusion):\n    return fusion._k\n", encoding="utf-8")
    own.write_text("class A:\n    _k = 2\n    def f(self, other):\n        return other._k + self._k\n",
                   encoding="utf-8")
    modules = {"m.owner": owner, "m.reader": reader, "m.own": own}
    readers = {name: _ImportReader(name, path, modules) for name, path in modules.items()}
    assert object_crossings(readers) == [("m.reader", "_k", 2)]


def test_an_upward_or_apart_import_is_reported() -> None:
    """Upward, same-layer, apart and type-only upward imports are reported; a downward one is not."""
    fake = [Import("missiontree.reasoning.calls", "missiontree.engine.context", 12, False, False),
            Import("missiontree.perception.fusion", "missiontree.semantics.map", 3, True, True),
            Import("missiontree.runlog.replay", "missiontree.session.rundir", 4, True, False),
            Import("missiontree.cli.world", "missiontree.backends.sim.world", 5, True, False),
            Import("missiontree.engine.runner", "missiontree.robot.interface", 40, True, False)]
    found = upward_imports(fake)
    assert sorted(found) == [
        "upward missiontree.cli.world -> missiontree.backends.sim.world",
        "upward missiontree.perception.fusion -> missiontree.semantics.map",
        "upward missiontree.reasoning.calls -> missiontree.engine.context",
        "upward missiontree.runlog.replay -> missiontree.session.rundir"]
    assert "type only" in found["upward missiontree.perception.fusion -> missiontree.semantics.map"]
    assert "stand apart" in found["upward missiontree.reasoning.calls -> missiontree.engine.context"]


def test_every_part_of_the_package_has_a_layer() -> None:
    """Each top-level part of the package is placed on a floor."""
    parts = {part_of(m) for m in module_files()}
    assert parts <= set(LAYERS), f"add these parts to LAYERS: {sorted(parts - set(LAYERS))}"


def test_every_layer_names_a_part_that_exists() -> None:
    """LAYERS names no module or package the package does not have (the floor plan is today's)."""
    parts = {part_of(m) for m in module_files()}
    assert set(LAYERS) <= parts, f"remove from LAYERS: {sorted(set(LAYERS) - parts)}"


def test_every_allowed_violation_says_why_and_names_its_issue() -> None:
    """An allow-list entry carries its owner, a reason and an issue number."""
    for key, entry in ALLOWED.items():
        assert key.split(" ", 1)[0] in {"circle", "upward", "private"}, key
        assert entry.owner and len(entry.reason) > 10 and entry.issue > 0, key


# -- the package ----------------------------------------------------------------------------------------


def test_the_package_keeps_its_floor_plan() -> None:
    """No circle, no upward or apart import, no private name across modules, beyond the allow-list."""
    found = violations()
    new = sorted(set(found) - set(ALLOWED))
    assert not new, "violations of the floor plan:\n" + _report(new, found)


def test_the_allow_list_is_not_stale() -> None:
    """Every allowed violation still exists: a fixed one leaves the list."""
    stale = sorted(set(ALLOWED) - set(violations()))
    assert not stale, "fixed, so remove from ALLOWED:\n" + "\n".join(stale)



# -- one definition, one place -------------------------------------------------------------------------

#: Calls that change the whole process (allocator and garbage collector): only ``session.process``
#: makes them, and only the applications (:data:`TUNING_CALLERS`) ask it to (issue 31, deliverable 6).
PROCESS_SETTINGS = {"gc.freeze", "gc.unfreeze", "gc.disable", "gc.enable", "gc.set_threshold",
                    "pin_mmap_threshold", "mallopt"}
TUNING_CALLERS = {"missiontree.cli.main", "missiontree.evaluation.worker"}


def _called_names(tree: ast.AST) -> list[tuple[str, int]]:
    """(dotted name, line) of every call whose function is a plain or dotted name."""
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            func, parts = node.func, []
            while isinstance(func, ast.Attribute):
                parts.append(func.attr)
                func = func.value
            if isinstance(func, ast.Name):
                found.append((".".join([func.id, *reversed(parts)]), node.lineno))
    return found


def _is_protocol(node: ast.ClassDef) -> bool:
    for base in node.bases:
        base = base.value if isinstance(base, ast.Subscript) else base
        if (isinstance(base, ast.Name) and base.id == "Protocol") or (
                isinstance(base, ast.Attribute) and base.attr == "Protocol"):
            return True
    return False


def test_every_protocol_is_defined_once() -> None:
    """No two modules define a Protocol of the same name (the event sink was defined twice)."""
    where: dict[str, list[str]] = defaultdict(list)
    for name, path in module_files().items():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ClassDef) and _is_protocol(node):
                where[node.name].append(name)
    twice = {protocol: modules for protocol, modules in where.items() if len(modules) > 1}
    assert not twice, f"protocols defined more than once (keep one, import it): {twice}"


def test_only_the_process_module_changes_the_process_and_only_applications_ask() -> None:
    """gc.freeze, the mmap threshold and the like live in session.process; tune_process is the CLI's call."""
    wrong = []
    for name, path in module_files().items():
        for called, line in _called_names(ast.parse(path.read_text(encoding="utf-8"))):
            short = called.rsplit(".", 1)[-1]
            if (called in PROCESS_SETTINGS or short in PROCESS_SETTINGS) and name not in {
                    "missiontree.session.process", "missiontree.engine.native_memory"}:
                wrong.append(f"{path}:{line}: {called}")
            if short == "tune_process" and name not in TUNING_CALLERS:
                wrong.append(f"{path}:{line}: {called} (only {sorted(TUNING_CALLERS)} tune the process)")
    assert not wrong, "process settings changed outside session.process:\n" + "\n".join(wrong)


#: Modules that read pydantic's error dictionaries (``err["msg"]``, ``err["loc"]``) themselves, besides
#: the one translation in ``yamlio.problems`` (issue 31, deliverable 5), each with its reason.
PYDANTIC_READERS = {
    "missiontree.yamlio.problems": "the one translation of pydantic errors into problems and messages",
    "missiontree.engine.validate": "merges a union's alternatives into one node-parameter issue, worded "
                                   "by yamlio's expected_text",
    "missiontree.backends.sim.world": "drops a world's broken objects to check the rest (no wording)",
    "missiontree.backends.sim.robot_profiles": "names an override's key path (not in a file); the message is "
                                               "yamlio's error_message",
    "missiontree.reasoning.checks": "a model answer's errors fed back to the model (not a config file); "
                                    "owned by the intent work",
    "missiontree.backends.ros2.profile": "to move to yamlio's error_lines (owned by the ROS 2 work)",
}


def _reads_error_dicts(tree: ast.AST) -> list[int]:
    """Lines that subscript something with the string ``"msg"`` or ``"loc"`` (a pydantic error's keys)."""
    return [node.lineno for node in ast.walk(tree) if isinstance(node, ast.Subscript)
            and isinstance(node.slice, ast.Constant) and node.slice.value in ("msg", "loc")]


def test_pydantic_errors_are_worded_in_one_place() -> None:
    """Only yamlio.problems (and the listed exceptions) reads pydantic's error dictionaries."""
    found = {name: lines for name, path in module_files().items()
             if (lines := _reads_error_dicts(ast.parse(path.read_text(encoding="utf-8"))))}
    extra = sorted(set(found) - set(PYDANTIC_READERS))
    assert not extra, f"word pydantic errors with missiontree.yamlio (error_lines, validation_problems): " \
                      f"{[(m, found[m]) for m in extra]}"
    stale = sorted(set(PYDANTIC_READERS) - set(found))
    assert not stale, f"no longer reads pydantic errors, so remove from PYDANTIC_READERS: {stale}"


def test_the_call_reader_finds_dotted_and_plain_calls() -> None:
    """gc.freeze() and pin_mmap_threshold() are read as called names; an attribute without a call is not."""
    tree = ast.parse("import gc\ngc.freeze()\npin_mmap_threshold()\nx = gc.freeze\na.b.c(1)\n")
    assert _called_names(tree) == [("gc.freeze", 2), ("pin_mmap_threshold", 3), ("a.b.c", 5)]


# -- sizes ---------------------------------------------------------------------------------------------

#: Longest module and function in src/ (issue 31): modules of one concept, functions that read whole.
MAX_MODULE_LINES = 600
MAX_FUNCTION_LINES = 60
#: Known oversize modules and functions (``module`` or ``module:function``), each with its owner and
#: reason; an entry that is no longer over the limit fails the test, so the list only shrinks.
SIZE_ALLOWED: dict[str, Allowed] = {}


def oversize() -> dict[str, int]:
    """Modules over :data:`MAX_MODULE_LINES` and functions over :data:`MAX_FUNCTION_LINES`: key → lines."""
    found: dict[str, int] = {}
    for name, path in module_files().items():
        text = path.read_text(encoding="utf-8")
        if text.count("\n") > MAX_MODULE_LINES:
            found[name] = text.count("\n")
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                length = (node.end_lineno or node.lineno) - node.lineno + 1
                if length > MAX_FUNCTION_LINES:
                    found[f"{name}:{node.name}"] = length
    return found


def test_no_module_or_function_is_over_its_size() -> None:
    """No module over 600 lines and no function over 60 in src/, beyond the size allow-list."""
    found = oversize()
    new = {key: lines for key, lines in found.items() if key not in SIZE_ALLOWED}
    assert not new, f"split these along a real seam (lines): {new}"


def test_the_size_allow_list_is_not_stale() -> None:
    """Every allowed oversize module or function is still over its limit: a fixed one leaves the list."""
    stale = sorted(set(SIZE_ALLOWED) - set(oversize()))
    assert not stale, f"within the limits now, so remove from SIZE_ALLOWED: {stale}"


# -- the floor plan in the README ----------------------------------------------------------------------

README = PACKAGE_DIR.parent.parent / "README.md"
#: The generated table sits between these lines of README.md's "Where things are" section.
README_BEGIN = ("<!-- packages: generated from each package's docstring by "
                "`python tests/test_architecture.py --write-readme`, which checks it -->")
README_END = "<!-- end of packages -->"


def _summary(doc: str | None) -> str:
    """A docstring's first line as Markdown: Sphinx roles and double backticks as plain code."""
    import re

    first = (doc or "").strip().split("\n\n", 1)[0].replace("\n", " ")
    first = re.sub(r":(?:mod|func|class|data|meth|attr):`~?([^`]+)`", r"`\1`", first)
    return first.replace("``", "`").replace("|", "\\|")


def readme_packages() -> str:
    """The README's table of packages, top floor first: each package's path, floor and docstring summary."""
    rows = []
    for path in sorted(PACKAGE_DIR.rglob("__init__.py")):
        parts = path.parent.relative_to(PACKAGE_DIR).parts
        if not parts or not (path.parent / "__init__.py").is_file() or "data" in parts:
            continue
        doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8")))
        rows.append((-LAYERS[parts[0]], "/".join(parts), _summary(doc)))
    modules = [f"`{stem}`" for stem in sorted(p.stem for p in PACKAGE_DIR.glob("*.py")
                                              if p.stem not in ("__init__", "__main__"))]
    lines = [README_BEGIN, "", "| package (`src/missiontree/`) | floor | what |", "|---|---|---|"]
    lines += [f"| `{name}/` | {-floor} | {summary} |" for floor, name, summary in sorted(rows)]
    lines += [f"| modules | 0-14 | {', '.join(modules)}: see each module's docstring |", "", README_END]
    return "\n".join(lines)


def _readme_with(table: str) -> str:
    text = README.read_text(encoding="utf-8")
    start, end = text.find(README_BEGIN), text.find(README_END)
    assert 0 <= start < end, f"README.md has no {README_BEGIN!r} ... {README_END!r} block"
    return text[:start] + table + text[end + len(README_END):]


def test_every_package_docstring_has_a_summary_line() -> None:
    """Each package says in its first docstring line what lives in it (the README's table is made of them)."""
    missing = [str(p) for p in PACKAGE_DIR.rglob("__init__.py")
               if "data" not in p.parts and not ast.get_docstring(ast.parse(p.read_text(encoding="utf-8")))]
    assert not missing, f"packages without a docstring: {missing}"


def test_the_readme_lists_every_package_from_its_docstring() -> None:
    """README's "Where things are" is the table made from the package docstrings, floor by floor."""
    assert README.read_text(encoding="utf-8") == _readme_with(readme_packages()), (
        "README.md's package table is out of date: run `python tests/test_architecture.py --write-readme`")


if __name__ == "__main__":
    import sys

    if sys.argv[1:] == ["--write-readme"]:
        README.write_text(_readme_with(readme_packages()), encoding="utf-8")
    else:
        print(readme_packages())
