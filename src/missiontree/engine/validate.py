"""Check every node of a mission against its registered type, and report every problem at once.

For each node: the type must be registered (else the nearest known names and their providers are
suggested); the node must have the children its category allows (a leaf none, a decorator one
``child:``, a composite a ``children:`` list); its parameters must validate against the type's
pydantic ``Params`` model, where ``{bb: key}`` is accepted for any parameter and kept as a
:class:`~missiontree.engine.ports.BlackboardRef`. Finally every ``{bb: key}`` must name a key that
something writes: a ``blackboard:`` default or a node's output port.

Each problem reads ``file:line:col: node path: expected …, found … (hint: …)``.
"""

from __future__ import annotations

import difflib
import math
import re
import types
import typing
from dataclasses import dataclass
from typing import Any

from pydantic import BaseModel, TypeAdapter, ValidationError

from missiontree.engine.condition_check import assigned_keys, check_conditions
from missiontree.engine.ports import BlackboardRef, ports_of
from missiontree.engine.registry import NodeRegistry, NodeType
from missiontree.engine.spec import CHILD_KEY, CHILDREN_KEY, MissionSpec, NodeSpec
from missiontree.errors import Problem
from missiontree.yamlio import expected_text, format_path, short_repr, written_loc

_UNRESOLVED = re.compile(r"(?<!\$)\$\{[^}]*\}")


@dataclass(frozen=True)
class ParamIssue:
    """One parameter problem, before it is given a file position.

    Attributes:
        loc: Path inside the parameter mapping (``("seconds",)``), empty for the whole mapping.
        message: What was expected and what was found.
        hint: How to fix it.
        at_key: Locate at the key (unknown parameter) rather than at the value.
    """

    loc: tuple[str | int, ...]
    message: str
    hint: str = ""
    at_key: bool = False


def is_ref(value: Any) -> bool:
    """Whether a written value is a blackboard reference ``{bb: key}``."""
    bb = value.get("bb") if isinstance(value, dict) and len(value) == 1 else None
    return isinstance(bb, str) and bb != ""


def validate_params(
    model: type[BaseModel], raw: dict[str, Any]
) -> tuple[BaseModel | None, list[ParamIssue]]:
    """Validate written parameters against a node type's Params model.

    ``{bb: key}`` values are accepted for any parameter that is not itself a port, and kept as
    :class:`BlackboardRef` in the returned instance (the leaf reads them when it starts).

    Returns:
        (instance or None, issues): the instance is None when there are issues.
    """
    issues: list[ParamIssue] = list(non_finite_issues(raw))
    fields = model.model_fields
    by_name = {(info.alias or name): name for name, info in fields.items()}
    refs, plain = _split_references(model, raw, by_name, issues)
    if refs:  # fields typed Any (a compared value) take the reference as it is, validators included
        try:
            alias = {name: fields[name].alias or name for name in refs}
            whole = model.model_validate({**plain, **{alias[n]: ref for n, ref in refs.items()}})
            if all(getattr(whole, name) is ref for name, ref in refs.items()):
                return whole, []
        except (ValidationError, TypeError, ValueError):
            pass  # typed fields refuse a reference: check the others alone below
    instance: BaseModel | None = None
    try:
        instance = model.model_validate(plain)
    except (ValidationError, TypeError, ValueError) as exc:  # a buggy Params model may raise plainly
        if not isinstance(exc, ValidationError):
            return None, [ParamIssue((), f"expected the parameters to pass the node type's own checks, but "
                                     f"they raised {type(exc).__name__}: {exc}",
                                     "a bug in the node type's Params model; report it to its provider")]
        issues += _validation_issues(model, exc, plain, refs)
    if issues:
        return None, issues
    if not refs:
        return instance, []
    values: dict[str, Any] = {}
    for name, info in fields.items():
        if name in refs:
            values[name] = refs[name]
        elif instance is not None:
            values[name] = getattr(instance, name)
        elif (info.alias or name) in plain:
            adapter = TypeAdapter(info.annotation)  # type: ignore[arg-type]  # a declared field is annotated
            values[name] = adapter.validate_python(plain[info.alias or name])
    return model.model_construct(_fields_set={*refs, *(by_name[k] for k in plain)}, **values), []


def _split_references(
    model: type[BaseModel], raw: dict[str, Any], by_name: dict[str, str], issues: list[ParamIssue],
) -> tuple[dict[str, BlackboardRef], dict[str, Any]]:
    """Written parameters as (blackboard references by field name, plain values by written key).

    Unknown keys and references written for a port are added to ``issues`` and left out.
    """
    ports = ports_of(model)
    refs: dict[str, BlackboardRef] = {}
    plain: dict[str, Any] = {}
    for key, value in raw.items():
        if key not in by_name:
            near = difflib.get_close_matches(key, list(by_name), n=1)
            known = ", ".join(by_name) or "none"
            issues.append(ParamIssue(
                (key,), f"expected one of the parameters ({known}), found {short_repr(key)}",
                f"did you mean {near[0]!r}?" if near else "remove it (`missiontree nodes` lists parameters)",
                at_key=True,
            ))
        elif is_ref(value):
            if by_name[key] in ports:
                issues.append(ParamIssue(
                    (key,), f"expected a blackboard key name for port {key!r}, found a {{bb: ...}} reference",
                    f"a port already names its key: write `{key}: {value['bb']}`",
                ))
            else:
                refs[by_name[key]] = BlackboardRef(value["bb"])
        else:
            plain[key] = value
    return refs, plain


def _validation_issues(
    model: type[BaseModel], exc: ValidationError, plain: dict[str, Any], refs: dict[str, BlackboardRef],
) -> list[ParamIssue]:
    """The validation errors as issues, one per written key (a union's alternatives merged into one)."""
    by_loc: dict[tuple[str | int, ...], list[Any]] = {}
    for err in exc.errors():
        loc = tuple(err["loc"])
        if err["type"] == "missing" and loc and loc[0] in refs:
            continue
        if isinstance(err.get("input"), str) and _UNRESOLVED.search(err["input"]):
            continue  # an unknown ${param}: the loader reported it where it was written
        # drop union-member tags (``int``, ``str``...) that pydantic puts in loc: keep written keys
        by_loc.setdefault(written_loc(plain, loc, err["type"]), []).append(err)
    issues = []
    for loc, errs in by_loc.items():
        merged = dict(errs[0], loc=loc)
        if len(errs) > 1 and all(e["type"] not in ("missing", "extra_forbidden") for e in errs):
            merged["msg"] = " or ".join(dict.fromkeys(expected_text(e) for e in errs))
            merged["type"] = "union"
        issues.append(_issue(model, merged))
    return issues


def non_finite_issues(value: Any, loc: tuple[str | int, ...] = ()) -> list[ParamIssue]:
    """Every NaN or infinite number in a written value (YAML's ``.nan``, ``.inf``), where it is."""
    if isinstance(value, float) and not math.isfinite(value):
        return [ParamIssue(loc, f"{format_path(loc) + ': ' if loc else ''}expected a finite number, "
                           f"found {value!r}", "write a real number; NaN and infinity are never valid")]
    if isinstance(value, dict):
        return [i for k, v in value.items() for i in non_finite_issues(v, (*loc, k))]
    if isinstance(value, list):
        return [i for n, v in enumerate(value) for i in non_finite_issues(v, (*loc, n))]
    return []


def _issue(model: type[BaseModel], err: Any) -> ParamIssue:
    loc = tuple(err["loc"])
    name = str(loc[0]) if loc else ""
    info = model.model_fields.get(name)
    doc = info.description if info is not None and info.description else ""
    if err["type"] == "missing" and name == "memory" and info is not None and info.annotation is bool:
        return ParamIssue(loc[:-1], "expected `memory: true` or `memory: false` (stated), found none",
                          "true resumes the RUNNING child next tick (a plan of steps); false restarts from "
                          "the first child every tick (earlier children are re-checked)")
    if err["type"] == "missing" and len(loc) > 1:
        return ParamIssue(loc[:-1], f"{format_path(loc[:-1])}: expected key {loc[-1]!r}, found none",
                          f"add `{loc[-1]}: ...`" + (f" ({doc})" if doc else ""))
    if err["type"] == "missing":
        kind = type_label(info.annotation) if info is not None else "a value"
        hint = f"add `{name}: ...`" + (f" ({doc})" if doc else "")
        return ParamIssue(loc[:-1], f"expected parameter {name!r} ({kind}), found none", hint)
    if err["type"] == "extra_forbidden":
        return ParamIssue(loc, f"expected no parameter {'.'.join(map(str, loc))!r}, found one", "remove it",
                          at_key=True)
    msg = expected_text(err)
    where = format_path(loc)
    found = err.get("input")
    found_text = ("nothing" if found is None else short_repr(found) if not isinstance(found, dict)
                  else "a mapping")
    if err["type"] == "value_error":
        return ParamIssue(loc, f"{where}: {msg}" if where else msg, doc)
    return ParamIssue(loc, f"{where}: expected {msg}, found {found_text}" if where else f"expected {msg}",
                      doc or "fix the value")


def type_label(annotation: Any) -> str:
    """A short, readable name of a parameter's type: ``number``, ``text``, ``one of 'a', 'b'``."""
    origin = typing.get_origin(annotation)
    if origin is typing.Annotated:
        return type_label(typing.get_args(annotation)[0])
    if origin is typing.Literal:
        return "one of " + ", ".join(repr(a) for a in typing.get_args(annotation))
    if origin in (typing.Union, types.UnionType):
        return " or ".join(type_label(a) for a in typing.get_args(annotation) if a is not type(None))
    if origin in (list, tuple, set):
        args = typing.get_args(annotation)
        return f"list of {type_label(args[0])}" if args else "list"
    if origin is dict:
        return "mapping"
    names = {bool: "true/false", int: "integer", float: "number", str: "text", type(None): "nothing"}
    if annotation in names:
        return names[annotation]
    if annotation is Any:
        return "any value"
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return f"mapping ({', '.join(annotation.model_fields)})"
    return getattr(annotation, "__name__", str(annotation))


# -- the whole tree ---------------------------------------------------------------------------------


def check_tree(spec: MissionSpec, registry: NodeRegistry) -> list[Problem]:
    """Check every node of ``spec`` (setting each node's ``params`` and ``category``); return all problems."""
    problems: list[Problem] = []
    for node in spec.nodes():
        problems += check_node(node, registry)
    problems += _dangling_refs(spec)
    problems += _default_types(spec, registry)
    problems += check_conditions(spec)
    return problems


def check_node(node: NodeSpec, registry: NodeRegistry) -> list[Problem]:
    """Check one node (not its children) against its type."""
    node_type = registry.get(node.type)
    if node_type is None:
        return [_unknown_type(node, registry)]
    node.category = node_type.category
    problems = _structure(node, node_type)
    instance, issues = validate_params(node_type.params, node.raw)
    node.params = instance
    if instance is not None and node_type.category != "leaf":
        issues += _refs_not_read(node_type, instance)
        if issues:
            node.params = None
    for issue in issues:
        problems.append(_locate(node, issue))
    if instance is not None and node.type == "Parallel":
        problems += _parallel_selection(node, instance)
    return problems


def reads_refs(node_type: NodeType, field_name: str) -> bool:
    """Whether ``{bb: key}`` is accepted for a parameter of ``node_type``.

    Always for leaves (:meth:`~missiontree.engine.leaf.Leaf.value` reads it); for decorators and
    composites only where the field says so (``json_schema_extra={"bb_ref": True}``).
    """
    if node_type.category == "leaf":
        return True
    info = node_type.params.model_fields.get(field_name)
    extra = info.json_schema_extra if info is not None else None
    return isinstance(extra, dict) and extra.get("bb_ref") is True


def _refs_not_read(node_type: NodeType, params: BaseModel) -> list[ParamIssue]:
    return [
        ParamIssue((name,), f"{name}: expected a fixed value ({node_type.name} is a {node_type.category} and "
                   f"reads no blackboard), found {{bb: {value.key}}}",
                   "write the value itself; only leaves (and Guard's value) read {bb: key} references")
        for name in type(params).model_fields
        if isinstance(value := getattr(params, name, None), BlackboardRef) and not reads_refs(node_type, name)
    ]


def _locate(node: NodeSpec, issue: ParamIssue) -> Problem:
    if node.located is None or not issue.loc:
        src = node.source
        return Problem(src.file, src.line, src.col, node.path, issue.message, issue.hint)
    return node.located.problem_at(issue.loc, issue.message, issue.hint, key=issue.at_key, where=node.path)


def _unknown_type(node: NodeSpec, registry: NodeRegistry) -> Problem:
    near = registry.nearest(node.type)
    if near:
        named = ", ".join(f"{n} (from {registry.get(n).provider})" for n in near)  # type: ignore[union-attr]
        hint = f"did you mean {named}? If a plugin provides it, install it (`missiontree plugins` lists them)"
    else:
        hint = "`missiontree nodes` lists every known type; a plugin that provides it may not be installed"
    return Problem(node.source.file, node.source.line, node.source.col, node.path,
                   f"expected a known node type, found {short_repr(node.type)}", hint)


def _structure(node: NodeSpec, node_type: NodeType) -> list[Problem]:
    def problem(message: str, hint: str) -> Problem:
        key = node.child_key
        if node.located is not None and key is not None:
            return node.located.problem_at((key,), message, hint, key=True, where=node.path)
        return Problem(node.source.file, node.source.line, node.source.col, node.path, message, hint)

    if node_type.category == "leaf" and node.child_key is not None:
        return [problem(f"expected no children ({node.type} is a leaf), found `{node.child_key}:`",
                        "remove the children, or wrap them in a Sequence or Selector")]
    if node_type.category == "decorator":
        if node.child_key == CHILDREN_KEY:
            return [problem(f"expected one `child:` ({node.type} is a decorator), found `children:`",
                            "write `child:` with one node; wrap several in a Sequence")]
        if node.child_key is None:
            return [problem(f"expected one `child:` ({node.type} is a decorator), found none",
                            f"add `child:` with the node that {node.type} decorates")]
    if node_type.category == "composite":
        if node.child_key == CHILD_KEY:
            return [problem(f"expected `children:` (a list; {node.type} is a composite), found `child:`",
                            "write `children:` followed by `- Node: ...` lines")]
        if not node.children and node.child_key is None:
            return [problem("expected `children:` with at least one node, found none",
                            f"add `children:` under {node.type}")]
        written = node.located.data.get(CHILDREN_KEY) if node.located is not None else None
        if written == []:
            return [problem("expected at least one child, found an empty list", "add children or remove it")]
    return []


def _parallel_selection(node: NodeSpec, params: BaseModel) -> list[Problem]:
    from missiontree.engine.nodes.composites import ParallelParams, selected_children

    assert isinstance(params, ParallelParams)
    names = [c.name for c in node.children]
    indices, unknown = selected_children(params, names)
    issue: ParamIssue | None = None
    if params.policy == "success_on_selected" and (unknown or not indices):
        found = ", ".join(unknown) or "none"
        issue = ParamIssue(("selected",), f"expected `selected` to name children ({', '.join(names)}) or "
                           f"their indices, found {found}",
                           "list the children that must succeed, by name or 0-based index")
    elif params.policy != "success_on_selected" and params.selected:
        issue = ParamIssue(("selected",), f"expected no `selected` with policy {params.policy!r}, found some",
                           "use `policy: success_on_selected`, or remove `selected`", at_key=True)
    return [_locate(node, issue)] if issue is not None else []


def written_keys(spec: MissionSpec) -> set[str]:
    """Blackboard keys something in the mission writes: defaults, output ports, assignments (post, Script)."""
    keys = {_root_key(k) for k in spec.blackboard} | assigned_keys(spec)
    for node in spec.nodes():
        if node.params is None:
            continue
        for field_name, port in ports_of(type(node.params)).items():
            value = getattr(node.params, field_name, None)
            if port.direction == "out" and isinstance(value, str):
                keys.add(_root_key(value))
    return keys


def _dangling_refs(spec: MissionSpec) -> list[Problem]:
    written = written_keys(spec)
    problems: list[Problem] = []
    for node in spec.nodes():
        if node.params is None:
            continue
        for field_name in type(node.params).model_fields:
            value = getattr(node.params, field_name, None)
            if isinstance(value, BlackboardRef) and _root_key(value.key) not in written:
                near = difflib.get_close_matches(value.key, sorted(written), n=1)
                hint = (f"did you mean {{bb: {near[0]}}}?" if near else
                        f"add `{value.key}: ...` under `blackboard:`, or let a node write it")
                message = (f"{field_name}: expected a blackboard key that the mission sets or a node writes, "
                           f"found {{bb: {value.key}}} which nothing writes")
                problems.append(_locate(node, ParamIssue((field_name,), message, hint)))
    return problems


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


#: Checks of a blackboard value against a port's declared type (types not listed are not checked).
PORT_TYPES: dict[str, Any] = {
    "str": lambda v: isinstance(v, str),
    "int": lambda v: isinstance(v, int) and not isinstance(v, bool),
    "float": _is_number,
    "bool": lambda v: isinstance(v, bool),
    "dict": lambda v: isinstance(v, dict),
    "list": lambda v: isinstance(v, list),
    "list[str]": lambda v: isinstance(v, list) and all(isinstance(x, str) for x in v),
}


def _default_types(spec: MissionSpec, registry: NodeRegistry | None = None) -> list[Problem]:
    """Blackboard defaults checked against the type of every parameter or input port that reads them.

    ``goal_x: "six"`` under ``blackboard:`` read by ``NavigateTo: {x: {bb: goal_x}}`` is reported at
    the ``{bb: goal_x}`` with the default's value, before the run rather than when the leaf starts.
    """
    problems: list[Problem] = []
    for node in spec.nodes():
        for field_name, port in ports_of(type(node.params)).items() if node.params is not None else ():
            key = getattr(node.params, field_name, None)
            if port.direction != "in" or not isinstance(key, str) or key not in spec.blackboard:
                continue
            check = PORT_TYPES.get(port.type)
            if check is not None and not check(spec.blackboard[key]):
                problems.append(_locate(node, ParamIssue(
                    (field_name,), f"{field_name}: expected the blackboard default {key!r} to be {port.type} "
                    f"(the type of the port that reads it), found {short_repr(spec.blackboard[key])}",
                    f"fix `{key}:` under `blackboard:`")))
        for field_name, info, value in _refs_of(node, registry):
            if value.key not in spec.blackboard:
                continue
            default = spec.blackboard[value.key]
            try:
                TypeAdapter(info.annotation).validate_python(default)
            except (ValidationError, TypeError, ValueError):
                expected = type_label(info.annotation)
                message = (f"{field_name}: expected {expected} in the blackboard default {value.key!r} "
                           f"(this parameter reads it), found {short_repr(default)}")
                problems.append(_locate(node, ParamIssue(
                    (field_name,), message, f"fix `{value.key}:` under `blackboard:`")))
    return problems


def _refs_of(node: NodeSpec, registry: NodeRegistry | None) -> list[tuple[str, Any, BlackboardRef]]:
    """(field, field info, reference) for every ``{bb: key}`` of a node.

    Also for a node whose other parameters have problems (read from what was written), so every
    problem is reported at once.
    """
    if node.params is not None:
        return [(name, info, value) for name, info in type(node.params).model_fields.items()
                if isinstance(value := getattr(node.params, name, None), BlackboardRef)]
    node_type = registry.get(node.type) if registry is not None else None
    if node_type is None:
        return []
    fields = node_type.params.model_fields
    by_name = {(info.alias or name): name for name, info in fields.items()}
    return [(by_name[key], fields[by_name[key]], BlackboardRef(value["bb"]))
            for key, value in node.raw.items() if key in by_name and is_ref(value)]


def _root_key(key: str) -> str:
    return key.lstrip("/").split(".", 1)[0]
