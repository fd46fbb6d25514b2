"""MCAP export: JSON channels with jsonschema schemas, read back with the mcap reader."""

from __future__ import annotations

import json
from pathlib import Path

from mcap.reader import make_reader
from runlog_helpers import read_lines

from missiontree.runlog.mcap_export import TOPICS, write_mcap
from missiontree.runlog.replay import open_run


def read_back(path: Path) -> tuple[dict, dict[str, list[dict]]]:
    with path.open("rb") as stream:
        reader = make_reader(stream)
        summary = reader.get_summary()
        messages: dict[str, list[dict]] = {}
        for schema, channel, message in reader.iter_messages():
            assert schema.encoding == "jsonschema" and channel.message_encoding == "json"
            messages.setdefault(channel.topic, []).append(
                {"log_time": message.log_time, **json.loads(message.data)}
            )
    schemas = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
    return schemas, messages


def test_channels_carry_ticks_transitions_blackboard_events_log_and_poses(patrol_run: Path, tmp_path: Path):
    """Every tick, change, blackboard write and event of the log is a message on its channel."""
    path = write_mcap(open_run(patrol_run), tmp_path / "run.mcap")
    schemas, messages = read_back(path)
    assert schemas == TOPICS
    lines = read_lines(patrol_run)
    ticks = [line for line in lines if line["event"] == "tick"]
    assert [m["tick"] for m in messages["/missiontree/ticks"]] == [line["tick"] for line in ticks]
    assert [m["status"] for m in messages["/missiontree/ticks"]] == [line["status"] for line in ticks]
    changes = [
        (line["tick"], c["node"], c["status"])
        for line in lines
        if line["event"] in ("tick", "halted")
        for c in line.get("changed", [])
    ]
    assert [(m["tick"], m["node"], m["status"]) for m in messages["/missiontree/transitions"]] == changes
    writes = [(line["tick"], key) for line in ticks for key in line.get("bb", {})]
    assert [(m["tick"], m["key"]) for m in messages["/missiontree/blackboard"]] == writes
    kinds = [
        line["event"]
        for line in lines
        if line["event"] not in ("tick", "halted", "mission_started", "mission_finished")
    ]
    assert [m["kind"] for m in messages["/missiontree/events"]] == kinds
    alarms = [m for m in messages["/missiontree/log"] if m["message"].startswith("alarm")]
    assert alarms and all(m["level"] == 3 for m in alarms)
    assert messages["/robot/pose"] and messages["/robot/pose"][0]["frame_id"] == "map"
    times = [m["log_time"] for topic in messages.values() for m in topic]
    assert min(times) >= 0


def test_messages_are_in_log_time_order(patrol_run: Path, tmp_path: Path):
    """Foxglove plays a file in log-time order; the writer keeps it."""
    path = write_mcap(open_run(patrol_run), tmp_path / "run.mcap")
    with path.open("rb") as stream:
        times = [
            message.log_time for _, _, message in make_reader(stream).iter_messages(log_time_order=False)
        ]
    assert times == sorted(times)


def test_the_same_run_gives_the_same_bytes(patrol_run: Path, tmp_path: Path):
    """Byte-identical output for the same run."""
    a = write_mcap(open_run(patrol_run), tmp_path / "a.mcap").read_bytes()
    b = write_mcap(open_run(patrol_run), tmp_path / "b.mcap").read_bytes()
    assert a == b


def test_the_map_goes_on_map_as_a_foxglove_grid(patrol_run: Path, tmp_path: Path):
    """The run's map is one foxglove.Grid message of int8 occupancy, as wide as the map."""
    import base64

    from missiontree.runlog.html import run_map

    grid_map = run_map(patrol_run)
    path = write_mcap(open_run(patrol_run), tmp_path / "run.mcap", grid_map=grid_map)
    _, messages = read_back(path)
    (grid,) = messages["/map"]
    cells = base64.b64decode(grid["data"])
    assert grid["column_count"] == grid_map["width"] and len(cells) == grid_map["width"] * grid_map["height"]
    assert set(cells) <= {0, 100, 255}  # free, occupied, unknown (-1 as a byte)
    assert grid["cell_size"]["x"] == grid_map["resolution"]
