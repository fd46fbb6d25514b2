"""The checked form of a mission file: what the loader produces and the builder consumes.

A :class:`MissionSpec` holds the root :class:`NodeSpec`, the blackboard defaults written before
the first tick, and the optional ``run:`` section (:class:`RunSection`) whose values are defaults
that command-line flags override. Every node keeps where it was written (:class:`Source`), so
problems found after loading can still name ``file:line:col``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from missiontree.yamlio import Located

#: Top-level keys a mission or subtree file may hold.
TOP_LEVEL_KEYS = ("version", "description", "params", "required", "run", "blackboard", "root")

#: Keys inside a node's mapping that are not parameters of its type.
NAME_KEY = "name"
CHILD_KEY = "child"
CHILDREN_KEY = "children"
#: Pre-conditions (checked before a tick, in BT.CPP's order) and post-conditions (assignments after),
#: allowed on any node (see :mod:`missiontree.engine.conditions`).
PRE_KEYS = ("fail_if", "succeed_if", "skip_if", "while")
POST_KEYS = ("on_success", "on_failure", "on_halted", "post")
CONDITION_KEYS = PRE_KEYS + POST_KEYS


class RunSection(BaseModel):
    """Defaults for ``missiontree run`` that the command line overrides (all optional)."""

    model_config = ConfigDict(extra="forbid")

    backend: str | None = Field(None, description="Robot backend: sim or ros2.")
    world: str | None = Field(None, description="Simulator world: a shipped name or a path to a world file.")
    robot: str | None = Field(None, description="Robot profile: a shipped name (turtlebot4) or a path.")
    models: str | None = Field(None, description="Models config: a shipped name or a path.")
    config: str | None = Field(None, description="Run configuration file (as --config).")
    tick_hz: float | None = Field(None, gt=0, le=1000, description="Tick rate in Hz.")
    max_duration: float | None = Field(None, gt=0, description="Stop after this many seconds (robot clock).")
    seed: int | None = Field(None, description="Random seed of the run.")
    realtime: bool | None = Field(None, description="Pace the simulator to wall time.")
    robots: int | None = Field(None, ge=1, le=16, description="Robots in one world, the tree run once per "
                               "robot on one clock (as --robots; docs/fleet.md).")
    map: Literal["known", "unknown"] | None = Field(
        None, description="known: the robot is given the world's map; unknown: it starts without one and "
        "learns it from its own lidar (as --unknown-map).")


@dataclass(frozen=True)
class Source:
    """Where something was written.

    Attributes:
        file: The file as the user named it.
        line: 1-based line.
        col: 1-based column.
        included_from: ``file:line`` of the include that brought this file in, innermost last.
    """

    file: str
    line: int
    col: int
    included_from: tuple[str, ...] = ()

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.col}"


@dataclass
class NodeSpec:
    """One node of the mission tree, as written and (after checking) with validated parameters.

    Attributes:
        type: The node type's name (a key of the registry).
        name: The node's name (``name:`` in the file, else the type name).
        raw: The parameters as written (after ``${param}`` substitution), without name/child keys.
        children: Child nodes (one for decorators, several for composites, none for leaves).
        source: Where the node's type name was written.
        path: The node path shown in problems, e.g. ``root/Sequence(main)/Retry[2]/Wait``.
        params: The validated Params model instance, set by the checker (None before/if invalid).
        category: ``leaf``, ``decorator`` or ``composite`` once the type is known.
        located: The parameter mapping as parsed, to locate problems in individual parameters.
    """

    type: str
    name: str
    raw: dict[str, Any]
    children: list[NodeSpec]
    source: Source
    path: str
    params: BaseModel | None = None
    category: Literal["leaf", "decorator", "composite"] | None = None
    #: The node's parameter mapping with the source position of every key and value.
    located: Located | None = field(default=None, repr=False, compare=False)
    #: Which structural key the file used for children (``child``, ``children``) or None.
    child_key: str | None = None
    #: Pre- and post-conditions as written (``skip_if: ...``), by key.
    conditions: dict[str, Any] = field(default_factory=dict)
    #: Where a condition was written when not in the node's own mapping (on an ``Include``), by key.
    condition_sites: dict[str, Located] = field(default_factory=dict, repr=False, compare=False)
    #: The parsed conditions (a :class:`~missiontree.engine.conditions.NodeConditions`), set by the checker.
    prepost: Any = field(default=None, repr=False, compare=False)

    def walk(self) -> list[NodeSpec]:
        """This node and every descendant, depth first, parents before children."""
        nodes = [self]
        for child in self.children:
            nodes.extend(child.walk())
        return nodes


@dataclass
class MissionSpec:
    """A checked mission, ready to build.

    Attributes:
        path: The mission file.
        root: The root node.
        blackboard: Keys written to the blackboard before the first tick.
        run: Defaults for the run; the CLI's flags override them.
        description: Free text from the file's ``description:``.
        files: Every file read (the mission and the subtrees it includes).
    """

    path: Path
    root: NodeSpec
    blackboard: dict[str, Any] = field(default_factory=dict)
    run: RunSection = field(default_factory=RunSection)
    description: str = ""
    files: list[Path] = field(default_factory=list)

    def nodes(self) -> list[NodeSpec]:
        """Every node of the tree, depth first."""
        return self.root.walk()
