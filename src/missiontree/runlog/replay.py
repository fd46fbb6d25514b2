"""Replay a tick log: every node's status, feedback and reason, and the blackboard, at any tick.

One reader for the viewer and the exports. A :class:`Replay` is fed tick-log records (dicts, as
:func:`missiontree.engine.tick_log.read_records` returns them, whole or as a growing file yields them
in ``--follow`` mode) and keeps compact lists: the tick numbers and times, the root status of each
tick, the status changes in order (node, status, feedback, reason), blackboard writes, and the
leaves' events. The state at a tick is rebuilt from the nearest keyframe (a full snapshot every
:data:`KEYFRAME_EVERY` ticks) plus the changes after it.

The tree comes from the mission as declared (:func:`declared_tree`, or the ``runview.json`` the
run wrote, see :mod:`missiontree.runlog.record`); nodes the log names that the declaration lacks
are added under their parent path, so a log alone still replays.
"""

from __future__ import annotations

import json
import math
from bisect import bisect_right
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from missiontree.engine.tick_log import read_records
from missiontree.errors import ConfigError
from missiontree.file_limits import MAX_POSES_BYTES, MAX_RUNVIEW_BYTES, read_bounded, read_text_bounded

#: Status names in the order of their codes (py_trees' INVALID is Groot's IDLE).
STATUSES = ("INVALID", "RUNNING", "SUCCESS", "FAILURE")
STATUS_CODE = {name: code for code, name in enumerate(STATUSES)}
#: A full snapshot of the state every this many ticks.
KEYFRAME_EVERY = 256
#: Runner lines that are not leaf events.
RUNNER_LINES = frozenset({"tick", "halted", "mission_started", "mission_finished"})
#: Fields every line carries that say nothing about the event itself.
_COMMON = ("event", "mission", "tick", "t")


@dataclass
class TreeNode:
    """One node of the tree as declared.

    Attributes:
        path: The node's path as the tick log writes it (``root/child/leaf``).
        name: Its name.
        type: The node type as the mission file names it (``?`` when only the log knew it).
        category: ``leaf``, ``decorator``, ``composite`` or ``""`` when unknown.
        params: Its parameters as written.
        source: ``file:line:col`` of its declaration, or ``""``.
        parent: Index of its parent, -1 for the root.
        children: Indices of its children, in order.
    """

    path: str
    name: str
    type: str = "?"
    category: str = ""
    params: dict[str, Any] = field(default_factory=dict)
    source: str = ""
    parent: int = -1
    children: list[int] = field(default_factory=list)


@dataclass(frozen=True)
class Change:
    """A node's status change in one tick (``tick`` is the tick's index in the replay)."""

    tick: int
    node: int
    status: int
    was: int
    feedback: str = ""
    reason: str = ""


@dataclass(frozen=True)
class Event:
    """A leaf's event: its kind, the tick index it belongs to, its time and its own fields."""

    tick: int
    kind: str
    t: float
    fields: dict[str, Any]


@dataclass
class NodeState:
    """A node's status at a tick, with the feedback and reason of its last change."""

    status: str
    feedback: str
    reason: str


def declared_tree(spec: Any) -> dict[str, Any]:
    """The tree of a checked mission spec as plain data (names, types, parameters, sources).

    A node's conditions (``skip_if``, ``post``, ...) are among its ``params``, as written.

    Paths follow :func:`missiontree.engine.node_words.node_paths` (``[i]`` added to repeated names).
    """
    from missiontree.engine.json_lines import plain

    def convert(node: Any, path: str) -> dict[str, Any]:
        names = [child.name for child in node.children]
        children = []
        for index, child in enumerate(node.children):
            suffix = f"[{index}]" if names.count(child.name) > 1 else ""
            children.append(convert(child, f"{path}/{child.name}{suffix}"))
        return {
            "path": path,
            "name": node.name,
            "type": node.type,
            "category": node.category or "",
            "params": plain({**node.raw, **node.conditions}),
            "source": str(node.source),
            "children": children,
        }

    return convert(spec.root, spec.root.name)


class Replay:
    """The replayable content of one tick log.

    Args:
        tree: A declared tree (:func:`declared_tree`'s form), or None to learn nodes from the log.
    """

    def __init__(self, tree: dict[str, Any] | None = None) -> None:
        self.nodes: list[TreeNode] = []
        self.index: dict[str, int] = {}
        self.tick_numbers: list[int] = []
        self.times: list[float] = []
        self.root_status: list[int] = []
        self.changes: list[Change] = []
        #: ``change_start[i]``: index of tick i's first change (one more entry than ticks).
        self.change_start: list[int] = [0]
        #: (tick index, key, value) — value is :data:`UNSET` when the key was removed.
        self.blackboard: list[tuple[int, str, Any]] = []
        self.events: list[Event] = []
        self.halted: list[Change] = []
        #: Robot time of the halt at the end of the run.
        self.halted_t = 0.0
        self.started: dict[str, Any] = {}
        self.finished: dict[str, Any] = {}
        #: (t, x, y) of the robot, from the run's trajectory or events that carry a robot pose.
        self.poses: list[tuple[float, float, float]] = []
        self.lines = 0
        self._poses_recorded = False
        self._pending_events: list[dict[str, Any]] = []
        self._keyframes: list[tuple[list[int], list[str], list[str], dict[str, Any]]] = []
        if tree is not None:
            self._add_declared(tree, -1)

    # -- building --------------------------------------------------------------------------------

    def _add_declared(self, node: dict[str, Any], parent: int) -> None:
        index = len(self.nodes)
        self.nodes.append(
            TreeNode(
                path=node["path"],
                name=node.get("name", node["path"].rsplit("/", 1)[-1]),
                type=node.get("type", "?"),
                category=node.get("category", ""),
                params=dict(node.get("params") or {}),
                source=node.get("source", ""),
                parent=parent,
            )
        )
        self.index[node["path"]] = index
        if parent >= 0:
            self.nodes[parent].children.append(index)
        for child in node.get("children", []):
            self._add_declared(child, index)

    def node_id(self, path: str) -> int:
        """The index of the node at ``path``, adding it (and missing ancestors) when new."""
        found = self.index.get(path)
        if found is not None:
            return found
        parent = -1
        if "/" in path:
            parent = self.node_id(path.rsplit("/", 1)[0])
        index = len(self.nodes)
        self.nodes.append(TreeNode(path=path, name=path.rsplit("/", 1)[-1], parent=parent))
        self.index[path] = index
        if parent >= 0:
            self.nodes[parent].children.append(index)
        return index

    def feed(self, record: dict[str, Any]) -> None:
        """Take one tick-log record."""
        self.lines += 1
        kind = record.get("event")
        if kind == "tick":
            self._tick(record)
        elif kind == "halted":
            at = max(len(self.tick_numbers) - 1, 0)
            self.halted.extend(self._changes(record, at))
            self.halted_t = float(record.get("t", self.times[-1] if self.times else 0.0))
        elif kind == "mission_started":
            self.started = record
        elif kind == "mission_finished":
            self.finished = record
        elif isinstance(kind, str):
            self._event(record)

    def feed_all(self, records: list[dict[str, Any]]) -> Replay:
        """Take every record; return self."""
        for record in records:
            self.feed(record)
        self.flush_events()
        return self

    def _tick(self, record: dict[str, Any]) -> None:
        at = len(self.tick_numbers)
        self.tick_numbers.append(int(record.get("tick", at + 1)))
        self.times.append(float(record.get("t", 0.0)))
        self.root_status.append(STATUS_CODE.get(str(record.get("status")), 0))
        self.changes.extend(self._changes(record, at))
        self.change_start.append(len(self.changes))
        for key, value in (record.get("bb") or {}).items():
            self.blackboard.append((at, str(key), value))
        for key in record.get("bb_unset") or []:
            self.blackboard.append((at, str(key), UNSET))
        pose = record.get("pose")
        if isinstance(pose, list) and len(pose) >= 2:
            self.poses.append((self.times[-1], float(pose[0]), float(pose[1])))
        self.flush_events()
        self._keyframes = self._keyframes[: (at // KEYFRAME_EVERY) + 1]  # later ones are stale

    def _changes(self, record: dict[str, Any], at: int) -> list[Change]:
        out = []
        for entry in record.get("changed") or []:
            if not isinstance(entry, dict) or "node" not in entry:
                continue
            out.append(
                Change(
                    at,
                    self.node_id(str(entry["node"])),
                    STATUS_CODE.get(str(entry.get("status")), 0),
                    STATUS_CODE.get(str(entry.get("was")), 0),
                    str(entry.get("feedback", "")),
                    str(entry.get("reason", "")),
                )
            )
        return out

    def _event(self, record: dict[str, Any]) -> None:
        self._pending_events.append(record)

    def flush_events(self) -> None:
        """Place the events read so far on their ticks (an event may precede its tick's line)."""
        if not self._pending_events:
            return
        pending, self._pending_events = self._pending_events, []
        for record in pending:
            number = record.get("tick")
            at = self.tick_index(int(number)) if isinstance(number, int) else len(self.tick_numbers) - 1
            fields = {k: v for k, v in record.items() if k not in _COMMON}
            event = Event(max(at, 0), str(record["event"]), float(record.get("t", 0.0)), fields)
            self.events.append(event)
            pose = fields.get("robot_pose")
            if (
                not self._poses_recorded
                and isinstance(pose, list)
                and len(pose) >= 2
                and all(isinstance(v, int | float) for v in pose[:2])
            ):
                self.poses.append((event.t, float(pose[0]), float(pose[1])))

    def set_poses(self, poses: list[tuple[float, float, float]]) -> None:
        """Replace the robot's path (a recorded trajectory is better than poses taken from events)."""
        self.poses = sorted((float(t), float(x), float(y)) for t, x, y in poses)
        self._poses_recorded = bool(self.poses)

    # -- queries --------------------------------------------------------------------------------

    def __len__(self) -> int:
        return len(self.tick_numbers)

    def tick_index(self, number: int) -> int:
        """The index of tick ``number`` (the last tick at or before it; 0 before the first)."""
        numbers = self.tick_numbers
        if numbers and numbers[-1] - numbers[0] == len(numbers) - 1:  # consecutive: no search
            return min(max(number - numbers[0], 0), len(numbers) - 1)
        return max(bisect_right(numbers, number) - 1, 0)

    def _keyframe(self, k: int) -> tuple[list[int], list[str], list[str], dict[str, Any]]:
        """The state at the end of tick ``k * KEYFRAME_EVERY - 1`` (k = 0: before any tick)."""
        while len(self._keyframes) <= k:
            j = len(self._keyframes)
            if j == 0:
                count = len(self.nodes)
                self._keyframes.append(([0] * count, [""] * count, [""] * count, {}))
                continue
            status, feedback, reason, board = self._keyframe(j - 1)
            status, feedback, reason, board = list(status), list(feedback), list(reason), dict(board)
            self._apply(status, feedback, reason, board, (j - 1) * KEYFRAME_EVERY, j * KEYFRAME_EVERY)
            self._keyframes.append((status, feedback, reason, board))
        return self._keyframes[k]

    def _apply(
        self,
        status: list[int],
        feedback: list[str],
        reason: list[str],
        board: dict[str, Any],
        first: int,
        end: int,
    ) -> None:
        end = min(end, len(self.tick_numbers))
        grow = len(self.nodes) - len(status)
        if grow > 0:
            status.extend([0] * grow)
            feedback.extend([""] * grow)
            reason.extend([""] * grow)
        if first >= end:
            return
        for change in self.changes[self.change_start[first] : self.change_start[end]]:
            status[change.node] = change.status
            feedback[change.node] = change.feedback
            reason[change.node] = change.reason
        lo = bisect_right(self.blackboard, first - 1, key=lambda b: b[0])
        for at, key, value in self.blackboard[lo:]:
            if at >= end:
                break
            if value is UNSET:
                board.pop(key, None)
            else:
                board[key] = value

    def state_at(self, at: int) -> tuple[dict[str, NodeState], dict[str, Any]]:
        """Every node's state and the blackboard at the end of tick index ``at``."""
        if not self.tick_numbers:
            return {n.path: NodeState("INVALID", "", "") for n in self.nodes}, {}
        at = min(max(at, 0), len(self.tick_numbers) - 1)
        k = (at + 1) // KEYFRAME_EVERY
        status, feedback, reason, board = self._keyframe(k)
        status, feedback, reason, board = list(status), list(feedback), list(reason), dict(board)
        self._apply(status, feedback, reason, board, k * KEYFRAME_EVERY, at + 1)
        states = {
            node.path: NodeState(STATUSES[status[i]], feedback[i], reason[i])
            for i, node in enumerate(self.nodes)
        }
        return states, board

    def ending(self) -> dict[str, Any]:
        """The chain of nodes that decided how the run ended, and the tick to look at.

        From the root down, each step takes the child that holds the root's final status and
        changed to it last; the chain stops at a node with no such child (for a failure, the leaf
        whose reason ended the run). Returns ``{"tick": index, "status", "chain": [node indices],
        "reason", "text"}``.
        """
        if not self.tick_numbers or not self.nodes:
            return {"tick": 0, "status": "INVALID", "chain": [], "reason": "", "text": "the log has no ticks"}
        last = len(self.tick_numbers) - 1
        states, _ = self.state_at(last)
        final = STATUSES[self.root_status[last]]
        last_change: dict[int, int] = {}
        for index, change in enumerate(self.changes):
            last_change[change.node] = index
        chain = [0]
        while True:
            node = self.nodes[chain[-1]]
            held = [c for c in node.children if states[self.nodes[c].path].status == final]
            if not held:
                break
            chain.append(max(held, key=lambda c: last_change.get(c, -1)))
        deciding = chain[-1]
        change_at = last_change.get(deciding)
        tick = self.changes[change_at].tick if change_at is not None else last
        state = states[self.nodes[deciding].path]
        reason = state.reason or state.feedback
        stopped_by = self.finished.get("stopped_by", "")
        if final in ("SUCCESS", "FAILURE"):
            text = f"{final}: {self.nodes[deciding].path}" + (f": {reason}" if reason else "")
        else:
            text = f"stopped by {stopped_by or 'the end of the log'} while {final}"
            tick = last
        return {"tick": tick, "status": final, "chain": chain, "reason": reason, "text": text}


class _Unset:
    """Marks a blackboard key that was removed."""

    def __repr__(self) -> str:
        return "UNSET"


UNSET: Any = _Unset()


def event_category(event: Event) -> str:
    """The event's mark: ``goal``, ``alarm``, ``model``, ``failure``, ``detection`` or ``other``."""
    kind = event.kind
    if kind == "error" or "fail" in kind or kind.endswith("_lost") or "abort" in kind:
        return "failure"
    if "alarm" in kind:
        return "alarm"
    if "goal" in kind:
        return "goal"
    if kind.startswith("model") or "verdict" in kind or "answer" in kind:
        return "model"
    if "detect" in kind or "confirm" in kind or "found" in kind:
        return "detection"
    return "other"


def event_position(event: Event) -> tuple[float, float] | None:
    """Where on the map an event happened, when it says (``position`` [x, y] or ``x``/``y``)."""
    fields = event.fields
    position = fields.get("position")
    if (
        isinstance(position, list | tuple)
        and len(position) >= 2
        and all(isinstance(v, int | float) for v in position[:2])
    ):
        return float(position[0]), float(position[1])
    x, y = fields.get("x"), fields.get("y")
    if isinstance(x, int | float) and isinstance(y, int | float) and not isinstance(x, bool):
        return float(x), float(y)
    return None


# -- run directories ---------------------------------------------------------------------------------

RUNVIEW_FILE = "runview.json"
#: The poses ``run --view`` samples while the mission runs.
POSES_FILE = "poses.jsonl"


def log_path(run: Path) -> Path:
    """The tick log of a run directory (or ``run`` itself when it is a file)."""
    run = Path(run)
    if run.is_dir():
        candidate = run / "ticks.jsonl"
        if not candidate.is_file():
            raise ConfigError(
                f"{run} has no ticks.jsonl; give a run directory written by `missiontree run` "
                f"(see its --out) or the log file itself"
            )
        return candidate
    if not run.exists():
        raise ConfigError(f"run {str(run)!r} does not exist; give a run directory or a ticks.jsonl")
    return run


def read_runview(run_dir: Path) -> dict[str, Any]:
    """What the run recorded for viewing (tree, map, trajectory), or {} when it recorded nothing."""
    path = Path(run_dir) / RUNVIEW_FILE
    if not path.is_file():
        return {}
    try:
        data = json.loads(read_text_bounded(path, MAX_RUNVIEW_BYTES, "run view file"))
    except (OSError, json.JSONDecodeError, UnicodeDecodeError) as error:
        raise ConfigError(
            f"{path}: not a readable run view file ({error}); delete it to view the log alone"
        ) from error
    return data if isinstance(data, dict) else {}


def load_tree(mission: Path | None, run_dir: Path | None) -> dict[str, Any] | None:
    """The declared tree: from ``mission`` (a mission file, checked), else the run's ``runview.json``."""
    if mission is not None:
        from missiontree.engine.loader import load_mission
        from missiontree.plugins.manager import load_plugins

        spec = load_mission(Path(mission), load_plugins().nodes)
        return declared_tree(spec)
    if run_dir is not None:
        tree = read_runview(run_dir).get("tree")
        if isinstance(tree, dict):
            why = _not_a_tree(tree, 0, [0])
            if why:
                raise ConfigError(f"{Path(run_dir) / RUNVIEW_FILE}: its tree is not one a run records "
                                  f"({why}); delete the file to view the log alone, or give the mission file")
            return tree
    return None


#: A recorded tree's limits: nodes and depth (a real mission is far inside them).
MAX_TREE_NODES = 100_000
MAX_TREE_DEPTH = 200
_TEXT_KEYS = ("name", "type", "category", "source")


def _not_a_tree(node: Any, depth: int, count: list[int]) -> str:
    """Why ``node`` is not a recorded tree node with well-formed children ("" when it is)."""
    count[0] += 1
    if count[0] > MAX_TREE_NODES or depth > MAX_TREE_DEPTH:
        return f"more than {MAX_TREE_NODES:,} nodes or {MAX_TREE_DEPTH} levels"
    if not isinstance(node, dict) or not isinstance(node.get("path"), str) or not node["path"]:
        return "a node without a path"
    if any(not isinstance(node.get(key, ""), str) for key in _TEXT_KEYS):
        return "a node whose name, type, category or source is not text"
    if not isinstance(node.get("params") or {}, dict) or not isinstance(node.get("children", []), list):
        return "a node whose params are not a mapping or whose children are not a list"
    for child in node.get("children", []):
        why = _not_a_tree(child, depth + 1, count)
        if why:
            return why
    return ""


def _pose_row(row: Any) -> tuple[float, float, float] | None:
    """A recorded pose row ``[t, x, y, ...]`` as three finite numbers, or None."""
    if not isinstance(row, list | tuple) or len(row) < 3:
        return None
    values = row[:3]
    if any(isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) for v in values):
        return None
    return float(values[0]), float(values[1]), float(values[2])


def open_run(run: Path, mission: Path | None = None) -> Replay:
    """Replay a run directory (or a ticks.jsonl): its tree, its log and its recorded trajectory.

    Raises:
        ConfigError: No tick log, an unreadable line, or an empty log.
    """
    path = log_path(run)
    run_dir = path.parent
    replay = Replay(load_tree(mission, run_dir))
    records, _ = read_records(path)
    if not records:
        raise ConfigError(f"{path} is empty: the run wrote no tick log lines")
    replay.feed_all(records)
    poses = read_runview(run_dir).get("poses")
    if not poses:
        poses = [list(p) for p in read_pose_trail(run_dir)]
    if isinstance(poses, list) and poses:  # rows that are not three finite numbers are not a pose
        replay.set_poses([row for row in map(_pose_row, poses) if row is not None])
    return replay


def read_pose_trail(run_dir: Path) -> list[tuple[float, float, float]]:
    """The poses ``run --view`` recorded (``poses.jsonl``), complete lines only."""
    path = Path(run_dir) / POSES_FILE
    if not path.is_file():
        return []
    rows = []
    try:
        text = read_bounded(path, MAX_POSES_BYTES, "pose trail").decode("utf-8", errors="replace")
    except OSError as error:
        raise ConfigError(
            f"{path}: not a readable pose trail ({error}); delete it to view the log alone") from None
    for line in text.splitlines():
        try:
            t, x, y = json.loads(line)[:3]
            rows.append((float(t), float(x), float(y)))
        except (ValueError, TypeError):
            continue  # a line being written
    return rows
