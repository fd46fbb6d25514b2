"""Substitution rules for testing: swap nodes of a loaded tree for stubs, without editing the mission.

As BehaviorTree.CPP 4's ``SubstitutionRules`` / ``TestNodeConfig`` (and py_trees_ros' mocks), a
rules file names nodes by a glob on their path (as the tick log writes it:
``find_object/search/next_candidate/locate_approach_verify/approach_confirm/confirm_looks``) or on
their type (``BuildSceneGraph``), and says what stands in for each::

    rules:
      - match: BuildSceneGraph          # every node of this type
        status: RUNNING                 # never ends, as the real one
      - match: "*/confirm_looks"        # a path glob (* also crosses /)
        status: SUCCESS
        after: 2.0                      # seconds on the robot's clock of RUNNING first
        writes: {verified: true}        # blackboard values written when it returns

The stub (:class:`~missiontree.engine.nodes.stub.Stub`) keeps the node's name, so paths in the
log do not change; a node with children is replaced with its whole subtree; the node's own
conditions (``skip_if`` ...) stay on the stub. The first rule that matches a node wins. A rule that
matches no node (or only nodes inside a subtree an earlier rule replaced) is a problem at its
``file:line:col``, as are unknown keys and bad values: all reported at once, before the robot starts.

:func:`substitute_session` applies rules to an opened session before it runs: every replaced node is a
``substituted`` event in the tick log (after ``mission_started``) and the summary's
``substitutions`` lists them.
"""

from __future__ import annotations

import difflib
import math
import os
import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from fnmatch import fnmatchcase
from pathlib import Path
from typing import Any

import py_trees

from missiontree.engine.build import node_specs_by_behaviour
from missiontree.engine.conditions import attach, conditions_of
from missiontree.engine.node_words import node_paths
from missiontree.engine.nodes.stub import Stub
from missiontree.engine.spec import MissionSpec
from missiontree.errors import MissionFileError, Problem
from missiontree.yamlio import Located, load_yaml
from missiontree.yamlio import short_repr as shown

Behaviour = py_trees.behaviour.Behaviour
Status = py_trees.common.Status

STATUSES = ("SUCCESS", "FAILURE", "RUNNING")
RULE_KEYS = ("match", "status", "after", "writes")
_KEY_RE = re.compile(r"/?[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*\Z")
_HINT = "a rule is {match: GLOB, status: SUCCESS|FAILURE|RUNNING, after: seconds, writes: {key: value}}"


@dataclass(frozen=True)
class Rule:
    """One substitution rule.

    Attributes:
        match: Glob on a node's path or type.
        status: What the stub returns.
        after: Seconds of RUNNING (robot clock) before it does.
        writes: Blackboard values written then.
        index: Position in the file (0-based).
        where: ``file:line:col`` of the rule.
    """

    match: str
    status: str
    after: float = 0.0
    writes: dict[str, Any] = field(default_factory=dict)
    index: int = 0
    where: str = ""

    def describe(self) -> dict[str, Any]:
        """The rule as the summary and the tick log record it."""
        return {"rule": self.index, "match": self.match, "status": self.status, "after": self.after,
                "writes": dict(self.writes), "where": self.where}


@dataclass(frozen=True)
class Substitution:
    """One node replaced: by which rule, its path and its type."""

    rule: Rule
    node: str
    type: str


def load_rules(path: str | os.PathLike[str]) -> list[Rule]:
    """Read and check a rules file.

    Raises:
        MissionFileError: The file is missing, not YAML or a rule is bad (every problem located).
    """
    return parse_rules(load_yaml(Path(path), error=MissionFileError))


def parse_rules(doc: Located) -> list[Rule]:
    """The rules of a parsed rules file (``rules:``, a list of rules).

    Raises:
        MissionFileError: A problem with the file's shape or a rule (all at once, located).
    """
    data = doc.data
    if not isinstance(data, dict) or set(data) != {"rules"} or not isinstance(data["rules"], list):
        raise MissionFileError([doc.problem_at((), "expected a mapping with one key, `rules:`, holding a "
                                               "list of rules", _HINT, where="")])
    problems: list[Problem] = []
    rules = [_rule(doc, index, item, problems) for index, item in enumerate(data["rules"])]
    if not rules:
        problems.append(doc.problem_at(("rules",), "expected at least one rule, found an empty list", _HINT))
    if problems:
        raise MissionFileError(problems)
    return [rule for rule in rules if rule is not None]


def _rule(doc: Located, index: int, item: Any, problems: list[Problem]) -> Rule | None:
    at = ("rules", index)
    if not isinstance(item, dict):
        problems.append(doc.problem_at(at, f"expected a rule (a mapping), found {shown(item)}", _HINT))
        return None
    found = len(problems)
    for key in item:
        if key not in RULE_KEYS:
            near = difflib.get_close_matches(str(key), RULE_KEYS, n=1)
            problems.append(doc.problem_at((*at, key), f"expected one of {', '.join(RULE_KEYS)}, found "
                                           f"{shown(key)}", f"did you mean {near[0]}?" if near else _HINT,
                                           key=True))
    match = item.get("match")
    if not isinstance(match, str) or not match.strip():
        problems.append(doc.problem_at((*at, "match"), f"expected a glob on a node's path or type, found "
                                       f"{shown(match)}", _HINT))
    status = item.get("status", "SUCCESS")
    if status not in STATUSES:
        problems.append(doc.problem_at((*at, "status"), f"expected SUCCESS, FAILURE or RUNNING, found "
                                       f"{shown(status)}"))
    after = item.get("after", 0.0)
    number = isinstance(after, int | float) and not isinstance(after, bool)
    if not number or not (math.isfinite(after) and after >= 0):
        problems.append(doc.problem_at((*at, "after"),
                                       f"expected seconds (a number >= 0), found {shown(after)}"))
    writes = item.get("writes", {})
    if not isinstance(writes, dict):
        problems.append(doc.problem_at((*at, "writes"), f"expected a mapping of blackboard keys to values, "
                                       f"found {shown(writes)}"))
        writes = {}
    for key in writes:
        if not isinstance(key, str) or not _KEY_RE.match(key):
            problems.append(doc.problem_at((*at, "writes", key), f"expected a blackboard key name, found "
                                           f"{shown(key)}", key=True))
    if len(problems) > found:
        return None
    line, col = doc.position(at)
    return Rule(match=str(match), status=str(status), after=float(after), writes=dict(writes), index=index,
                where=f"{doc.file}:{line}:{col}")


def apply_rules(spec: MissionSpec, root: Behaviour,
                rules: Iterable[Rule]) -> tuple[Behaviour, list[Substitution]]:
    """Replace every node a rule matches by a stub; return the (possibly new) root and what was replaced.

    ``root`` must be the tree built from ``spec`` and not yet set up or ticked.

    Raises:
        MissionFileError: A rule matches no node (or only nodes an earlier rule's replacement removed).
    """
    rules = list(rules)
    specs = node_specs_by_behaviour(spec, root)
    paths = node_paths(root)
    types = {node: specs[node.id].type for node in paths}
    matched: dict[int, list[str]] = {rule.index: [] for rule in rules}
    chosen: dict[Behaviour, Rule] = {}
    for node, path in paths.items():
        for rule in rules:
            if fnmatchcase(path, rule.match) or fnmatchcase(types[node], rule.match):
                matched[rule.index].append(path)
                chosen.setdefault(node, rule)
    done: list[Substitution] = []
    replaced: dict[Behaviour, Rule] = {}
    for node in sorted(chosen, key=lambda n: paths[n]):  # parents before children
        if any(ancestor in replaced for ancestor in _ancestors(node)):
            continue
        replaced[node] = chosen[node]
        done.append(Substitution(chosen[node], paths[node], types[node]))
    problems = _unmatched(rules, matched, done, paths, types, spec)
    if problems:
        raise MissionFileError(problems)
    for node, rule in replaced.items():
        root = _replace(root, node, _stub(node, rule, types[node]))
    return root, done


def _ancestors(node: Behaviour) -> Iterable[Behaviour]:
    parent = node.parent
    while parent is not None:
        yield parent
        parent = parent.parent


def _unmatched(rules: list[Rule], matched: dict[int, list[str]], done: list[Substitution],
               paths: dict[Behaviour, str], types: dict[Behaviour, str], spec: MissionSpec) -> list[Problem]:
    used = {sub.rule.index for sub in done}
    problems: list[Problem] = []
    for rule in rules:
        if rule.index in used:
            continue
        file, line, col = rule.where.rsplit(":", 2)
        if matched[rule.index]:
            message = (f"expected a rule that replaces a node, found {shown(rule.match)} matching only "
                       f"{', '.join(matched[rule.index][:3])}, inside a subtree an earlier rule replaced")
            hint = "drop the rule, or match the subtree's node instead of its parent"
        else:
            message = (f"expected a glob matching a node's path or type, found {shown(rule.match)} "
                       "matching none")
            near = difflib.get_close_matches(rule.match, sorted({*paths.values(), *types.values()}), n=3)
            hint = (f"did you mean {' or '.join(near)}?" if near else
                    f"paths look like {next(iter(paths.values()))}/...; * also matches /")
        problems.append(Problem(file, int(line), int(col), f"rules[{rule.index}].match",
                                f"{message} in {spec.path.name}", hint))
    return problems


def _stub(node: Behaviour, rule: Rule, node_type: str) -> Stub:
    status = {"SUCCESS": Status.SUCCESS, "FAILURE": Status.FAILURE, "RUNNING": Status.RUNNING}[rule.status]
    stub = Stub(node.name, status=status, after=rule.after, writes=rule.writes, rule=rule.where,
                replaced=node_type)
    conditions = conditions_of(node)
    if conditions is not None:  # the mission's own logic on the node stays
        attach(stub, conditions)
    return stub


def _replace(root: Behaviour, old: Behaviour, new: Behaviour) -> Behaviour:
    """Put ``new`` where ``old`` is in the tree; return the root (``new`` when ``old`` was the root)."""
    parent = old.parent
    if parent is None:
        return new if old is root else root
    index = next(i for i, child in enumerate(parent.children) if child is old)
    parent.children[index] = new
    new.parent = parent
    if getattr(parent, "decorated", None) is old:
        parent.decorated = new  # type: ignore[attr-defined]  # a py_trees Decorator's alias of its child
    policy = getattr(parent, "policy", None)
    selected = getattr(policy, "children", None)
    if isinstance(selected, list):  # Parallel's success_on_selected names its children as objects
        policy.children = [new if child is old else child for child in selected]  # type: ignore[union-attr]
    return root


def substitute_session(session: Any, rules: Iterable[Rule]) -> list[Substitution]:
    """Apply ``rules`` to an opened :class:`~missiontree.session.mission.Session` before it runs.

    The session's tree (and its runner's) is replaced; the tick log gets one ``substituted`` event per
    replaced node after ``mission_started``, and the summary a ``substitutions`` list.

    Raises:
        MissionFileError: A rule matches no node.
    """
    root, done = apply_rules(session.spec, session.root, rules)
    session.root = root
    session.runner.root = root
    announce(session.runner, done)
    return done


def announce(runner: Any, done: list[Substitution]) -> None:
    """Have ``runner`` log a ``substituted`` event per node at the start and list them in its summary."""
    runner.hook = _Announce(runner.hook, done)
    described = [{**sub.rule.describe(), "node": sub.node, "type": sub.type} for sub in done]
    add_to_final_state(runner, "substitutions", described)


def add_to_final_state(runner: Any, key: str, value: Any) -> None:
    """Have the summary's final state say ``key: value`` too, after what ``runner.final_state`` said before.

    The one way to chain onto a runner's ``final_state`` (the summary's extra keys), keeping what is there.
    """
    earlier = runner.final_state

    def final_state() -> dict[str, Any]:
        found = dict(earlier()) if earlier is not None else {}
        found[key] = value
        return found

    runner.final_state = final_state


class _Announce:
    """A plugin hook relay that first writes the substitutions into the tick log as the mission starts."""

    def __init__(self, hook: Any, done: list[Substitution]) -> None:
        self._hook = hook
        self._done = done

    def missiontree_mission_started(self, **kwargs: Any) -> None:
        context = kwargs.get("context")
        for sub in self._done:
            if context is not None:
                context.events.emit("substituted", node=sub.node, type=sub.type, rule=sub.rule.index,
                                    match=sub.rule.match, status=sub.rule.status, after=sub.rule.after,
                                    writes=sub.rule.writes, where=sub.rule.where)
        if self._hook is not None:
            self._hook.missiontree_mission_started(**kwargs)

    def __getattr__(self, name: str) -> Any:
        if self._hook is None:  # the runner calls every hook: without plugins, nothing to relay
            return _nothing
        return getattr(self._hook, name)


def _nothing(**kwargs: Any) -> None:
    """A hook with nothing behind it."""


__all__ = ["STATUSES", "Rule", "Substitution", "add_to_final_state", "announce", "apply_rules", "load_rules",
           "parse_rules", "substitute_session"]
