"""A queryable log: runs written from their tick logs into one SQLite file (BT.CPP's ``SqliteLogger``).

The JSONL tick log stays the source of truth; this file is written from it, one run at a time or
appended for a batch, so a question over many runs is one query::

    SELECT node, COUNT(*) AS failures FROM transitions
    WHERE status = 'FAILURE' GROUP BY node ORDER BY failures DESC LIMIT 5;

Tables (every one keyed by ``run_id``):

- ``runs``: one row a run: ``name`` (the batch's run id or the directory), ``run_dir``, ``mission``,
  ``status``, ``stopped_by``, ``reason``, ``ticks``, ``duration`` (robot s), ``seed``, ``world``,
  ``params`` (JSON), ``summary`` (summary.json as JSON).
- ``nodes``: the tree definition: ``uid`` (depth-first from 0), ``path``, ``name``, ``type``,
  ``category`` (leaf, decorator, composite; a run that did not record its tree (no runview.json,
  no mission given) has its nodes learnt from the log: ``leaf`` when no child was seen, else
  empty), ``parent_uid``, ``params`` (JSON), ``source``
  (``file:line:col``).
- ``transitions``: every status change: ``tick``, ``t`` (robot s), ``node`` (path), ``uid``,
  ``status``, ``was``, ``feedback``, ``reason``; the halt at the end too (``halted`` = 1).
- ``events``: every event line (leaf events and the runner's ``mission_started``/``finished``):
  ``tick``, ``t``, ``kind``, ``node``, ``fields`` (the whole line as JSON, for ``json_extract``).

Writing a run whose ``run_dir`` is already in the file replaces it (a resumed batch appends once).
"""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from missiontree.engine.tick_log import read_log
from missiontree.errors import ConfigError
from missiontree.runlog.replay import Replay, load_tree, log_path

SCHEMA = """
CREATE TABLE IF NOT EXISTS runs (
    run_id INTEGER PRIMARY KEY, name TEXT, run_dir TEXT UNIQUE, mission TEXT, status TEXT,
    stopped_by TEXT, reason TEXT, ticks INTEGER, duration REAL, seed INTEGER, world TEXT,
    params TEXT, summary TEXT);
CREATE TABLE IF NOT EXISTS nodes (
    run_id INTEGER, uid INTEGER, path TEXT, name TEXT, type TEXT, category TEXT, parent_uid INTEGER,
    params TEXT, source TEXT, PRIMARY KEY (run_id, uid));
CREATE TABLE IF NOT EXISTS transitions (
    run_id INTEGER, tick INTEGER, t REAL, node TEXT, uid INTEGER, status TEXT, was TEXT, feedback TEXT,
    reason TEXT, halted INTEGER);
CREATE TABLE IF NOT EXISTS events (
    run_id INTEGER, tick INTEGER, t REAL, kind TEXT, node TEXT, fields TEXT);
CREATE INDEX IF NOT EXISTS transitions_by_node ON transitions (node, status);
CREATE INDEX IF NOT EXISTS events_by_kind ON events (kind);
"""

#: Documented example queries (docs/queryable-log.md shows them with their answers).
EXAMPLES: dict[str, str] = {
    "failures per node": "SELECT node, COUNT(*) AS failures FROM transitions WHERE status = 'FAILURE' "
    "GROUP BY node ORDER BY failures DESC, node LIMIT 10",
    "failures per leaf": "SELECT t.node, COUNT(*) AS failures FROM transitions t JOIN nodes n "
    "ON n.run_id = t.run_id AND n.uid = t.uid WHERE t.status = 'FAILURE' AND n.category = 'leaf' "
    "GROUP BY t.node ORDER BY failures DESC, t.node LIMIT 10",
    "outcomes": "SELECT status, stopped_by, COUNT(*) AS runs FROM runs GROUP BY status, stopped_by",
    "reasons": "SELECT node, reason, COUNT(*) AS n FROM transitions WHERE reason != '' "
    "GROUP BY node, reason ORDER BY n DESC LIMIT 10",
    "errors": "SELECT r.name, e.node, json_extract(e.fields, '$.error') AS error, "
    "json_extract(e.fields, '$.where') AS at FROM events e JOIN runs r USING (run_id) WHERE e.kind = 'error'",
}

_RUNNER_LINES = {"tick", "halted"}


def connect(path: Path) -> sqlite3.Connection:
    """Open (creating) a log database for writing, with its tables."""
    try:
        db = sqlite3.connect(path)
        db.executescript(SCHEMA)
    except sqlite3.Error as error:
        raise ConfigError(f"cannot write the SQLite log {path}: {error}") from error
    return db


def add_run(db: sqlite3.Connection, run: Path, *, name: str | None = None, mission: Path | None = None,
            extra: Mapping[str, Any] | None = None) -> int:
    """Write one run (a run directory or its ticks.jsonl) into ``db``; return its ``run_id``.

    ``extra`` adds the batch's ``world``, ``seed`` and ``params`` when the summary lacks them.

    Raises:
        ConfigError: No tick log, or a line that is not JSON.
    """
    path = log_path(run)
    run_dir = path.parent
    records = read_log(path)
    summary = _summary(run_dir)
    extra = dict(extra or {})
    tree = load_tree(mission, run_dir)
    replay = Replay(tree)
    for record in records:  # paths of nodes the declared tree lacks are learnt from the log
        for change in record.get("changed") or []:
            if isinstance(change, dict) and isinstance(change.get("node"), str):
                replay.node_id(change["node"])
    for node in replay.nodes:  # a run without its recorded tree: a node never seen with children is a leaf
        if not node.category and not node.children:
            node.category = "leaf"
    started: dict[str, Any] = next((r for r in records if r.get("event") == "mission_started"), {})
    finished: dict[str, Any] = next(
        (r for r in reversed(records) if r.get("event") == "mission_finished"), {})
    key = str(run_dir.resolve())
    with db:
        old = db.execute("SELECT run_id FROM runs WHERE run_dir = ?", (key,)).fetchone()
        if old is not None:
            for table in ("runs", "nodes", "transitions", "events"):
                db.execute(f"DELETE FROM {table} WHERE run_id = ?", (old[0],))  # noqa: S608 - fixed names
        cursor = db.execute(
            "INSERT INTO runs (name, run_dir, mission, status, stopped_by, reason, ticks, duration, seed, "
            "world, params, summary) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
            (name or run_dir.name, key, summary.get("mission") or started.get("mission"),
             summary.get("status") or finished.get("status"),
             summary.get("stopped_by") or finished.get("stopped_by"),
             _reason(summary, finished), summary.get("ticks", finished.get("ticks")),
             summary.get("duration", finished.get("duration")), summary.get("seed", extra.get("seed")),
             extra.get("world"), json.dumps(extra.get("params") or {}, sort_keys=True),
             json.dumps(summary, sort_keys=True)))
        run_id = int(cursor.lastrowid or 0)
        db.executemany("INSERT INTO nodes VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)", [
            (run_id, uid, node.path, node.name, node.type, node.category,
             node.parent if node.parent >= 0 else None,
             json.dumps(node.params, sort_keys=True, default=str), node.source)
            for uid, node in enumerate(replay.nodes)])
        db.executemany("INSERT INTO transitions VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                       list(_transitions(run_id, records, replay)))
        db.executemany("INSERT INTO events VALUES (?, ?, ?, ?, ?, ?)", [
            (run_id, record.get("tick"), record.get("t"), record["event"],
             record.get("node") if isinstance(record.get("node"), str) else None,
             json.dumps(record, sort_keys=True))
            for record in records
            if isinstance(record.get("event"), str) and record["event"] not in _RUNNER_LINES])
    return run_id


def _transitions(run_id: int, records: Iterable[dict[str, Any]], replay: Replay) -> Iterable[tuple[Any, ...]]:
    for record in records:
        kind = record.get("event")
        if kind not in _RUNNER_LINES:
            continue
        for change in record.get("changed") or []:
            if not isinstance(change, dict) or not isinstance(change.get("node"), str):
                continue
            yield (run_id, record.get("tick"), record.get("t"), change["node"],
                   replay.index.get(change["node"]), change.get("status"), change.get("was"),
                   change.get("feedback", ""), change.get("reason", ""), int(kind == "halted"))


def _summary(run_dir: Path) -> dict[str, Any]:
    try:
        data = json.loads((run_dir / "summary.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def _reason(summary: Mapping[str, Any], finished: Mapping[str, Any]) -> str:
    fault = summary.get("fault") or finished.get("fault")
    if isinstance(fault, dict):
        return f"fault in {fault.get('node')}: {fault.get('error')}"
    return str(summary.get("reason") or finished.get("reason") or "")


def query(path: Path, sql: str) -> tuple[list[str], list[tuple[Any, ...]]]:
    """Run ``sql`` on a log database opened read-only; return the column names and rows.

    ``path`` may also be a run directory (or its ticks.jsonl): the run is written into a database in
    memory first, so one run is queried without an export.

    Raises:
        ConfigError: The file does not exist, is not a database, or the query fails (or writes).
    """
    if path.is_dir() or path.suffix == ".jsonl":
        db = connect(Path(":memory:"))
        add_run(db, path)
        return _run_query(db, path, sql)
    if not path.is_file():
        raise ConfigError(f"{path}: no such SQLite log; write one with `missiontree log export RUN --format "
                          "sqlite --out FILE` or `missiontree batch ... --log sqlite`")
    try:
        db = sqlite3.connect(f"{path.resolve().as_uri()}?mode=ro", uri=True)
    except sqlite3.Error as error:
        raise ConfigError(f"cannot open {path}: {error}") from error
    return _run_query(db, path, sql)


def _run_query(db: sqlite3.Connection, path: Path, sql: str) -> tuple[list[str], list[tuple[Any, ...]]]:
    """Run ``sql`` with writes refused (``query_only``); close the connection."""
    try:
        db.execute("PRAGMA query_only = ON")
        cursor = db.execute(sql)
        columns = [d[0] for d in cursor.description or []]
        return columns, [tuple(row) for row in cursor.fetchall()]
    except sqlite3.Error as error:
        raise ConfigError(f"query failed on {path}: {error}") from error
    finally:
        db.close()


def format_rows(columns: list[str], rows: list[tuple[Any, ...]]) -> str:
    """Rows as an aligned text table (a header, then one line a row)."""
    cells = [columns] + [["" if v is None else str(v) for v in row] for row in rows]
    widths = [max(len(row[i]) for row in cells) for i in range(len(columns))]
    lines = ["  ".join(cell.ljust(widths[i]) for i, cell in enumerate(row)).rstrip() for row in cells]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)


__all__ = ["EXAMPLES", "SCHEMA", "add_run", "connect", "format_rows", "query"]
