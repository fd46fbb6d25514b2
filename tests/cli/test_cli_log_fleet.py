"""``log summarize`` on a fleet run: each robot's end, loss and events, and the re-balancings."""

from __future__ import annotations

from missiontree.cli.log import format_summary, summarize

LINES = [
    {"event": "mission_started", "mission": "fleet_patrol", "t": 0.0},
    {"event": "goal_sent", "robot": "robot1", "t": 0.0},
    {"event": "goal_sent", "robot": "robot2", "t": 0.0},
    {"event": "tick", "tick": 1, "t": 0.0, "status": "RUNNING",
     "changed": [{"node": "fleet/robot1", "status": "RUNNING"},
                 {"node": "fleet/robot2", "status": "RUNNING"}]},
    {"event": "robot_lost", "robot": "robot2", "t": 5.0, "reason": "killed"},
    {"event": "fleet_rebalanced", "t": 5.0, "lost": "robot2", "assignment": {"robot1": ["P1", "P2"]}},
    {"event": "tick", "tick": 2, "t": 5.0, "status": "RUNNING",
     "changed": [{"node": "fleet/robot2", "status": "FAILURE", "was": "RUNNING"}]},
    {"event": "waypoint_reached", "robot": "robot1", "t": 9.0},
    {"event": "tick", "tick": 3, "t": 9.0, "status": "SUCCESS",
     "changed": [{"node": "fleet/robot1", "status": "SUCCESS", "was": "RUNNING"},
                 {"node": "fleet", "status": "SUCCESS", "was": "RUNNING"}]},
    {"event": "mission_finished", "status": "SUCCESS", "stopped_by": "status", "duration": 9.0, "t": 9.0},
]


def test_each_robot_is_summarised_with_its_end_and_loss() -> None:
    """robot1 SUCCESS with its events, robot2 FAILURE lost at 5 s, and the re-balancing listed."""
    summary = summarize(LINES)
    assert summary["robots"]["robot1"]["status"] == "SUCCESS"
    assert summary["robots"]["robot1"]["events"] == {"goal_sent": 1, "waypoint_reached": 1}
    assert summary["robots"]["robot2"]["status"] == "FAILURE"
    assert summary["robots"]["robot2"]["lost"] == {"t": 5.0, "reason": "killed"}
    text = format_summary(summary)
    assert "robot2: FAILURE — lost at 5.0 s: killed" in text
    assert "re-balanced at 5.0 s after losing robot2: robot1: P1, P2" in text


def test_a_single_robot_log_has_no_robot_section() -> None:
    """Events without a robot field leave the summary as it was."""
    summary = summarize([line for line in LINES if "robot" not in line])
    assert "robots" not in summary
