"""What a tree's nodes say, in the mission file's words: paths, feedback, failure reasons.

Shared by the live run (:class:`~missiontree.engine.tick_log.TickRecorder`, the run summary) and
the log read back (``missiontree log summarize``), so both name nodes and failures alike:

- :func:`node_paths`: readable, unique paths (``Root/Patrol/GoTo``, ``[i]`` for repeated names).
- :func:`feedback_of`: a node's feedback, py_trees' decorator phrases ("success is failure")
  replaced by the mission file's names (ForceFailure, Retry, Repeat, ...).
- :func:`failure_reason`: why a node failed (a leaf's ``failure_reason``, else its feedback).
- :func:`absorber`: which ancestor absorbed a failure, or None when it decided the outcome.
"""

from __future__ import annotations

import re
from collections import Counter
from collections.abc import Callable

import py_trees

Behaviour = py_trees.behaviour.Behaviour

def node_paths(root: Behaviour) -> dict[Behaviour, str]:
    """Readable, unique paths of every node: ``Root/Patrol/GoTo``, ``[i]`` added to repeated names.

    Linear in the number of nodes (a composite's repeated names are counted once, not per child).
    """
    paths: dict[Behaviour, str] = {root: root.name}
    stack = [root]
    while stack:
        node = stack.pop()
        names = Counter(child.name for child in node.children)
        for index, child in enumerate(node.children):
            suffix = f"[{index}]" if names[child.name] > 1 else ""
            paths[child] = f"{paths[node]}/{child.name}{suffix}"
            stack.append(child)
    return paths


_RETRY_RE = re.compile(
    r"^(attempt failed|final failure|running|succeeded) \[status: (\d+) failure from (\d+)\]$")
_REPEAT_RE = re.compile(r"^(failed, aborting|success|running) \[status: (\d+) success from (-?\d+)\]$")


def _wrapped(prefix: str, message: str, words: str) -> str | None:
    """``words`` plus the child's feedback when ``message`` is py_trees' ``prefix [child]``."""
    if message == prefix:
        return words
    if message.startswith(prefix + " [") and message.endswith("]"):
        return f"{words} [{message[len(prefix) + 2:-1]}]"
    return None


def _retry_words(message: str) -> str | None:
    found = _RETRY_RE.match(message)
    if found is None:
        return None
    kind, done, limit = found.groups()
    return {"attempt failed": f"Retry: attempt {done} of {limit} failed, trying again",
            "final failure": f"Retry: all {limit} attempts failed",
            "running": f"Retry: attempt {int(done) + 1} of {limit} running",
            "succeeded": f"Retry: succeeded after {done} failed attempt(s)"}[kind]


def _repeat_words(message: str) -> str | None:
    found = _REPEAT_RE.match(message)
    if found is None:
        return None
    kind, done, limit = found.groups()
    total = "forever" if limit == "-1" else f"of {limit}"
    return {"failed, aborting": f"Repeat: the child failed after {done} success(es) {total}",
            "success": f"Repeat: {done} success(es) {total}, done",
            "running": f"Repeat: {done} success(es) {total} so far"}[kind]


#: py_trees decorator → rewrite of its feedback into the mission file's words (None: keep it).
_FEEDBACK_WORDS: dict[type, Callable[[str], str | None]] = {
    py_trees.decorators.SuccessIsFailure: lambda m: _wrapped(
        "success is failure", m, "ForceFailure: the child succeeded, FAILURE by design"),
    py_trees.decorators.FailureIsSuccess: lambda m: _wrapped(
        "failure is success", m, "ForceSuccess: the child failed, SUCCESS by design"),
    py_trees.decorators.Inverter: lambda m: {"success -> failure": "Inverter: the child succeeded",
                                             "failure -> success": "Inverter: the child failed"}.get(m),
    py_trees.decorators.Retry: _retry_words,
    py_trees.decorators.Repeat: _repeat_words,
}


_WORDS_OF_CLASS: dict[type, Callable[[str], str | None] | None] = {}


def _words_of(cls: type) -> Callable[[str], str | None] | None:
    """The rewrite for ``cls`` or the nearest of its bases that has one (a subclass keeps its words)."""
    if cls not in _WORDS_OF_CLASS:
        _WORDS_OF_CLASS[cls] = next((_FEEDBACK_WORDS[k] for k in cls.__mro__ if k in _FEEDBACK_WORDS), None)
    return _WORDS_OF_CLASS[cls]


def feedback_of(node: Behaviour) -> str:
    """The node's feedback message, py_trees' own phrases put in the mission file's words."""
    message = node.feedback_message
    if message:
        rewrite = _words_of(node_class(node))
        if rewrite is not None:
            return rewrite(message) or message
    return message


#: Attribute of a watched class naming the node's own class.
BASE_CLASS = "_missiontree_base_class"


def node_class(node: Behaviour) -> type:
    """The node's own class, also while a recorder watches it."""
    cls = type(node)
    return getattr(cls, BASE_CLASS, cls)


def failure_reason(node: Behaviour) -> str:
    """Why ``node`` failed: a Leaf's ``failure_reason``, else its feedback message."""
    return getattr(node, "failure_reason", "") or feedback_of(node)


def absorber(path: str, status_of: Callable[[str], str | None]) -> str | None:
    """Which ancestor absorbed a failure of the node at ``path``, or None when it decided the outcome.

    Walks up the path (``a/b/c`` → ``a/b`` → ``a``): the first ancestor whose status at the end of
    the tick is not FAILURE absorbed it (a Selector moving on, a Retry, an Inverter); when every
    ancestor failed too, the failure reached the root. The same rule serves the run summary (on the
    live tree) and ``log summarize`` (on the statuses replayed from the log), so both agree.

    Args:
        path: The failed node's path.
        status_of: Status name of a node path at the end of the tick (None: not known, taken as
            not failed).
    """
    while "/" in path:
        path = path.rsplit("/", 1)[0]
        if status_of(path) != "FAILURE":
            return path
    return None
