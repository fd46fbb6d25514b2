"""ServeCommands: run a child once per user command, the one given or each from the robot's channel.

The decorator takes the user's commands — the one given as a parameter (``--set command="I'm
thirsty"``), or one after another from the robot's command channel (stdin in the simulator,
``/command`` on ROS 2, see :mod:`missiontree.robot.commands`) — writes each to the blackboard and
runs its child (e.g. :class:`~missiontree.behaviours.intent.GoToIntent`) once per command.

Tick-log events: ``command_received``, ``command_served``, ``command_refused`` (input the channel
could not read as a command, such as a line that is not UTF-8: it counts as a failed command, so the
node cannot end SUCCESS with "every command served" while one was lost).
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Annotated, Any

import py_trees
from pydantic import BaseModel, ConfigDict, Field

from missiontree.engine.faults import fault_of, verdict_of
from missiontree.engine.leaf import Status
from missiontree.engine.node_words import failure_reason
from missiontree.engine.ports import Output, ports_of
from missiontree.engine.registry import NodeType

Behaviour = py_trees.behaviour.Behaviour


class ServeCommandsParams(BaseModel):
    """Parameters of ServeCommands."""

    model_config = ConfigDict(extra="forbid")

    command: str = Field(
        "",
        description="The command to serve; empty: serve the robot's command channel "
        "(stdin in the simulator, /command on ROS 2) one command after another.",
    )
    max_commands: int = Field(
        0,
        ge=0,
        description="End after this many commands from the channel (0: until "
        "the channel closes, which stdin does at its end; a topic never does).",
    )
    command_key: Annotated[str, Output("the command being served", type="str")] = "intent_command"


class ServeCommands(py_trees.decorators.Decorator):
    """Run the child once per user command: the `command` given, or each command from the robot's channel.

    With ``command`` set it ends with the child's status. Otherwise it waits for commands (RUNNING),
    serves them in turn (one that arrives meanwhile waits its turn), and ends when the channel closes:
    SUCCESS when every command was served, FAILURE naming those that were not.
    """

    def __init__(self, name: str, child: Behaviour, params: ServeCommandsParams) -> None:
        super().__init__(name=name, child=child)
        self.params = params
        self.ctx: Any = None
        self.bb = self.attach_blackboard_client(name=name)
        self.bb.register_key(key=params.command_key, access=py_trees.common.Access.WRITE)
        self.waiting: list[tuple[float, str]] = []
        self.current: str | None = None
        self.served: list[tuple[str, bool, str]] = []
        self.given_done = False
        self.failure_reason = ""

    def setup(self, **kwargs: Any) -> None:
        """Keep the mission context."""
        self.ctx = kwargs.get("context", self.ctx)

    def initialise(self) -> None:
        """Start afresh (a given command is served again when the node is re-entered)."""
        self.waiting.clear()
        self.current = None
        self.served.clear()
        self.given_done = False

    def tick(self) -> Iterator[Behaviour]:
        """Take the next command when idle, tick the child while a command is served."""
        if self.status != Status.RUNNING:
            self.initialise()
        if self.current is None:
            self._take_next()
        if self.current is not None:
            yield from self.decorated.tick()
            child = self.decorated.status
            if child in (Status.SUCCESS, Status.FAILURE):
                reason = said_by(self.decorated)
                self.served.append((self.current, child == Status.SUCCESS, reason))
                self._emit("command_served", command=self.current, status=child.value.lower(), reason=reason)
                self.current = None
        new_status = self._status_now()
        if new_status != Status.RUNNING:
            self.stop(new_status)
        self.status = new_status
        yield self

    def update(self) -> Status:
        """Not used: :meth:`tick` decides (py_trees calls update only from its own tick)."""
        return self.status

    def _take_next(self) -> None:
        if self.params.command.strip():
            if not self.given_done:
                self.given_done = True
                self._start(self.params.command, "parameter", self._now())
            return
        robot = self.ctx.robot if self.ctx is not None else None
        poll = getattr(robot, "commands", None)
        if callable(poll):
            for command in poll():
                if getattr(command, "error", ""):  # input that is not a command: reported, never dropped
                    self.served.append(("(unreadable input)", False, command.error))
                    self._emit("command_refused", error=command.error, stamp=command.stamp,
                               source=command.source)
                    continue
                self.waiting.append((command.stamp, command.text))
                self._emit(
                    "command_received", command=command.text, stamp=command.stamp, source=command.source
                )
        if self.waiting and not self._limit_reached():
            stamp, text = self.waiting.pop(0)
            self._start(text, "channel", stamp)

    def _start(self, text: str, source: str, stamp: float) -> None:
        self.current = text
        self.bb.set(self.params.command_key, text, overwrite=True)
        if source == "parameter":
            self._emit("command_received", command=text, stamp=stamp, source=source)
        self.feedback_message = f"serving {text!r}"

    def _status_now(self) -> Status:
        if self.current is not None:
            return Status.RUNNING
        if self.params.command.strip():
            ok, reason = self.served[-1][1:] if self.served else (False, "not served")
            return self._end(ok, reason)
        robot = self.ctx.robot if self.ctx is not None else None
        if not callable(getattr(robot, "commands", None)):
            return self._end(
                False,
                'no command given and this robot has no command channel; give one with --set command="..."',
            )
        closed = getattr(robot, "commands_closed", None)
        if self._limit_reached() or (callable(closed) and closed() and not self.waiting):
            failed = [(c, r) for c, ok, r in self.served if not ok]
            if not self.served:
                return self._end(False, "the command channel closed before any command came")
            if failed:
                shown = "; ".join(f"{c!r}: {r}" for c, r in failed[:3])
                return self._end(False, f"{len(failed)} of {len(self.served)} commands failed: {shown}")
            return self._end(True, f"{len(self.served)} commands served")
        self.feedback_message = (
            f"waiting for a command ({len(self.served)} served)"
            if not self.waiting
            else f"{len(self.waiting)} commands waiting"
        )
        return Status.RUNNING

    def _limit_reached(self) -> bool:
        return bool(self.params.max_commands) and len(self.served) >= self.params.max_commands

    def _end(self, ok: bool, reason: str) -> Status:
        self.feedback_message = reason
        self.failure_reason = "" if ok else reason
        return Status.SUCCESS if ok else Status.FAILURE

    def _now(self) -> float:
        return float(self.ctx.robot.now()) if self.ctx is not None else 0.0

    def _emit(self, event: str, **fields: Any) -> None:
        if self.ctx is not None:
            self.ctx.events.emit(event, node=self.name, **fields)


def said_by(node: Behaviour) -> str:
    """What a finished child says of its outcome: a verdict or fault below it, else the last leaf's words.

    A subtree's composites and decorators say little themselves ("succeeded [status: ...]"): the leaf
    that ran last (down the running child of each) is asked first, then the nodes above it.
    """
    if node.status == Status.FAILURE:
        found = verdict_of(node) or fault_of(node)
        if found is not None:
            return found[1]
    chain = [node]
    while (below := getattr(chain[-1], "decorated", None) or getattr(chain[-1], "current_child", None)):
        chain.append(below)
    for step in reversed(chain):
        words = failure_reason(step) if step.status == Status.FAILURE else step.feedback_message
        if words:
            return str(words)
    return ""


def _serve_commands(name: str, params: BaseModel, children: list[Behaviour]) -> Behaviour:
    if len(children) != 1:
        raise ValueError(f"ServeCommands takes exactly one child, found {len(children)}")
    assert isinstance(params, ServeCommandsParams)
    return ServeCommands(name, children[0], params)


SERVE_COMMANDS = NodeType(
    "ServeCommands",
    "decorator",
    ServeCommandsParams,
    _serve_commands,
    "Run the child once per user command: the `command` given, or each from the robot's command channel.",
    ports=ports_of(ServeCommandsParams),
)
