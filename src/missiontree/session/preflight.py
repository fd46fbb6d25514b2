"""Everything a mission references, checked before the run: world, robot, models, waypoint files.

:func:`~missiontree.engine.loader.load_mission` checks the mission file itself (nodes, parameters,
blackboard defaults against the parameters that read them). This module checks what the file
*names*, as the run will use it (flags first, then the mission's ``run:`` section, then defaults):

- the world (simulator only): found, and valid as a whole (its own ``file:line:col`` problems);
- the robot profile and the models config: found and valid, the model files its providers name
  inside its folder (or ``$MISSIONTREE_MODEL_PATH``) and within their size limits;
- every waypoint file a node names (a parameter called ``waypoints_file``, with ``route``): found
  beside the mission or under config/waypoints/, valid, written for this world (its ``world:``),
  and every waypoint inside the world's map and outside its obstacles; inline ``waypoints`` lists
  too;
- when the mission names its world (``run.world`` or ``--world``): every literal goal of a motion
  leaf (parameters ``x`` and ``y``, as NavigateTo's) inside the map, outside obstacles and at
  least a robot radius from them, as the navigator will require when the goal is sent.

A name that cannot be found is reported where the mission wrote it (``run.world`` or the node's
parameter), as ``file:line:col``. A waypoint file found beside the mission is handed to the node as
an absolute path, so the run reads the file that was checked. ``missiontree validate`` and
:class:`~missiontree.session.mission.Session` call :func:`check_references`.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from missiontree.behaviours.waypoints import misfits, parse_waypoints, read_waypoint_file
from missiontree.engine.ports import BlackboardRef
from missiontree.engine.spec import MissionSpec, NodeSpec
from missiontree.errors import ConfigError, MissionTreeError, Problem, ProblemsError
from missiontree.yamlio import Located, load_yaml, validation_problems

#: The backend used when neither a flag nor the mission names one.
DEFAULT_BACKEND = "sim"
#: The simulator's world when none is named.
DEFAULT_WORLD = "office"
#: Parameters that name a waypoint file (with ``route``), and inline routes, on any node type.
WAYPOINTS_FILE_PARAM = "waypoints_file"
WAYPOINTS_PARAM = "waypoints"
#: The parameters of a motion leaf's goal (NavigateTo's ``x`` and ``y``), checked against a named world.
GOAL_X, GOAL_Y = "x", "y"
#: Keys of a models config's role section that are the wiring's, not the provider's options.
MODEL_ROLE_KEYS = frozenset({"provider", "latency", "timeout"})


def resolve_mission_path(mission: Path, value: str) -> str:
    """A path written in a mission resolves relative to the mission file (as ``Include`` does)."""
    if not value.endswith((".yaml", ".yml")) or Path(value).is_absolute():
        return value
    beside = mission.resolve().parent / value
    return str(beside) if beside.is_file() else value


def check_references(
    spec: MissionSpec,
    *,
    providers: Mapping[str, Any] | None = None,
    backend: str | None = None,
    world: str | None = None,
    robot: str | None = None,
    models: str | os.PathLike[str] | Mapping[str, Any] | None = None,
    check_models: bool = True,
) -> list[Problem]:
    """Check what the mission references; return every problem (empty when all is well).

    Args:
        spec: The loaded mission (its waypoint parameters may be rewritten to absolute paths).
        providers: Model provider names → factories; unknown providers are problems when given.
        backend: The command line's backend; None takes the mission's, then ``sim``.
        world: The command line's world; None takes the mission's, then ``office``.
        robot: The command line's robot profile; None takes the mission's, then the world's.
        models: The command line's models config; None takes the mission's, then the default.
        check_models: Check the models config too (a caller that builds the models right after,
            which checks the config whole first, may leave it out).
    """
    problems, loaded_world = _run_references(spec, providers, backend, world, robot, models, check_models)
    problems += _check_waypoints(spec, loaded_world)
    return problems


def _run_references(spec: MissionSpec, providers: Mapping[str, Any] | None, backend: str | None,
                    world: str | None, robot: str | None, models: Any,
                    check_models: bool) -> tuple[list[Problem], Any]:
    doc = _mission_doc(spec)
    run = spec.run
    problems: list[Problem] = []
    backend = backend or run.backend or DEFAULT_BACKEND
    loaded_world = None
    if backend == "sim":
        loaded_world, world_problems = _check_world(spec, doc, world)
        problems += world_problems
        robot_name = robot or run.robot or (loaded_world.profile_name if loaded_world is not None else None)
        profile = None
        if robot_name is not None:
            robot_problems, profile = _check_robot(spec, doc, robot_name,
                                                   from_file=robot is None and run.robot is not None)
            problems += robot_problems
        named = world is not None or run.world is not None
        if named and loaded_world is not None and profile is not None:
            problems += _check_goals(spec, loaded_world, profile)
    if check_models:
        problems += _check_models(spec, doc, models, providers)
    return problems, loaded_world


def _mission_doc(spec: MissionSpec) -> Located | None:
    try:
        return load_yaml(spec.path)
    except ProblemsError:
        return None


def _at_run(spec: MissionSpec, doc: Located | None, key: str, message: str, hint: str = "") -> Problem:
    """A problem at ``run.<key>`` of the mission (or at the file when the key is not there)."""
    if doc is not None and doc.has(("run", key)):
        return doc.problem_at(("run", key), message, hint, where=f"run.{key}")
    return Problem(str(spec.path), 0, 0, f"run.{key}" if doc is None else "", message, hint)


def _relocate(spec: MissionSpec, doc: Located | None, key: str, name: str, problems: list[Problem],
              from_file: bool) -> list[Problem]:
    """Problems that only say "not found" (no line) are moved to where the mission named the file."""
    moved = []
    for p in problems:
        if from_file and p.line == 0 and p.file == name:
            moved.append(_at_run(spec, doc, key, p.message, p.hint or f"fix `{key}:` in the run section"))
        elif p.line == 0 and p.file == name:
            moved.append(Problem(f"--{key}", 0, 0, "", p.message, p.hint))
        else:
            moved.append(p)
    return moved


def _check_world(spec: MissionSpec, doc: Located | None, flag: str | None) -> tuple[Any, list[Problem]]:
    from missiontree.backends.sim import load_world
    from missiontree.errors import WorldFileError

    from_file = flag is None and spec.run.world is not None
    name = flag or spec.run.world or DEFAULT_WORLD
    if from_file:
        name = resolve_mission_path(spec.path, name)
    try:
        return load_world(name), []
    except WorldFileError as exc:
        return None, _relocate(spec, doc, "world", name, exc.problems, from_file)


def _check_robot(spec: MissionSpec, doc: Located | None, name: str, from_file: bool
                 ) -> tuple[list[Problem], Any]:
    """The robot profile's problems, and the profile (None when it does not load)."""
    from missiontree.backends.sim import load_robot_profile
    from missiontree.errors import WorldFileError

    if from_file:
        name = resolve_mission_path(spec.path, name)
    try:
        return [], load_robot_profile(name)
    except WorldFileError as exc:
        return _relocate(spec, doc, "robot", name, exc.problems, from_file), None


def goal_misfit(world: Any, profile: Any, x: float, y: float) -> str | None:
    """Why the goal (x, y) cannot be reached in ``world`` by the robot of ``profile``, or None.

    The navigator's own test at the goal (outside the map, inside an obstacle, or inside the zone
    one robot radius around one: the inflated costmap's inscribed cost), so a goal that would fail
    when sent is refused before the run.
    """
    from missiontree.mapping import planner

    if not (math.isfinite(x) and math.isfinite(y)):
        return None   # the leaf reports a goal that is not a finite pose itself
    grid, radius = world.grid, float(profile.body.radius)
    nav = profile.navigation
    costmap = planner.Costmap(grid, radius, nav.inflation_radius, nav.cost_scaling, allow_unknown=False,
                              accelerate=profile.accelerate)
    if costmap.cost_at(x, y) <= planner.MAX_FREE:
        return None
    rows, cols = grid.data.shape
    x0, y0 = grid.origin.x, grid.origin.y
    x1, y1 = x0 + cols * grid.resolution, y0 + rows * grid.resolution
    if not costmap.contains(x, y):
        return f"outside the map ({x0:.1f}..{x1:.1f}, {y0:.1f}..{y1:.1f})"
    if costmap.cost_at(x, y) >= planner.LETHAL:
        return "inside an obstacle"
    gap = float(world.clearance(x, y))
    return f"inside an obstacle's inscribed zone ({gap:.2f} m from it, robot radius {radius:.2f} m)"


def _check_goals(spec: MissionSpec, world: Any, profile: Any) -> list[Problem]:
    """Literal goals of motion leaves (a node whose parameters hold ``x`` and ``y``) against the world.

    A goal read from the blackboard (``{bb: key}``) is known only when the leaf starts, and is not
    checked here.
    """
    problems: list[Problem] = []
    for node in spec.nodes():
        params = node.params
        if params is None or not {GOAL_X, GOAL_Y} <= set(type(params).model_fields):
            continue
        x, y = getattr(params, GOAL_X), getattr(params, GOAL_Y)
        if not all(isinstance(v, int | float) and not isinstance(v, bool) for v in (x, y)):
            continue
        why = goal_misfit(world, profile, float(x), float(y))
        if why is not None:
            problems.append(_at_param(
                node, GOAL_X, f"expected a goal the robot can reach in the world {world.name!r}, found "
                f"({float(x):g}, {float(y):g}) {why}",
                "move the goal into free space, at least a robot radius from obstacles "
                "(`missiontree world show` draws the map with coordinates)"))
    return problems


def _check_models(spec: MissionSpec, doc: Located | None, flag: Any, providers: Mapping[str, Any] | None
                  ) -> list[Problem]:
    from missiontree.session.models import load_models_config

    from_file = flag is None and spec.run.models is not None
    name = flag if flag is not None else spec.run.models
    if from_file and isinstance(name, str):
        name = resolve_mission_path(spec.path, name)
    try:
        if providers is not None:
            return check_models_file(name, providers)
        load_models_config(name)
    except ProblemsError as exc:
        return list(exc.problems)
    except ConfigError as exc:
        if from_file:
            return [_at_run(spec, doc, "models", str(exc), "fix `models:` in the run section")]
        return [Problem("--models", 0, 0, "", str(exc))]
    return []


def check_models_file(models: str | os.PathLike[str] | Mapping[str, Any] | None,
                      providers: Mapping[str, Any]) -> list[Problem]:
    """A models config checked whole, each role's provider options and the files they name included.

    Every problem is located; a file outside the config's folder and ``$MISSIONTREE_MODEL_PATH`` or
    over its size limit is one (:mod:`missiontree.session.model_files`), its content never shown.

    Raises:
        ConfigError: The config cannot be found (the message lists the shipped ones).
    """
    from missiontree.session.model_files import config_base, model_file_problems
    from missiontree.session.models import check_models_config, load_models_config

    document = load_models_config(models)
    try:
        roles, _ = check_models_config(document, providers, strict=models is not None)
    except ProblemsError as exc:
        return list(exc.problems)
    file_problems, _ = model_file_problems(document, roles, providers, config_base(models, document))
    return _provider_options(document, roles, providers) + file_problems


def _provider_options(document: Located, roles: Mapping[str, Mapping[str, Any]],
                      providers: Mapping[str, Any]) -> list[Problem]:
    """Each role's options against the options model its provider's factory declares (``options_model``)."""
    from pydantic import ValidationError

    from missiontree.plugins.builtin import resolve_factory

    problems: list[Problem] = []
    for role, section in roles.items():
        name = section.get("provider")
        if name not in providers:
            continue
        try:
            factory = resolve_factory("provider", str(name), providers[str(name)])
        except (ImportError, MissionTreeError):
            continue  # reported when the models are built (the role is unusable, with the reason)
        model = getattr(factory, "options_model", None)
        if model is None:
            continue
        options = {k: v for k, v in section.items() if k not in MODEL_ROLE_KEYS}
        try:
            model.model_validate(options)
        except ValidationError as exc:
            problems += validation_problems(exc, document, model, prefix=("roles", role))
    return problems


def _check_waypoints(spec: MissionSpec, world: Any) -> list[Problem]:
    problems: list[Problem] = []
    for node in spec.nodes():
        params = node.params
        if params is None:
            continue
        fields = type(params).model_fields
        if WAYPOINTS_FILE_PARAM in fields:
            problems += _check_waypoint_file(node, world)
        if WAYPOINTS_PARAM in fields:
            inline = getattr(params, WAYPOINTS_PARAM, None)
            if isinstance(inline, list) and world is not None:
                try:
                    route = parse_waypoints(inline, WAYPOINTS_PARAM)
                except ConfigError:
                    continue  # reported by the node's own parameter check
                for reason in misfits(route, world.grid):
                    problems.append(_at_param(node, WAYPOINTS_PARAM, f"expected waypoints in the world "
                                              f"{world.name!r}, found {reason}",
                                              "move the waypoint into free space, or run another world"))
    return problems


def _check_waypoint_file(node: NodeSpec, world: Any) -> list[Problem]:
    params = node.params
    assert params is not None
    value = getattr(params, WAYPOINTS_FILE_PARAM, None)
    if not isinstance(value, str) or isinstance(value, BlackboardRef):
        return []
    route = getattr(params, "route", None)
    base = Path(node.source.file).resolve().parent
    try:
        found = read_waypoint_file(value, route if isinstance(route, str) else None, base=base)
    except ProblemsError as exc:
        return [_at_param(node, WAYPOINTS_FILE_PARAM, f"expected a valid waypoint file, found "
                          f"{len(exc.problems)} problem(s) in {value!r}"), *exc.problems]
    except ConfigError as exc:
        return [_at_param(node, WAYPOINTS_FILE_PARAM, str(exc),
                          "a waypoint file is found beside the mission or under config/waypoints/")]
    problems: list[Problem] = []
    if world is not None:
        if found.world is not None and found.world != world.name:
            problems.append(_at_param(
                node, WAYPOINTS_FILE_PARAM, f"expected a waypoint file for the world {world.name!r}, found "
                f"{value!r} written for {found.world!r}",
                f"run it in its world (--world {found.world}) or pick this world's waypoints"))
        else:
            for reason in misfits(found.waypoints, world.grid):
                problems.append(_at_param(
                    node, WAYPOINTS_FILE_PARAM, f"expected waypoints in the world {world.name!r}, found "
                    f"{reason} ({found.path.name})", "is this file written for another world?"))
    if not problems and str(found.path) != value:
        node.params = params.model_copy(update={WAYPOINTS_FILE_PARAM: str(found.path)})
    return problems


def _at_param(node: NodeSpec, name: str, message: str, hint: str = "") -> Problem:
    if node.located is not None:
        return node.located.problem_at((name,), message, hint, where=node.path)
    src = node.source
    return Problem(src.file, src.line, src.col, node.path, message, hint)
