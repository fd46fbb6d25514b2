"""The leaf a substitution rule puts in place of a node (:mod:`missiontree.engine.substitute`).

It keeps the replaced node's name (so its path in the tick log is unchanged), is RUNNING until
``after`` seconds have passed on the robot's clock, then writes its blackboard values and returns
its status (a RUNNING stub writes them and stays RUNNING). It is never written in a mission file:
only a rules file makes one, so it is not a registered node type.
"""

from __future__ import annotations

from typing import Any

import py_trees

from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.nodes.clock import clock_of


class Stub(Leaf):
    """Stands in for a substituted node: a fixed status after a delay, with blackboard writes.

    Args:
        name: The replaced node's name.
        status: SUCCESS, FAILURE or RUNNING.
        after: Seconds (robot clock) of RUNNING before the status is returned.
        writes: Blackboard keys and values written when ``after`` has passed.
        rule: Where the rule was written (``rules.yaml:3:5``), shown in the feedback.
        replaced: The type of the replaced node.
    """

    def __init__(self, name: str, *, status: Status, after: float = 0.0, writes: dict[str, Any] | None = None,
                 rule: str = "", replaced: str = "") -> None:
        super().__init__(name)
        self.result = status
        self.after = float(after)
        self.writes = dict(writes or {})
        self.rule = rule
        self.replaced = replaced
        self._started = 0.0
        self._written = False
        # through a client that registers its keys, so a fleet's namespacing moves them as it does
        # the replaced node's (each robot's stub writes its own /robotN/ key)
        self._board = self.attach_blackboard_client(name=f"{name} (substituted)")
        for key in self.writes:
            self._board.register_key(key=key, access=py_trees.common.Access.WRITE)

    def initialise(self) -> None:
        """Start the delay on the robot's clock."""
        self._started = clock_of(self.ctx)()
        self._written = False

    def update(self) -> Status:
        """RUNNING until ``after`` has passed; then write the values and return the status."""
        waited = clock_of(self.ctx)() - self._started
        said = f"substituted {self.replaced} ({self.rule})"
        if waited < self.after - 1e-9:
            return self.running(f"{said}: {self.result.name} in {self.after - waited:.1f} s")
        if not self._written:
            for key, value in self.writes.items():
                self._board.set(key, value, overwrite=True)
            self._written = True
        if self.result == Status.FAILURE:
            return self.fail(f"{said}: FAILURE")
        if self.result == Status.RUNNING:
            return self.running(f"{said}: RUNNING")
        return self.succeed(f"{said}: SUCCESS")
