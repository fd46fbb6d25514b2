"""``missiontree log summarize RUN``: what failed and why, read back from a run's tick log.

Works from ``ticks.jsonl`` alone (a run directory or the file itself): it replays the status
changes of every tick, so it can say which nodes were running when the run stopped, which
failure ended it (the deepest node that turned FAILURE on the last tick), every node's failures
with their reasons, and the errors and events leaves emitted.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from missiontree.cli import print_json
from missiontree.engine.tick_log import read_log
from missiontree.errors import ConfigError

#: Runner lines that are not leaf events.
_RUNNER_LINES = {"tick", "halted", "mission_started", "mission_finished"}


def register(subparsers: Any) -> None:
    """Add the ``log`` subcommand group (``log summarize``)."""
    parser = subparsers.add_parser("log", help="read a run's tick log",
                                   description="Read back what a run did from its tick log.")
    actions = parser.add_subparsers(dest="log_command", metavar="ACTION", required=True)
    summarize = actions.add_parser(
        "summarize", help="what failed and why",
        description="Summarise a run from its ticks.jsonl: how it ended, which failure ended it, every "
        "node's failures with reasons, errors and events.",
    )
    summarize.add_argument("run_path", metavar="RUN", type=Path, help="a run directory or its ticks.jsonl")
    summarize.add_argument("--json", action="store_true", help="print the summary as JSON")
    summarize.set_defaults(func=run)


def log_file(run_path: Path) -> Path:
    """The tick log of a run directory (or the path itself when it is a file)."""
    if run_path.is_dir():
        candidate = run_path / "ticks.jsonl"
        if not candidate.is_file():
            raise ConfigError(f"{run_path} has no ticks.jsonl; give a run directory written by "
                              f"`missiontree run` (see its --out) or the log file itself")
        return candidate
    if not run_path.exists():
        raise ConfigError(f"run {str(run_path)!r} does not exist; give a run directory or a ticks.jsonl")
    return run_path


def summarize(lines: list[dict[str, Any]]) -> dict[str, Any]:
    """Summarise a tick log (one dict a line) into how it ended and what failed why."""
    started = next((r for r in lines if r.get("event") == "mission_started"), {})
    finished = next((r for r in reversed(lines) if r.get("event") == "mission_finished"), {})
    ticks = [r for r in lines if r.get("event") == "tick"]
    statuses: dict[str, str] = {}
    failures: dict[str, dict[str, Any]] = {}
    for record in ticks:
        for change in record.get("changed", []):
            node, status = change.get("node", "?"), change.get("status", "?")
            statuses[node] = status
            if status == "FAILURE":
                entry = failures.setdefault(node, {"count": 0, "reasons": {}})
                entry.setdefault("first_tick", record.get("tick"))
                entry["count"] += 1
                reason = change.get("reason", "") or "(no reason given)"
                entry["reasons"][reason] = entry["reasons"].get(reason, 0) + 1
                entry["last_tick"] = record.get("tick")
    last = ticks[-1] if ticks else {}
    ended_by = [c for c in last.get("changed", []) if c.get("status") == "FAILURE"]
    ended_by.sort(key=lambda c: -str(c.get("node", "")).count("/"))
    if any(c.get("reason") for c in ended_by):  # composites failing "because a child did" add nothing
        ended_by = [c for c in ended_by if c.get("reason")]
    events: dict[str, int] = {}
    errors: list[dict[str, Any]] = []
    for record in lines:
        kind = record.get("event", "?")
        if kind in _RUNNER_LINES:
            continue
        events[kind] = events.get(kind, 0) + 1
        if kind == "error":
            errors.append({k: record.get(k) for k in ("tick", "t", "node", "error", "where")})
    return {
        "mission": started.get("mission") or last.get("mission", ""),
        "status": finished.get("status") or last.get("status", "UNKNOWN"),
        "stopped_by": finished.get("stopped_by", "unknown (the log has no mission_finished line)"),
        "ticks": len(ticks),
        "duration": finished.get("duration", (last.get("t", 0.0) - ticks[0].get("t", 0.0)) if ticks else 0.0),
        "ended_by": [{k: c.get(k) for k in ("node", "reason") if c.get(k)} for c in ended_by],
        "running_at_end": sorted(n for n, s in statuses.items() if s == "RUNNING"),
        "failures": dict(sorted(failures.items())),
        "errors": errors,
        "events": dict(sorted(events.items())),
    }


def format_summary(summary: dict[str, Any]) -> str:
    """The text form of :func:`summarize`'s result."""
    out = [f"mission {summary['mission'] or '?'}: {summary['status']} (stopped by {summary['stopped_by']}) "
           f"after {summary['ticks']} ticks, {summary['duration']:.1f} s on the robot clock"]
    if summary["ended_by"]:
        out.append("ended by (deepest first):")
        out += [f"  {e['node']}: {e.get('reason', '(no reason given)')}" for e in summary["ended_by"]]
    if summary["running_at_end"] and summary["status"] not in ("SUCCESS", "FAILURE"):
        out.append("still running when stopped:")
        out += [f"  {node}" for node in summary["running_at_end"]]
    if summary["failures"]:
        out.append("failures (node: times, reasons):")
        for node, entry in summary["failures"].items():
            reasons = ", ".join(f"{r} (x{n})" for r, n in entry["reasons"].items())
            out.append(f"  {node}: {entry['count']} — {reasons}")
    else:
        out.append("no node failed")
    if summary["errors"]:
        out.append("errors:")
        out += [f"  tick {e['tick']} {e['node'] or '(run)'}: {e['error']}"
                + (f" (in {e['where']})" if e.get("where") else "") for e in summary["errors"]]
    if summary["events"]:
        out.append("events: " + ", ".join(f"{k} {v}" for k, v in summary["events"].items()))
    return "\n".join(out)


def run(args: argparse.Namespace) -> int:
    """Print the summary of one run."""
    path = log_file(args.run_path)
    lines = read_log(path)
    if not lines:
        raise ConfigError(f"{path} is empty: the run wrote no tick log lines")
    summary = summarize(lines)
    if args.json:
        print_json(summary)
    else:
        print(format_summary(summary))
    return 0
