"""The queryable SQLite log: runs written from their tick logs, queried read-only."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from missiontree.cli.main import main
from missiontree.engine.build import build_tree
from missiontree.engine.context import MissionContext
from missiontree.engine.loader import load_mission
from missiontree.engine.runner import Runner
from missiontree.errors import ConfigError
from missiontree.runlog.sqlite_log import EXAMPLES, add_run, connect, query
from missiontree.testing import ClockRobot, clean_state, fresh_plugins

MISSION = """\
version: 1
blackboard: {n: 0}
root:
  Selector:
    name: try
    memory: true
    children:
      - ScriptCondition: {name: door_open, code: "n % 4 == 0"}
      - ScriptCondition: {name: window_open, code: "n % 2 == 0"}
      - Succeed: {name: chimney}
"""


def _runs(tmp_path: Path, count: int) -> list[Path]:
    """``count`` runs of the small mission, run ``i`` with ``n = i`` (on a clock-only robot)."""
    mission = tmp_path / "doors.yaml"
    mission.write_text(MISSION)
    registry = fresh_plugins().nodes
    spec = load_mission(mission, registry)
    dirs = []
    for index in range(count):
        clean_state()
        out = tmp_path / "runs" / f"r{index}"
        Runner(build_tree(spec, registry), MissionContext(robot=ClockRobot()), run_dir=out, mission="doors",
               blackboard={"n": index}, handle_signals=False, max_duration=5.0).run()
        dirs.append(out)
    clean_state()
    return dirs


def test_a_hundred_runs_answer_which_node_failed_most_in_one_query(tmp_path: Path) -> None:
    """Across 100 runs the door fails 75 times and the window 50: one query says which failed most."""
    db_path = tmp_path / "log.sqlite"
    db = connect(db_path)
    for run in _runs(tmp_path, 100):
        add_run(db, run)
    db.close()
    columns, rows = query(db_path, EXAMPLES["failures per leaf"])
    assert columns == ["node", "failures"]
    assert rows == [("try/door_open", 75), ("try/window_open", 50)]
    assert query(db_path, "SELECT COUNT(*) FROM runs")[1] == [(100,)]


def test_tables_hold_the_tree_transitions_events_and_the_run(tmp_path: Path) -> None:
    """One run gives its nodes, its status changes (the final halt marked) and its runner lines."""
    db_path = tmp_path / "log.sqlite"
    db = connect(db_path)
    add_run(db, _runs(tmp_path, 1)[0])
    db.close()
    assert query(db_path, "SELECT status, ticks FROM runs")[1] == [("SUCCESS", 1)]
    paths = [row[0] for row in query(db_path, "SELECT node FROM transitions WHERE halted = 0")[1]]
    assert "try/door_open" in paths
    kinds = {row[0] for row in query(db_path, "SELECT kind FROM events")[1]}
    assert {"mission_started", "mission_finished"} <= kinds


def test_writing_a_run_again_replaces_it(tmp_path: Path) -> None:
    """The same run directory written twice is one run (a resumed batch does not double count)."""
    db_path = tmp_path / "log.sqlite"
    run = _runs(tmp_path, 1)[0]
    db = connect(db_path)
    add_run(db, run)
    add_run(db, run)
    db.close()
    assert query(db_path, "SELECT COUNT(*) FROM runs")[1] == [(1,)]
    assert query(db_path, "SELECT COUNT(DISTINCT run_id) FROM transitions")[1] == [(1,)]


def test_a_query_cannot_write(tmp_path: Path) -> None:
    """The database is opened read-only: DELETE is refused and nothing is lost."""
    db_path = tmp_path / "log.sqlite"
    db = connect(db_path)
    add_run(db, _runs(tmp_path, 1)[0])
    db.close()
    with pytest.raises(ConfigError, match="readonly"):
        query(db_path, "DELETE FROM runs")
    assert query(db_path, "SELECT COUNT(*) FROM runs")[1] == [(1,)]


def test_cli_export_then_query(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`log export --format sqlite` appends runs; `log query` prints rows (an example by name, or JSON)."""
    runs = _runs(tmp_path, 4)
    out = tmp_path / "all.sqlite"
    for run in runs:
        assert main(["log", "export", str(run), "--format", "sqlite", "--out", str(out)]) == 0
    capsys.readouterr()
    assert main(["log", "query", str(out), "outcomes", "--json"]) == 0
    rows = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert rows == [{"runs": 4, "status": "SUCCESS", "stopped_by": "status"}]


def test_a_run_directory_is_queried_without_an_export(tmp_path: Path) -> None:
    """`log query RUN_DIR SQL` reads the run into memory: the same tables, nothing written."""
    run = _runs(tmp_path, 2)[1]
    sql = "SELECT node, COUNT(*) FROM transitions WHERE status = 'FAILURE' GROUP BY node ORDER BY node"
    assert query(run, sql)[1] == [("try/door_open", 1), ("try/window_open", 1)]
    assert not list(run.glob("*.sqlite"))
