"""MCAP export of a run, for Foxglove and Lichtblick: JSON channels with JSON Schema schemas.

Channels (message encoding ``json``, schema encoding ``jsonschema``):

=============================  ===========================  ============================================
topic                          schema                        one message per
=============================  ===========================  ============================================
``/missiontree/ticks``         ``missiontree.Tick``          tick: number, time, root status, changes
``/missiontree/transitions``   ``missiontree.NodeTransition``  node status change (feedback, reason)
``/missiontree/blackboard``    ``missiontree.BlackboardChange``  blackboard key written or removed
``/missiontree/events``        ``missiontree.Event``         leaf event (goal sent, alarm, model call ...)
``/missiontree/log``           ``foxglove.Log``              the same events and leaf failures, as log lines
``/robot/pose``                ``foxglove.PoseInFrame``      robot pose (frame ``map``) of the trajectory
=============================  ===========================  ============================================

Log and publish times are the robot clock's in nanoseconds. Nothing depends on the wall clock or
on dict order, and the ``mcap`` writer's chunks are deterministic, so the same run gives the same
bytes. Needs the ``viewer`` extra (``pip install 'missiontree[viewer]'``).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from missiontree import __version__
from missiontree.errors import BackendUnavailableError
from missiontree.runlog.replay import STATUSES, UNSET, Replay, event_category

_TIME = {
    "type": "object",
    "properties": {
        "sec": {"type": "integer", "minimum": 0},
        "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999},
    },
}

SCHEMAS: dict[str, dict[str, Any]] = {
    "missiontree.Tick": {
        "title": "missiontree.Tick",
        "description": "One tick of the behaviour tree",
        "type": "object",
        "properties": {
            "tick": {"type": "integer"},
            "t": {"type": "number", "description": "robot time, s"},
            "status": {"type": "string", "enum": list(STATUSES)},
            "changes": {"type": "integer", "description": "node status changes in this tick"},
        },
        "required": ["tick", "t", "status", "changes"],
    },
    "missiontree.NodeTransition": {
        "title": "missiontree.NodeTransition",
        "description": "A node's status change",
        "type": "object",
        "properties": {
            "tick": {"type": "integer"},
            "t": {"type": "number"},
            "node": {"type": "string"},
            "status": {"type": "string", "enum": list(STATUSES)},
            "was": {"type": "string", "enum": list(STATUSES)},
            "feedback": {"type": "string"},
            "reason": {"type": "string"},
            "halt": {"type": "boolean", "description": "part of the halt at the end of the run"},
        },
        "required": ["tick", "t", "node", "status", "was"],
    },
    "missiontree.BlackboardChange": {
        "title": "missiontree.BlackboardChange",
        "description": "A blackboard key written or removed",
        "type": "object",
        "properties": {
            "tick": {"type": "integer"},
            "t": {"type": "number"},
            "key": {"type": "string"},
            "value": {"description": "the new value (JSON), absent when removed"},
            "removed": {"type": "boolean"},
        },
        "required": ["tick", "t", "key", "removed"],
    },
    "missiontree.Event": {
        "title": "missiontree.Event",
        "description": "An event a leaf emitted",
        "type": "object",
        "properties": {
            "tick": {"type": "integer"},
            "t": {"type": "number"},
            "kind": {"type": "string"},
            "category": {"type": "string"},
            "node": {"type": "string"},
            "fields": {"type": "object", "description": "the event's own fields"},
        },
        "required": ["tick", "t", "kind", "fields"],
    },
    "foxglove.Log": {
        "title": "foxglove.Log",
        "description": "A log message",
        "type": "object",
        "properties": {
            "timestamp": {**_TIME, "description": "Timestamp of log message"},
            "level": {
                "title": "foxglove.LogLevel",
                "description": "Log level",
                "oneOf": [
                    {"title": "UNKNOWN", "const": 0},
                    {"title": "DEBUG", "const": 1},
                    {"title": "INFO", "const": 2},
                    {"title": "WARNING", "const": 3},
                    {"title": "ERROR", "const": 4},
                    {"title": "FATAL", "const": 5},
                ],
            },
            "message": {"type": "string", "description": "Log message"},
            "name": {"type": "string", "description": "Process or node name"},
            "file": {"type": "string", "description": "Filename"},
            "line": {"type": "integer", "minimum": 0, "description": "Line number in the file"},
        },
    },
    "foxglove.PoseInFrame": {
        "title": "foxglove.PoseInFrame",
        "description": "A timestamped pose for an object or reference frame in 3D space",
        "type": "object",
        "properties": {
            "timestamp": {**_TIME, "description": "Timestamp of pose"},
            "frame_id": {
                "type": "string",
                "description": "Frame of reference for pose position and orientation",
            },
            "pose": {
                "title": "foxglove.Pose",
                "type": "object",
                "properties": {
                    "position": {
                        "title": "foxglove.Vector3",
                        "type": "object",
                        "properties": {
                            "x": {"type": "number"},
                            "y": {"type": "number"},
                            "z": {"type": "number"},
                        },
                    },
                    "orientation": {
                        "title": "foxglove.Quaternion",
                        "type": "object",
                        "properties": {
                            "x": {"type": "number"},
                            "y": {"type": "number"},
                            "z": {"type": "number"},
                            "w": {"type": "number"},
                        },
                    },
                },
            },
        },
    },
}

SCHEMAS["foxglove.Grid"] = {
    "title": "foxglove.Grid",
    "description": "A 2D grid of data",
    "type": "object",
    "properties": {
        "timestamp": {**_TIME, "description": "Timestamp of grid"},
        "frame_id": {"type": "string", "description": "Frame of reference"},
        "pose": SCHEMAS["foxglove.PoseInFrame"]["properties"]["pose"],
        "column_count": {"type": "integer", "minimum": 0, "description": "Number of grid columns"},
        "cell_size": {
            "title": "foxglove.Vector2",
            "type": "object",
            "properties": {"x": {"type": "number"}, "y": {"type": "number"}},
        },
        "row_stride": {
            "type": "integer",
            "minimum": 0,
            "description": "Number of bytes between rows in data",
        },
        "cell_stride": {
            "type": "integer",
            "minimum": 0,
            "description": "Number of bytes between cells in data",
        },
        "fields": {
            "type": "array",
            "items": {
                "title": "foxglove.PackedElementField",
                "type": "object",
                "properties": {
                    "name": {"type": "string"},
                    "offset": {"type": "integer", "minimum": 0},
                    "type": {"type": "integer"},
                },
            },
        },
        "data": {"type": "string", "contentEncoding": "base64", "description": "Grid cell data, row-major"},
    },
}

TOPICS: dict[str, str] = {
    "/missiontree/ticks": "missiontree.Tick",
    "/missiontree/transitions": "missiontree.NodeTransition",
    "/missiontree/blackboard": "missiontree.BlackboardChange",
    "/missiontree/events": "missiontree.Event",
    "/missiontree/log": "foxglove.Log",
    "/robot/pose": "foxglove.PoseInFrame",
    "/map": "foxglove.Grid",
}
#: foxglove.NumericType of an int8 cell.
_INT8 = 2

_LEVEL = {"failure": 4, "alarm": 3}


def _ns(t: float) -> int:
    return max(round(t * 1e9), 0)


def _stamp(t: float) -> dict[str, int]:
    ns = _ns(t)
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def _encode(message: dict[str, Any]) -> bytes:
    return json.dumps(message, sort_keys=True, separators=(",", ":"), ensure_ascii=False).encode("utf-8")


def _messages(replay: Replay, mission: str) -> list[tuple[int, int, str, dict[str, Any]]]:
    """(log time ns, order, topic, message) of everything, sorted by time then by order written."""
    out = _Messages(replay, mission)
    events_by_tick: dict[int, list[Any]] = {}
    for event in replay.events:
        events_by_tick.setdefault(event.tick, []).append(event)
    bb_by_tick: dict[int, list[tuple[str, Any]]] = {}
    for at, key, value in replay.blackboard:
        bb_by_tick.setdefault(at, []).append((key, value))
    for at, number in enumerate(replay.tick_numbers):
        for event in events_by_tick.get(at, []):
            out.event(number, event)
        out.tick(at, number)
        t = replay.times[at]
        for key, value in bb_by_tick.get(at, []):
            message: dict[str, Any] = {"tick": number, "t": t, "key": key, "removed": value is UNSET}
            if value is not UNSET:
                message["value"] = value
            out.add(t, "/missiontree/blackboard", message)
    if replay.halted and replay.tick_numbers:
        t = float(replay.halted_t)
        for change in replay.halted:
            path = replay.nodes[change.node].path
            out.add(
                t,
                "/missiontree/transitions",
                _transition(replay.tick_numbers[-1], t, path, change, halt=True),
            )
    out.poses()
    out.found.sort(key=lambda m: (m[0], m[1]))
    return out.found


class _Messages:
    """The messages of a run, in the order written (:func:`_messages` sorts them by time)."""

    def __init__(self, replay: Replay, mission: str) -> None:
        self.replay = replay
        self.mission = mission
        self.found: list[tuple[int, int, str, dict[str, Any]]] = []

    def add(self, t: float, topic: str, message: dict[str, Any]) -> None:
        """One message at robot time ``t``."""
        self.found.append((_ns(t), len(self.found), topic, message))

    def log(self, t: float, level: int, message: str, name: str) -> None:
        """A ``foxglove.Log`` line."""
        self.add(
            t,
            "/missiontree/log",
            {"timestamp": _stamp(t), "level": level, "message": message, "name": name, "file": "", "line": 0},
        )

    def event(self, number: int, event: Any) -> None:
        """A leaf's event, and its log line."""
        category = event_category(event)
        node = str(event.fields.get("node", ""))
        self.add(
            event.t,
            "/missiontree/events",
            {
                "tick": number,
                "t": event.t,
                "kind": event.kind,
                "category": category,
                "node": node,
                "fields": event.fields,
            },
        )
        detail = " ".join(
            f"{k}={json.dumps(v, sort_keys=True)}" for k, v in sorted(event.fields.items()) if k != "node"
        )
        self.log(event.t, _LEVEL.get(category, 2), f"{event.kind}: {detail}".strip(), node or self.mission)

    def tick(self, at: int, number: int) -> None:
        """The tick's line and its transitions; a log line for each leaf that failed with a reason."""
        replay = self.replay
        t = replay.times[at]
        first, end = replay.change_start[at], replay.change_start[at + 1]
        self.add(
            t,
            "/missiontree/ticks",
            {"tick": number, "t": t, "status": STATUSES[replay.root_status[at]], "changes": end - first},
        )
        for change in replay.changes[first:end]:
            path = replay.nodes[change.node].path
            self.add(t, "/missiontree/transitions", _transition(number, t, path, change, halt=False))
            if change.status == 3 and change.reason and not replay.nodes[change.node].children:
                self.log(t, 4, f"FAILURE: {change.reason}", path)

    def poses(self) -> None:
        """The trajectory as ``foxglove.PoseInFrame``, headed along the path."""
        poses = self.replay.poses
        for index, (t, x, y) in enumerate(poses):
            nxt = poses[min(index + 1, len(poses) - 1)]
            prev = poses[max(index - 1, 0)]
            moved = (nxt[1], nxt[2]) != (prev[1], prev[2])
            yaw = math.atan2(nxt[2] - prev[2], nxt[1] - prev[1]) if moved else 0.0
            orientation = {
                "x": 0.0,
                "y": 0.0,
                "z": round(math.sin(yaw / 2), 6),
                "w": round(math.cos(yaw / 2), 6),
            }
            self.add(
                t,
                "/robot/pose",
                {
                    "timestamp": _stamp(t),
                    "frame_id": "map",
                    "pose": {"position": {"x": x, "y": y, "z": 0.0}, "orientation": orientation},
                },
            )


def _transition(number: int, t: float, path: str, change: Any, halt: bool) -> dict[str, Any]:
    message = {
        "tick": number,
        "t": t,
        "node": path,
        "status": STATUSES[change.status],
        "was": STATUSES[change.was],
        "feedback": change.feedback,
        "reason": change.reason,
    }
    if halt:
        message["halt"] = True
    return message


def grid_message(grid_map: dict[str, Any], t: float) -> dict[str, Any]:
    """The viewer's map (a PNG with resolution and origin) as a ``foxglove.Grid`` of occupancy (-1/0/100)."""
    import base64

    import cv2
    import numpy as np

    image = cv2.imdecode(np.frombuffer(base64.b64decode(grid_map["png"]), np.uint8), cv2.IMREAD_GRAYSCALE)
    if image is None:
        raise ValueError("the run's map is not a PNG image")
    rows = np.flipud(image)  # the PNG's top row is the highest y; the grid's first row is the lowest
    cells: np.ndarray = np.full(rows.shape, -1, dtype=np.int8)
    cells[rows >= 250] = 0
    cells[rows <= 50] = 100
    resolution = float(grid_map["resolution"])
    return {
        "timestamp": _stamp(t),
        "frame_id": "map",
        "pose": {
            "position": {"x": float(grid_map["origin"][0]), "y": float(grid_map["origin"][1]), "z": 0.0},
            "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
        },
        "column_count": int(cells.shape[1]),
        "cell_size": {"x": resolution, "y": resolution},
        "row_stride": int(cells.shape[1]),
        "cell_stride": 1,
        "fields": [{"name": "occupancy", "offset": 0, "type": _INT8}],
        "data": base64.b64encode(cells.tobytes()).decode("ascii"),
    }


def write_mcap(replay: Replay, path: Path, mission: str = "", grid_map: dict[str, Any] | None = None) -> Path:
    """Write the run as an MCAP file (deterministic: the same run gives the same bytes).

    ``grid_map`` (the viewer's map, see :func:`missiontree.runlog.html.run_map`) goes on ``/map``
    once, at the first tick's time.

    Raises:
        BackendUnavailableError: The ``mcap`` library is not installed (names the extra).
    """
    try:
        from mcap.writer import CompressionType, Writer
    except ImportError as error:
        raise BackendUnavailableError(
            "the MCAP export needs the viewer extra: pip install 'missiontree[viewer]' (the mcap library)"
        ) from error
    mission = mission or str(replay.started.get("mission", "")) or "mission"
    path = Path(path)
    with path.open("wb") as stream:
        writer = Writer(stream, compression=CompressionType.ZSTD)
        writer.start(profile="", library=f"missiontree {__version__}")
        channels = _register(writer, mission)
        sequence: dict[str, int] = {}
        messages = _messages(replay, mission)
        if grid_map is not None:
            first = replay.times[0] if replay.times else 0.0
            messages.insert(0, (_ns(first), -1, "/map", grid_message(grid_map, first)))
        for log_time, _, topic, message in messages:
            sequence[topic] = sequence.get(topic, 0) + 1
            writer.add_message(
                channel_id=channels[topic],
                log_time=log_time,
                publish_time=log_time,
                data=_encode(message),
                sequence=sequence[topic],
            )
        writer.add_metadata("missiontree.run", _run_metadata(replay, mission))
        writer.finish()
    return path


def _register(writer: Any, mission: str) -> dict[str, int]:
    """Register every schema and topic with the writer; channel ids by topic."""
    schema_ids = {
        name: writer.register_schema(
            name=name, encoding="jsonschema", data=json.dumps(schema, sort_keys=True).encode("utf-8")
        )
        for name, schema in SCHEMAS.items()
    }
    return {
        topic: writer.register_channel(
            topic=topic,
            message_encoding="json",
            schema_id=schema_ids[schema],
            metadata={"mission": mission},
        )
        for topic, schema in TOPICS.items()
    }


def _run_metadata(replay: Replay, mission: str) -> dict[str, str]:
    """The run's ``missiontree.run`` metadata record: mission, outcome, ticks, seed, robot."""
    return {
        "mission": mission,
        "status": str(replay.finished.get("status", "")),
        "stopped_by": str(replay.finished.get("stopped_by", "")),
        "ticks": str(len(replay)),
        "seed": str(replay.started.get("seed", "")),
        "robot": str(replay.started.get("robot", "")),
    }
