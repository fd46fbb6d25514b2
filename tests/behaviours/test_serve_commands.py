"""ServeCommands over stdin: input that cannot be read as a command is reported, never dropped silently."""

from __future__ import annotations

import io

import py_trees

from missiontree.backends.sim import create_robot
from missiontree.behaviours.commands import ServeCommands, ServeCommandsParams
from missiontree.engine.context import MissionContext
from missiontree.robot.commands import LineCommands
from missiontree.testing import capture_tick_log


class _Record(py_trees.behaviour.Behaviour):
    """A child that records each command it is run for and succeeds."""

    def __init__(self, seen: list[str]) -> None:
        super().__init__("record")
        self.seen = seen
        self.bb = self.attach_blackboard_client("record")
        self.bb.register_key("intent_command", access=py_trees.common.Access.READ)

    def update(self) -> py_trees.common.Status:
        self.seen.append(self.bb.get("intent_command"))
        return py_trees.common.Status.SUCCESS


def test_a_line_that_is_not_utf8_fails_the_node_and_later_commands_are_served() -> None:
    """Lines "first", a byte 0xff, "second": both commands served, the bad line named, the node FAILURE."""
    robot = create_robot({"world": "office", "seed": 1})
    stdin = io.TextIOWrapper(io.BytesIO(b"first\nbad \xff line\nsecond\n"), encoding="utf-8", errors="strict")
    robot.command_input = LineCommands(stdin)
    seen: list[str] = []
    root = ServeCommands("serve", _Record(seen), ServeCommandsParams(command=""))
    try:
        result, log = capture_tick_log(root, MissionContext(robot=robot), max_duration=30.0)
    finally:
        robot.close()
    assert seen == ["first", "second"]
    assert result.status.value == "FAILURE"
    refused = [e for e in log if e.get("event") == "command_refused"]
    assert refused and "line 2 on stdin is not UTF-8" in refused[0]["error"]
    assert "1 of 3 commands failed" in root.feedback_message
