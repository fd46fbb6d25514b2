"""Mission file → checked :class:`~missiontree.engine.spec.MissionSpec`, with every problem at once.

The loader reads the file with :mod:`missiontree.yamlio` (safe, bounded, positions kept), checks the
top level, substitutes ``${param}`` references, turns the ``root:`` node and everything under it into
:class:`~missiontree.engine.spec.NodeSpec` objects, expands ``Include`` nodes (subtrees from other
files, with parameters), and hands the tree to :func:`missiontree.engine.validate.check_tree`, which
checks every node against its registered type. Problems from all stages are collected and raised
together as one :class:`~missiontree.errors.MissionFileError`.

Includes are resolved relative to the including file, then relative to the trusted tree folders
(``./trees`` and the repository's ``trees/``), so ``file: subtrees/announce.yaml`` finds a shipped
subtree. A resolved path must lie inside the mission's folder or a trusted tree folder unless
``allow_outside=True``.
"""

from __future__ import annotations

import difflib
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from missiontree.engine.overrides import OverrideError, convert_override, describe_params
from missiontree.engine.registry import NodeRegistry
from missiontree.engine.spec import (
    CHILD_KEY,
    CHILDREN_KEY,
    CONDITION_KEYS,
    NAME_KEY,
    TOP_LEVEL_KEYS,
    MissionSpec,
    NodeSpec,
    RunSection,
    Source,
)
from missiontree.engine.substitution import kind as _kind
from missiontree.engine.substitution import substitute
from missiontree.engine.validate import check_tree, non_finite_issues
from missiontree.errors import MissionFileError, Problem
from missiontree.paths import REPO_ROOT
from missiontree.yamlio import Located, load_yaml, validation_problems
from missiontree.yamlio import short_repr as shown

#: The node type name the loader handles itself: a subtree from another file.
INCLUDE = "Include"
#: Most nested includes, and most nodes in the whole expanded mission.
MAX_INCLUDE_DEPTH = 16
MAX_TREE_NODES = 10_000

_IDENT_RE = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
_KEY_RE = re.compile(r"/?[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*\Z")


def trusted_tree_dirs() -> list[Path]:
    """Folders whose subtrees any mission may include: ``./trees`` and the repository's ``trees/``."""
    dirs: list[Path] = []
    for d in (Path.cwd() / "trees", REPO_ROOT / "trees"):
        resolved = d.resolve()
        if resolved.is_dir() and resolved not in dirs:
            dirs.append(resolved)
    return dirs


def load_mission(path: str | Path, registry: NodeRegistry, *, allow_outside: bool = False,
                 params: dict[str, Any] | None = None) -> MissionSpec:
    """Read, expand and check a mission file.

    Args:
        path: The mission file.
        registry: The node types the mission may use.
        allow_outside: Allow includes that resolve outside the mission's folder and the trusted
            tree folders.
        params: Values that replace the mission's ``params:`` defaults (``run --set``): text is read
            as YAML, each is held to its default's type (:mod:`missiontree.engine.overrides`); an
            unknown name or a wrong type is a problem at ``params.<name>``.

    Returns:
        The checked mission, every node's ``params`` validated.

    Raises:
        MissionFileError: With every problem found in the file and the subtrees it includes.
    """
    spec, problems = check_mission(path, registry, allow_outside=allow_outside, params=params)
    if problems:
        raise MissionFileError(problems)
    assert spec is not None  # no problems implies the root parsed
    return spec


def check_mission(path: str | Path, registry: NodeRegistry, *, allow_outside: bool = False,
                  params: dict[str, Any] | None = None) -> tuple[MissionSpec | None, list[Problem]]:
    """Like :func:`load_mission`, but return the problems (sorted) instead of raising them.

    The spec is returned even when some nodes have problems (those nodes have ``params=None``), so
    ``missiontree validate`` can go on to check what the rest of the mission references; it is None
    only when the file could not be read as a mission at all.
    """
    loader = _Loader(Path(path), registry, allow_outside)
    loader.overrides = dict(params or {})
    spec = loader.load()
    problems = list(loader.problems)
    if spec is not None:
        problems += check_tree(spec, registry)
    ordered = sorted(_dedupe(problems), key=lambda p: (p.file != str(path), p.file, p.line, p.col))
    return spec, ordered


def _dedupe(problems: list[Problem]) -> list[Problem]:
    seen: set[Problem] = set()
    unique = []
    for p in problems:
        if p not in seen:
            seen.add(p)
            unique.append(p)
    return unique


@dataclass
class _File:
    """One file being expanded: its document, its parameter values and its place in the include chain."""

    path: Path
    doc: Located
    values: dict[str, Any]
    chain: tuple[str, ...]
    resolved_chain: tuple[Path, ...]
    blackboard: dict[str, Any] = field(default_factory=dict)


class _Loader:
    """Reads one mission and its includes, collecting problems instead of stopping at the first."""

    def __init__(self, path: Path, registry: NodeRegistry, allow_outside: bool) -> None:
        self.path = path
        self.registry = registry
        self.allow_outside = allow_outside
        self.problems: list[Problem] = []
        self.files: list[Path] = []
        self.node_count = 0
        self.mission_dir = path.resolve().parent
        self._parsed: dict[Path, Located | None] = {}
        self.overrides: dict[str, Any] = {}

    # -- top level --------------------------------------------------------------------------

    def load(self) -> MissionSpec | None:
        try:
            doc = load_yaml(self.path, error=MissionFileError)
        except MissionFileError as exc:
            self.problems += exc.problems
            return None
        self.files.append(self.path.resolve())
        if not self._check_top(doc, is_subtree=False):
            return None
        values = self._declared_params(doc, given=None, include_site=None)
        values.update(self._checked_overrides(doc))
        file = _File(self.path, doc, values, (), (self.path.resolve(),))
        blackboard = self._blackboard(file)
        run = self._run_section(doc)
        root = self._root(file, "root")
        if root is None:
            return None
        description = doc.data.get("description")
        return MissionSpec(
            path=self.path, root=root, blackboard={**file.blackboard, **blackboard}, run=run,
            description=description if isinstance(description, str) else "", files=list(self.files),
        )

    def _check_top(self, doc: Located, *, is_subtree: bool) -> bool:
        data = doc.data
        if not isinstance(data, dict):
            found = "a list" if isinstance(data, list) else f"the single value {shown(data)}"
            self.problems.append(doc.problem_at(
                (), f"expected a mapping with `root:` at the top of the file, found {found}",
                "start the file with `root:` followed by the root node, indented below it", where="",
            ))
            return False
        ok = True
        for key in data:
            if key not in TOP_LEVEL_KEYS:
                near = difflib.get_close_matches(key, TOP_LEVEL_KEYS, n=1)
                self.problems.append(doc.problem_at(
                    (key,),
                    f"expected one of the top-level keys {', '.join(TOP_LEVEL_KEYS)}; found {shown(key)}",
                    f"did you mean {near[0]!r}?" if near else "remove it, or put the node under `root:`",
                    key=True, where="",
                ))
        if "root" not in data:
            self.problems.append(doc.problem_at(
                (), "expected a `root:` node, found none", "add `root:` with the mission's top node",
                where=""))
            ok = False
        if is_subtree and "run" in data:
            self.problems.append(doc.problem_at(
                ("run",), "expected no `run:` section in an included subtree, found one",
                "move run defaults to the mission file", key=True, where=""))
        version = data.get("version", 1)
        if version != 1:
            self.problems.append(doc.problem_at(
                ("version",), f"expected format version 1, found {shown(version)}", "write `version: 1`",
                where=""))
        return ok

    def _checked_overrides(self, doc: Located) -> dict[str, Any]:
        """The ``--set`` values, each read and held to its default's type; problems at ``params.<name>``."""
        declared = doc.data.get("params")
        declared = {str(k): v for k, v in declared.items()} if isinstance(declared, dict) else {}
        values: dict[str, Any] = {}
        for name, given in self.overrides.items():
            hint = describe_params(self.path, declared)
            if name not in declared:
                near = difflib.get_close_matches(name, list(declared), n=1)
                also = f"; did you mean {near[0]!r}?" if near else ""
                self.problems.append(doc.problem_at(
                    ("params",), f"--set {name}: the mission declares no parameter {name!r}{also}", hint,
                    key=True, where=f"params.{name}"))
                continue
            try:
                values[name] = convert_override(name, given, declared[name])
            except OverrideError as error:
                self.problems.append(doc.problem_at(("params", name), str(error), hint))
        return values

    def _declared_params(
        self, doc: Located, given: dict[str, Any] | None, include_site: tuple[Located, str] | None
    ) -> dict[str, Any]:
        """The file's parameter values: its `params:` defaults overridden by those an include gave."""
        declared = doc.data.get("params") or {}
        required = doc.data.get("required") or []
        values: dict[str, Any] = {}
        if not isinstance(declared, dict):
            self.problems.append(doc.problem_at(
                ("params",), f"expected a mapping of parameter names to defaults, found {_kind(declared)}",
                "write `params: {name: default}`", where=""))
            declared = {}
        if not isinstance(required, list) or not all(isinstance(r, str) for r in required):
            self.problems.append(doc.problem_at(
                ("required",), "expected a list of parameter names, found something else",
                "write `required: [name, ...]`", where=""))
            required = []
        for name in [*declared, *required]:
            if not _IDENT_RE.match(name):
                self.problems.append(doc.problem_at(
                    ("params", name), f"expected a parameter name (letters, digits, _), found {shown(name)}",
                    "rename it", key=True, where=""))
        values.update(declared)
        given = dict(given or {})
        if include_site is not None:
            site, where = include_site
            for name in given:
                if name not in declared and name not in required:
                    known = [*declared, *required]
                    near = difflib.get_close_matches(name, known, n=1)
                    self.problems.append(site.problem_at(
                        ("params", name),
                        f"expected one of the subtree's parameters ({', '.join(known) or 'none'}), "
                        f"found {shown(name)}",
                        f"did you mean {near[0]!r}?" if near else "remove it or declare it under `params:` "
                        "in the subtree", key=True, where=where))
            for name in required:
                if name not in given:
                    self.problems.append(site.problem_at(
                        ("params",), f"expected a value for the subtree's required parameter "
                        f"{name!r}, found none",
                        f"add `params: {{{name}: ...}}` to the Include", where=where))
            values.update(given)
        elif required:
            self.problems.append(doc.problem_at(
                ("required",), f"expected a mission file, found a subtree with required parameters "
                f"({', '.join(required)})", "check a mission that includes it, or give the parameters "
                "defaults under `params:`", where=""))
            # keep ${name} as written so the rest of the file is still checked without noise
            values.update({name: f"${{{name}}}" for name in required})
        return values

    def _blackboard(self, file: _File) -> dict[str, Any]:
        raw = file.doc.data.get("blackboard") or {}
        if not isinstance(raw, dict):
            self.problems.append(file.doc.problem_at(
                ("blackboard",), f"expected a mapping of blackboard keys to values, found {_kind(raw)}",
                "write `blackboard: {key: value}`", where=""))
            return {}
        values = self._substitute(raw, file, ("blackboard",), where="blackboard")
        for key in values:
            if not _KEY_RE.match(key):
                self.problems.append(file.doc.problem_at(
                    ("blackboard", key), f"expected a blackboard key (letters, digits, _ and / for "
                    f"namespaces), found {shown(key)}", "rename the key", key=True, where="blackboard"))
        for issue in non_finite_issues(values):
            self.problems.append(file.doc.problem_at(
                ("blackboard", *issue.loc), issue.message, issue.hint, where="blackboard"))
        return values

    def _run_section(self, doc: Located) -> RunSection:
        raw = doc.data.get("run")
        if raw is None:
            return RunSection()
        if not isinstance(raw, dict):
            self.problems.append(doc.problem_at(
                ("run",), f"expected a mapping of run defaults, found {_kind(raw)}",
                "write `run: {backend: sim, tick_hz: 10}`", where="run"))
            return RunSection()
        try:
            return RunSection.model_validate(raw)
        except ValidationError as exc:
            self.problems.extend(validation_problems(exc, doc, RunSection, prefix=("run",)))
            return RunSection()

    # -- nodes ------------------------------------------------------------------------------

    def _root(self, file: _File, parent_path: str) -> NodeSpec | None:
        raw = file.doc.data.get("root")
        substituted = self._substitute(raw, file, ("root",), where=parent_path)
        return self._node(file, substituted, ("root",), parent_path, index=None)

    def _node(
        self, file: _File, data: Any, key_path: tuple[str | int, ...], parent_path: str, index: int | None
    ) -> NodeSpec | None:
        doc = file.doc
        self.node_count += 1
        if self.node_count > MAX_TREE_NODES:
            if self.node_count == MAX_TREE_NODES + 1:
                self.problems.append(doc.problem_at(
                    key_path, f"expected at most {MAX_TREE_NODES} nodes in the expanded mission, found more",
                    "includes multiply the tree; include fewer copies", where=parent_path))
            return None
        suffix = f"[{index}]" if index is not None else ""
        found = self._type_and_params(doc, data, key_path, parent_path, suffix)
        if found is None:
            return None
        type_name, params, params_path = found
        line, col = doc.position(params_path, key=True) if params_path != key_path else doc.position(key_path)
        name = params.get(NAME_KEY, type_name)
        label = type_name if NAME_KEY not in params else f"{type_name}({name})"
        path = f"{parent_path}/{label}{suffix}"
        located = doc.view(params_path, params)
        source = Source(doc.file, line, col, file.chain)
        if not isinstance(name, str) or not name:
            self.problems.append(doc.problem_at(
                (*params_path, NAME_KEY), f"expected a non-empty text name, found {shown(name)}",
                "quote the name",
                where=path))
            name = type_name
        if type_name == INCLUDE:
            return self._include(file, params, params_path, path, source, index)
        skipped = (NAME_KEY, CHILD_KEY, CHILDREN_KEY, *CONDITION_KEYS)
        raw = {k: v for k, v in params.items() if k not in skipped}
        children = self._children(file, params, params_path, path)
        child_key = CHILD_KEY if CHILD_KEY in params else CHILDREN_KEY if CHILDREN_KEY in params else None
        return NodeSpec(type=type_name, name=name, raw=raw, children=children, source=source, path=path,
                        located=located, child_key=child_key,
                        conditions={k: params[k] for k in CONDITION_KEYS if k in params})

    def _type_and_params(
        self, doc: Located, data: Any, key_path: tuple[str | int, ...], parent_path: str, suffix: str,
    ) -> tuple[str, dict[str, Any], tuple[str | int, ...]] | None:
        """A node's (type, parameters, parameters' key path), or None with the problem reported."""
        if isinstance(data, str):
            return data, {}, key_path
        if not (isinstance(data, dict) and len(data) == 1):
            found = (
                f"a mapping with {len(data)} keys ({', '.join(map(str, list(data)[:4]))})"
                if isinstance(data, dict) else _kind(data)
            )
            self.problems.append(doc.problem_at(
                key_path, f"expected a node (`Type: {{parameters}}` or a type name), found {found}",
                "write the type as the only key and indent its parameters under it, e.g. `Wait: "
                "{seconds: 2}`",
                where=f"{parent_path}{suffix}"))
            return None
        type_name, params = next(iter(data.items()))
        params_path = (*key_path, type_name)
        if params is None:
            params = {}
        if not isinstance(params, dict):
            self.problems.append(doc.problem_at(
                params_path, f"expected the parameters of {type_name} as a mapping, found {_kind(params)}",
                f"write `{type_name}: {{param: value}}` (or `{type_name}:` alone when it needs none)",
                where=f"{parent_path}/{type_name}{suffix}"))
            return None
        return type_name, params, params_path

    def _children(
        self, file: _File, params: dict[str, Any], params_path: tuple[str | int, ...], path: str,
    ) -> list[NodeSpec]:
        """The nodes under ``child:`` or ``children:`` (problems reported, broken children left out)."""
        doc = file.doc
        if CHILD_KEY in params and CHILDREN_KEY in params:
            self.problems.append(doc.problem_at(
                (*params_path, CHILDREN_KEY), "expected either `child:` or `children:`, found both",
                "a decorator takes `child:` (one node), a composite `children:` (a list)",
                key=True, where=path))
        if CHILD_KEY in params:
            child = self._node(file, params[CHILD_KEY], (*params_path, CHILD_KEY), path, None)
            return [child] if child is not None else []
        children: list[NodeSpec] = []
        if CHILDREN_KEY in params:
            items = params[CHILDREN_KEY]
            if not isinstance(items, list):
                self.problems.append(doc.problem_at(
                    (*params_path, CHILDREN_KEY), f"expected a list of nodes, found {_kind(items)}",
                    "write each child on its own line starting with `- `", where=path))
            else:
                for i, item in enumerate(items):
                    child = self._node(file, item, (*params_path, CHILDREN_KEY, i), path, i)
                    if child is not None:
                        children.append(child)
        return children

    def _include(
        self, file: _File, params: dict[str, Any], params_path: tuple[str | int, ...], path: str,
        source: Source, index: int | None,
    ) -> NodeSpec | None:
        doc = file.doc
        if self.node_count > MAX_TREE_NODES:
            return None  # already reported; stop expanding
        found = self._include_target(file, params, params_path, path)
        if found is None:
            return None
        resolved, given = found
        sub_doc = self._read_subtree(resolved)
        if sub_doc is None:
            return None
        if resolved not in self.files:
            self.files.append(resolved)
        if not self._check_top(sub_doc, is_subtree=True):
            return None
        site = doc.view(params_path, params)
        before = len(self.problems)
        values = self._declared_params(sub_doc, given, (site, path))
        if len(self.problems) > before:
            return None  # the subtree cannot be checked meaningfully with wrong parameters
        line = doc.position((*params_path, "file"))[0]
        sub = _File(resolved, sub_doc, values, (*file.chain, f"{doc.file}:{line}"),
                    (*file.resolved_chain, resolved))
        own_blackboard = self._blackboard(sub)
        substituted = self._substitute(sub_doc.data.get("root"), sub, ("root",), where=path)
        node = self._node(sub, substituted, ("root",), path, None)
        for key, value in {**sub.blackboard, **own_blackboard}.items():
            file.blackboard.setdefault(key, value)
        if node is not None and NAME_KEY in params and isinstance(params[NAME_KEY], str):
            node.name = params[NAME_KEY]
        if node is not None:
            self._include_conditions(node, site, path)
        return node

    def _include_conditions(self, node: NodeSpec, site: Located, path: str) -> None:
        """An Include's conditions go on the subtree's root (the same key on both is a problem)."""
        for key in CONDITION_KEYS:
            if key not in site.data:
                continue
            if key in node.conditions:
                self.problems.append(site.problem_at(
                    (key,), f"expected `{key}` on the Include or on the subtree's root, found both",
                    "keep one of them", key=True, where=path))
                continue
            node.conditions[key] = site.data[key]
            node.condition_sites[key] = site

    def _include_target(
        self, file: _File, params: dict[str, Any], params_path: tuple[str | int, ...], path: str,
    ) -> tuple[Path, dict[str, Any]] | None:
        """An Include's subtree file and given parameter values, or None with the problem reported.

        The file must resolve, must not include itself through the chain of includes, and must lie
        at most :data:`MAX_INCLUDE_DEPTH` includes deep.
        """
        doc = file.doc
        for key in params:
            if key not in ("file", "params", NAME_KEY, *CONDITION_KEYS):
                self.problems.append(doc.problem_at(
                    (*params_path, key),
                    f"expected `file`, `params` or `name` in an Include, found {shown(key)}",
                    "an Include takes `file: path.yaml` and optional `params: {...}`", key=True, where=path))
        target = params.get("file")
        if not isinstance(target, str) or not target:
            self.problems.append(doc.problem_at(
                params_path, f"expected `file:` naming the subtree file, found {shown(target)}",
                "write `Include: {file: subtrees/name.yaml}`", where=path))
            return None
        given = params.get("params") or {}
        if not isinstance(given, dict):
            self.problems.append(doc.problem_at(
                (*params_path, "params"), f"expected a mapping of parameter values, found {_kind(given)}",
                "write `params: {name: value}`", where=path))
            given = {}
        resolved = self._resolve_include(file, target, (*params_path, "file"), path)
        if resolved is None:
            return None
        if resolved in file.resolved_chain:
            cycle = " -> ".join(p.name for p in (*file.resolved_chain, resolved))
            self.problems.append(doc.problem_at(
                (*params_path, "file"), f"expected a subtree that does not include itself, found "
                f"the cycle {cycle}",
                "break the cycle: a subtree must not include a file that includes it", where=path))
            return None
        if len(file.resolved_chain) >= MAX_INCLUDE_DEPTH:
            self.problems.append(doc.problem_at(
                (*params_path, "file"), f"expected includes nested at most {MAX_INCLUDE_DEPTH} "
                f"deep, found deeper",
                "flatten the subtrees", where=path))
            return None
        return resolved, given

    def _read_subtree(self, resolved: Path) -> Located | None:
        """Parse a subtree file once, however often it is included (its problems are reported once)."""
        if resolved not in self._parsed:
            try:
                shown = _display(resolved)
                self._parsed[resolved] = load_yaml(resolved, error=MissionFileError, display_name=shown)
            except MissionFileError as exc:
                self.problems += exc.problems
                self._parsed[resolved] = None
        return self._parsed[resolved]

    def _resolve_include(
        self, file: _File, target: str, key_path: tuple[str | int, ...], path: str
    ) -> Path | None:
        trusted = trusted_tree_dirs()
        candidates = [file.path.resolve().parent / target] + [d / target for d in trusted]
        found = next((c.resolve() for c in candidates if _is_file(c)), None)
        if found is None:
            tried = ", ".join(_display(c) if len(str(c)) <= 200 else f"a path of {len(str(c)):,} characters"
                              for c in candidates[:3])
            self.problems.append(file.doc.problem_at(
                key_path, f"expected an existing subtree file, found no {shown(target)} (looked at {tried})",
                "check the path; it is relative to the including file or to the trees/ folder", where=path))
            return None
        roots = [self.mission_dir, *trusted]
        if not self.allow_outside and not any(found.is_relative_to(r) for r in roots):
            self.problems.append(file.doc.problem_at(
                key_path, f"expected a subtree inside the mission's folder {_display(self.mission_dir)}, "
                f"found {shown(target)} which resolves to {_display(found)}",
                "move the subtree next to the mission, or allow it (--allow-outside)", where=path))
            return None
        return found

    # -- ${param} substitution ----------------------------------------------------------------

    def _substitute(self, value: Any, file: _File, key_path: tuple[str | int, ...], where: str) -> Any:
        """``value`` with ``${name}`` replaced by ``file``'s parameter values (problems collected)."""
        return substitute(value, file.values, file.doc, key_path, where, self.problems)


def _display(path: Path) -> str:
    """A path as short as possible: relative to the working directory when under it."""
    try:
        return str(path.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(path)


def _is_file(path: Path) -> bool:
    """``path.is_file()``, False for a name the system cannot look up (too long, a NUL in it)."""
    try:
        return path.is_file()
    except (OSError, ValueError):
        return False


__all__ = ["INCLUDE", "MAX_INCLUDE_DEPTH", "MAX_TREE_NODES", "check_mission", "load_mission",
           "trusted_tree_dirs"]
