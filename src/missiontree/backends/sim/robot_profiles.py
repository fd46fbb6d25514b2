"""Robot profiles for the simulator: loading one by name or path, with overrides merged over it.

Also the one place a located YAML document is validated into a schema model with the world
file's error messages (:func:`validate_model`), used for worlds and profiles alike.
"""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import pydantic

from missiontree.backends.sim.schema import RobotProfile
from missiontree.errors import ConfigError, Problem, WorldFileError
from missiontree.paths import find_config
from missiontree.yamlio import Located, error_message, load_yaml, validation_problems


def profile_problems(doc: Located) -> list[Problem]:
    """The world file's robot profile, if it names one that does not exist (as a located problem)."""
    robot = doc.data.get("robot") if isinstance(doc.data, dict) else None
    profile = robot.get("profile", "turtlebot4") if isinstance(robot, dict) else "turtlebot4"
    if not isinstance(profile, str):
        return []
    try:
        find_config("robots", profile)
    except ConfigError as exc:
        return [doc.problem_at(("robot", "profile"), str(exc), "create config/robots/<name>.yaml")]
    return []


def load_robot_profile(name: str | Path, overrides: dict[str, Any] | None = None) -> RobotProfile:
    """Load a robot profile by name or path, with ``overrides`` merged over it.

    Raises:
        WorldFileError: The profile is missing or broken; or an override is.
    """
    try:
        path = find_config("robots", name)
    except ConfigError as exc:
        raise WorldFileError([Problem(str(name), 0, 0, "", str(exc))]) from None
    doc = load_yaml(path, error=WorldFileError)
    if overrides:
        merged = deep_merge(copy.deepcopy(doc.data), overrides)
        try:
            return RobotProfile.model_validate(merged)
        except pydantic.ValidationError as exc:
            raise WorldFileError([
                Problem("<config overrides>", 0, 0, ".".join(str(p) for p in e["loc"]),
                        error_message(e, RobotProfile)) for e in exc.errors()
            ]) from None
    return validate_model(doc, RobotProfile)


def deep_merge(base: Any, over: dict[str, Any]) -> Any:
    """Merge ``over`` into ``base`` key by key, nested mappings too (``base`` is changed and returned)."""
    if not isinstance(base, dict):
        return over
    for key, value in over.items():
        if isinstance(value, dict) and isinstance(base.get(key), dict):
            deep_merge(base[key], value)
        else:
            base[key] = value
    return base


def validate_model(doc: Located, model: type[pydantic.BaseModel]) -> Any:
    """``doc``'s data validated into ``model``; every problem located in the file (WorldFileError)."""
    if not isinstance(doc.data, dict):
        raise WorldFileError([doc.problem_at((), f"expected a mapping, found {type(doc.data).__name__}")])
    try:
        return model.model_validate(doc.data)
    except pydantic.ValidationError as exc:
        raise WorldFileError(validation_problems(exc, doc, model, docs="docs/worlds.md")) from None
