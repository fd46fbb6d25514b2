"""What nodes say: unique paths, py_trees' decorator phrases in the mission's words, absorbers."""

from __future__ import annotations

import py_trees
from py_trees.common import Status

from missiontree.engine.node_words import absorber, failure_reason, feedback_of, node_paths


def _leaf(name: str, status: Status) -> py_trees.behaviour.Behaviour:
    return py_trees.behaviours.StatusQueue(name, queue=[status], eventually=status)


def test_repeated_names_get_their_index_and_paths_are_unique():
    root = py_trees.composites.Sequence("Root", memory=False,
                                        children=[_leaf("Go", Status.SUCCESS), _leaf("Go", Status.SUCCESS),
                                                  _leaf("Look", Status.SUCCESS)])
    paths = node_paths(root)
    assert sorted(paths.values()) == ["Root", "Root/Go[0]", "Root/Go[1]", "Root/Look"]


def test_decorator_feedback_is_put_in_the_mission_files_words():
    child = _leaf("Check", Status.SUCCESS)
    force = py_trees.decorators.SuccessIsFailure("force", child=child)
    force.tick_once()
    assert force.status is Status.FAILURE
    assert feedback_of(force).startswith("ForceFailure: the child succeeded, FAILURE by design")
    assert failure_reason(force) == feedback_of(force)
    retry = py_trees.decorators.Retry("retry", child=_leaf("Try", Status.FAILURE), num_failures=3)
    retry.tick_once()
    assert feedback_of(retry) == "Retry: attempt 1 of 3 failed, trying again"


def test_a_leaf_reason_wins_over_its_feedback():
    leaf = _leaf("GoTo", Status.FAILURE)
    leaf.feedback_message = "planning"
    assert failure_reason(leaf) == "planning"
    leaf.failure_reason = "no path to (3.0, 4.0)"  # type: ignore[attr-defined]
    assert failure_reason(leaf) == "no path to (3.0, 4.0)"


def test_the_first_ancestor_that_did_not_fail_absorbed_the_failure():
    status = {"Root": "SUCCESS", "Root/Choose": "SUCCESS", "Root/Choose/First": "FAILURE"}
    assert absorber("Root/Choose/First/GoTo", status.get) == "Root/Choose"
    assert absorber("Root/GoTo", {"Root": "FAILURE"}.get) is None
