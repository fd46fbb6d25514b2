"""Hot reload (``run --watch``): a changed mission file replaces the running tree, the blackboard kept.

:class:`TreeWatcher` is called by the runner after every tick (its ``on_tick``). Every
``check_every`` seconds of robot time it looks at the mission file and every subtree it includes
(their size and modification time; their content when those changed). When one changed:

1. the mission is loaded and checked again (the same checks as before a run); the new tree is built
   (and substituted, when the run has substitution rules) and set up with the run's context;
2. if any of that fails, the problems are printed, a ``reload_refused`` event goes to the tick log,
   and the old tree keeps running (the same file is not reported again until it changes again);
3. else the old tree is halted (its running leaves cancel their work; a ``halted`` line), the robot
   is stopped, the new tree takes its place in the runner and a ``reloaded`` event is logged. The
   blackboard is kept: only the new mission's ``blackboard:`` defaults for keys not set are written.

The tree restarts from its root on the next tick. What the ``run:`` section says (world, robot,
tick rate) is not applied again: the robot and the run go on as they were started. The summary's
per-node counts are by path, so a node present before and after a reload is counted once (the
later tree's counts).
"""

from __future__ import annotations

import hashlib
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any, TextIO

import py_trees

from missiontree.engine.spec import MissionSpec
from missiontree.errors import ConfigError, ProblemsError

Behaviour = py_trees.behaviour.Behaviour

#: Robot seconds between two looks at the files (a change is picked up within this, plus a tick).
CHECK_EVERY = 0.25
#: Problems written into a ``reload_refused`` event at most (all are printed).
MAX_LOGGED_PROBLEMS = 20


class TreeWatcher:
    """Watches a running mission's files and swaps in the changed tree (see the module docstring).

    Args:
        spec: The running mission.
        load: Loads and checks the mission again (raises ProblemsError/ConfigError when broken).
        build: Builds a checked mission's tree (substitution included); raises ProblemsError.
        check_every: Robot seconds between looks at the files.
        out: Where reloads and problems are printed.
    """

    def __init__(self, spec: MissionSpec, load: Callable[[], MissionSpec],
                 build: Callable[[MissionSpec], Behaviour], *, check_every: float = CHECK_EVERY,
                 out: TextIO | None = None) -> None:
        self.spec = spec
        self.load = load
        self.build = build
        self.check_every = check_every
        self.out = out
        self.reloads = 0
        self.refusals = 0
        self._next = float("-inf")
        self._seen = {path: _state(path) for path in self._files(spec)}

    @staticmethod
    def _files(spec: MissionSpec) -> list[Path]:
        return list(dict.fromkeys([Path(spec.path), *(Path(f) for f in spec.files)]))

    def changed(self) -> list[Path]:
        """The watched files whose content changed since last seen (and note their new state)."""
        found = []
        for path, (stat, digest) in list(self._seen.items()):
            now = _stat(path)
            if now == stat:
                continue
            state = _state(path)
            self._seen[path] = state
            if state[1] != digest:
                found.append(path)
        return found

    def __call__(self, runner: Any) -> None:
        """Look at the files when it is time (robot clock); reload when one changed."""
        now = runner.robot.now()
        if now < self._next:
            return
        self._next = now + self.check_every
        changed = self.changed()
        if changed:
            self.reload(runner, changed)

    def reload(self, runner: Any, changed: list[Path]) -> bool:
        """Check, build and set up the changed mission; swap it in, or keep the old tree. True: swapped."""
        events = runner.context.events
        names = [str(path) for path in changed]
        try:
            spec = self.load()
            root = self.build(spec)
            for node in root.iterate():
                node.setup(context=runner.context)
        except ProblemsError as error:
            self._refuse(events, names, [str(problem) for problem in error.problems])
            return False
        except ConfigError as error:
            self._refuse(events, names, [str(error)])
            return False
        except Exception as error:  # noqa: BLE001 - a node's setup that raises: the old tree runs on
            self._refuse(events, names, [f"a node failed to set up: {type(error).__name__}: {error}"])
            return False
        runner.halt()
        runner.robot.stop()
        for key, value in spec.blackboard.items():
            name = key if key.startswith("/") else f"/{key}"
            if not py_trees.blackboard.Blackboard.exists(name):
                py_trees.blackboard.Blackboard.set(name, value)
        runner.replace_tree(root)  # guarded as the first tree; the log names its nodes by path
        runner.spec = spec
        for path in self._files(spec):  # a subtree newly included is watched from now on
            self._seen.setdefault(path, _state(path))
        self.spec = spec
        self.reloads += 1
        events.emit("reloaded", files=names, nodes=sum(1 for _ in root.iterate()))
        self._say(f"reloaded {', '.join(names)} at {runner.robot.now():.2f} s on the robot clock "
                  "(tree halted and rebuilt, blackboard kept)")
        return True

    def _refuse(self, events: Any, names: list[str], problems: list[str]) -> None:
        self.refusals += 1
        events.emit("reload_refused", files=names, problems=problems[:MAX_LOGGED_PROBLEMS],
                    count=len(problems))
        self._say(f"{', '.join(names)} changed but was not reloaded ({len(problems)} problem(s)); the "
                  "running tree goes on:\n" + "\n".join(f"  {problem}" for problem in problems))

    def _say(self, text: str) -> None:
        print(f"watch: {text}", file=self.out if self.out is not None else sys.stderr, flush=True)


def _stat(path: Path) -> tuple[int, int] | None:
    try:
        stat = path.stat()
    except OSError:
        return None
    return stat.st_mtime_ns, stat.st_size


def _state(path: Path) -> tuple[tuple[int, int] | None, str]:
    """A file's (mtime, size) and content digest ("" when it cannot be read)."""
    stat = _stat(path)
    try:
        digest = hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        digest = ""
    return stat, digest


__all__ = ["CHECK_EVERY", "TreeWatcher"]
