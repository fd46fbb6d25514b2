"""``missiontree log summarize RUN``: what failed and why, read back from a run's tick log.

(``missiontree log profile RUN`` prints where the run's time went: :mod:`missiontree.cli.log_profile`.)

Works from ``ticks.jsonl`` alone (a run directory or the file itself): it replays the status
changes of every tick, so it can say which nodes were running when the run stopped, which
failure ended it (the deepest node that turned FAILURE on the last tick), every node's failures
with their reasons, and the errors and events leaves emitted. A composite that failed because a
child did has no reason of its own in the log; the summary names the child that ended it and the
reason that failure ends in (``child 'fetch' failed: goal aborted (from 'fetch/to_fridge')``),
found among the same tick's changes.

Counts are status *transitions*, as in the run's ``summary.json``: a node failing on many ticks in
a row turned FAILURE once. Each failure is either one that *decided the outcome* (FAILURE reached
the root) or one an ancestor *absorbed* by design (a Selector moving on, a Retry, a ForceFailure's
Selector parent), by the same rule as the summary (:func:`~missiontree.engine.node_words.absorber`),
so ``failures`` here and in ``summary.json`` agree on ``count``, ``decided`` and ``absorbed_by``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from missiontree.cli import print_json
from missiontree.engine.node_words import absorber
from missiontree.engine.recorder import read_summary
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
    from missiontree.cli import log_profile  # `log profile`: summary.json's profile as a table

    log_profile.add_to(actions)
    from missiontree.cli import export  # `log export`: Groot2 .btlog, MCAP and SQLite

    export.add_to(actions)
    add_query(actions)


def add_query(actions: Any) -> None:
    """Add ``log query DB SQL``: a read-only SQL query on a SQLite log."""
    from missiontree.runlog.sqlite_log import EXAMPLES

    examples = "\n".join(f"  {name}:\n    {sql}" for name, sql in EXAMPLES.items())
    query = actions.add_parser(
        "query", help="run a read-only SQL query on a SQLite log",
        description="Query a SQLite log written by `log export --format sqlite` or `batch --log sqlite` "
        "(tables runs, nodes, transitions, events; see docs/queryable-log.md). The database is opened "
        "read-only. SQL may also be the name of an example below.",
        epilog=f"Examples:\n{examples}", formatter_class=argparse.RawDescriptionHelpFormatter)
    query.add_argument("db", type=Path, help="the SQLite log, or a run directory (queried in memory)")
    query.add_argument("sql", help="the SQL query, or an example's name ('failures per node')")
    query.add_argument("--json", action="store_true", help="print the rows as JSON objects, one a line")
    query.set_defaults(func=run_query)


def run_query(args: argparse.Namespace) -> int:
    """Print the query's rows (a table, or JSON lines)."""
    from missiontree.redact import terminal_safe
    from missiontree.runlog.sqlite_log import EXAMPLES, format_rows, query

    columns, rows = query(args.db, EXAMPLES.get(args.sql, args.sql))
    if args.json:
        for row in rows:
            print(json.dumps(dict(zip(columns, row, strict=True)), sort_keys=True))
    else:
        print(terminal_safe(format_rows(columns, rows)))
    return 0


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


def _depth(path: str) -> int:
    return path.count("/")


def explain_failures(changed: list[dict[str, Any]],
                     latest: dict[str, dict[str, Any]]) -> dict[str, dict[str, str]]:
    """Why each node that turned FAILURE in one tick failed: its own reason, or the child's that ended it.

    A composite fails because a child failed; py_trees gives it no reason of its own. Its reason is
    derived from the same tick's changes, deepest first: the shallowest descendant that turned
    FAILURE in this tick (the last ticked, when several did) is the child that ended it, and that
    child's reason — its own, or derived in turn — is the composite's. When no descendant changed
    in this tick (it had already failed before), the last known status of each node (``latest``)
    is used instead. A decorator that has words of its own ("final failure [... 2 from 2]") keeps
    them and gains its child's reason after them, unless it only repeats them.

    Args:
        changed: The ``changed`` entries of one tick line, in the order the log holds them.
        latest: Every node's last ``changed`` entry from earlier ticks, with ``reason`` and
            ``origin`` filled in for failures.

    Returns:
        node path -> {"reason": the text to show, "origin": path of the node whose own reason it
        ends in (or ""), "own": that node's own reason, "child": path of the child that ended it (or
        "")} for every entry that turned FAILURE.
    """
    failed = [c for c in changed if c.get("status") == "FAILURE" and "node" in c]
    explained: dict[str, dict[str, str]] = {}
    for change in sorted(failed, key=lambda c: -_depth(c["node"])):  # stable: visit order kept
        node, own = change["node"], change.get("reason", "")
        prefix = node + "/"
        below = [c["node"] for c in failed if c["node"].startswith(prefix)]
        if not below and not own:  # failed in an earlier tick and has not changed since
            below = sorted(p for p, c in latest.items()
                           if p.startswith(prefix) and c.get("status") == "FAILURE")
        if not below:
            explained[node] = {"reason": own, "origin": node if own else "", "own": own, "child": ""}
            continue
        top = min(_depth(p) for p in below)
        children = [p for p in below if _depth(p) == top]
        child = children[-1]
        cause = explained.get(child) or {"origin": latest[child].get("origin", ""),
                                         "own": latest[child].get("own", "")}
        if own and (not cause["own"] or cause["own"] in own):  # a decorator repeating its child's words
            origin = cause["origin"] if cause["own"] else node
            explained[node] = {"reason": own, "origin": origin, "own": cause["own"] or own, "child": child}
            continue
        text = f"child {child[len(prefix):]!r} failed"
        others = [p[len(prefix):] for p in children[:-1]]
        if others:
            text += " (as did " + ", ".join(repr(o) for o in others) + ")"
        text += ": " + (cause["own"] or "(no reason given)")
        origin = cause["origin"]
        if origin and origin != child:
            text += f" (from {origin[len(prefix):]!r})"
        if own:  # a decorator's own words (a retry's count, a timeout) come first
            text = f"{own}; {text}"
        explained[node] = {"reason": text, "origin": origin, "own": cause["own"], "child": child}
    return explained


def summarize(lines: list[dict[str, Any]]) -> dict[str, Any]:
    """Summarise a tick log (one dict a line) into how it ended and what failed why.

    Failure reasons are the nodes' own; a composite that failed because a child did is given
    "child 'name' failed: <its reason>" (see :func:`explain_failures`).
    """
    started = next((r for r in lines if r.get("event") == "mission_started"), {})
    finished: dict[str, Any] = next((r for r in reversed(lines) if r.get("event") == "mission_finished"), {})
    ticks = [r for r in lines if r.get("event") == "tick"]
    latest, failures, explained = _tally_failures(ticks)
    last = ticks[-1] if ticks else {}
    ended_by = [c["node"] for c in last.get("changed", []) if c.get("status") == "FAILURE" and "node" in c]
    ended_by.sort(key=lambda n: -_depth(n))
    own = [n for n in ended_by if explained[n]["origin"] == n]
    # Composites failing "because a child did" add nothing to the leaf's reason; when no node of this
    # tick has words of its own (the leaf failed earlier), the deepest composite carries them.
    ended_by = own or ended_by[:1]
    return {
        "mission": started.get("mission") or last.get("mission", ""),
        "status": finished.get("status") or last.get("status", "UNKNOWN"),
        "stopped_by": finished.get("stopped_by", "unknown (the log has no mission_finished line)"),
        "ticks": len(ticks),
        "duration": finished.get("duration", (last.get("t", 0.0) - ticks[0].get("t", 0.0)) if ticks else 0.0),
        "ended_by": [{"node": n, "reason": explained[n]["reason"]} if explained[n]["reason"] else {"node": n}
                     for n in ended_by],
        "running_at_end": sorted(n for n, c in latest.items() if c.get("status") == "RUNNING"),
        "failures": dict(sorted(failures.items())),
        **_tally_events(lines),
        **({"fault": finished["fault"]} if isinstance(finished.get("fault"), dict) else {}),
        **_tally_robots(lines, latest),
    }


def _tally_robots(lines: list[dict[str, Any]], latest: _Nodes) -> dict[str, Any]:
    """A fleet run's robots (events carrying ``robot``): each one's end, loss and events; {} otherwise.

    A robot's end is the last status of its scope node (``fleet/<robot>``) in the tick lines.
    """
    robots: dict[str, dict[str, Any]] = {}
    for record in lines:
        name = record.get("robot")
        kind = record.get("event", "?")
        if not isinstance(name, str) or kind in _RUNNER_LINES:
            continue
        entry = robots.setdefault(name, {"events": {}})
        entry["events"][kind] = entry["events"].get(kind, 0) + 1
        if kind == "robot_lost":
            entry["lost"] = {"t": record.get("t"), "reason": record.get("reason")}
    if not robots:
        return {}
    for name, entry in robots.items():
        scope = latest.get(f"fleet/{name}", {})
        entry["status"] = scope.get("status", "RUNNING")
        if scope.get("reason"):
            entry["reason"] = scope["reason"]
        entry["events"] = dict(sorted(entry["events"].items()))
    rebalanced = [{"t": r.get("t"), "lost": r.get("lost"), "assignment": r.get("assignment")}
                  for r in lines if r.get("event") == "fleet_rebalanced"]
    return {"robots": dict(sorted(robots.items())), "rebalanced": rebalanced}


_Nodes = dict[str, dict[str, Any]]


def _tally_failures(ticks: list[dict[str, Any]]) -> tuple[_Nodes, _Nodes, dict[str, dict[str, str]]]:
    """Each node's latest change, its failures, and the explanations of the last tick's failures.

    A failure is counted with its reasons and classified as deciding or absorbed (by which node).
    """
    latest: dict[str, dict[str, Any]] = {}
    failures: dict[str, dict[str, Any]] = {}
    explained: dict[str, dict[str, str]] = {}
    for record in ticks:
        changed = record.get("changed", [])
        explained = explain_failures(changed, latest)
        failed_now: list[str] = []
        for change in changed:
            node = change.get("node", "?")
            entry = latest[node] = dict(change)
            if change.get("status") != "FAILURE":
                continue
            failed_now.append(node)
            why = explained.get(node, {"reason": "", "origin": "", "own": ""})
            entry.update(reason=why["reason"], origin=why["origin"], own=why["own"])
            failure = failures.setdefault(node, {"count": 0, "decided": 0, "absorbed_by": {}, "reasons": {}})
            failure.setdefault("first_tick", record.get("tick"))
            failure["count"] += 1
            reason = why["reason"] or "(no reason given)"
            failure["reasons"][reason] = failure["reasons"].get(reason, 0) + 1
            failure["last_tick"] = record.get("tick")
        for node in failed_now:  # classified on the statuses at the end of the tick
            by = absorber(node, lambda path: latest.get(path, {}).get("status"))
            if by is None:
                failures[node]["decided"] += 1
            else:
                failures[node]["absorbed_by"][by] = failures[node]["absorbed_by"].get(by, 0) + 1
    return latest, failures, explained


def _tally_events(lines: list[dict[str, Any]]) -> dict[str, Any]:
    """The events counted by kind, with the errors, substitutions and reloads listed."""
    events: dict[str, int] = {}
    errors: list[dict[str, Any]] = []
    stubs: list[dict[str, Any]] = []
    reloads: list[dict[str, Any]] = []
    for record in lines:
        kind = record.get("event", "?")
        if kind in _RUNNER_LINES:
            continue
        events[kind] = events.get(kind, 0) + 1
        if kind == "error":
            errors.append({k: record.get(k) for k in ("tick", "t", "node", "error", "where")})
        elif kind == "substituted":
            stubs.append({k: record.get(k) for k in ("node", "type", "status", "after", "where")})
        elif kind in ("reloaded", "reload_refused"):
            reloads.append({"t": record.get("t"), "reloaded": kind == "reloaded",
                            "files": record.get("files"), "problems": record.get("count", 0)})
    return {"errors": errors, "substituted": stubs, "reloads": reloads,
            "events": dict(sorted(events.items()))}


def format_summary(summary: dict[str, Any]) -> str:
    """The text form of :func:`summarize`'s result."""
    out = [f"mission {summary['mission'] or '?'}: {summary['status']} (stopped by {summary['stopped_by']}) "
           f"after {summary['ticks']} ticks, {summary['duration']:.1f} s on the robot clock"]
    if summary.get("outcome"):  # the mission's own words lead
        out.append(f"outcome: {summary['outcome']}")
    fault = summary.get("fault")
    if fault:  # failed because of an error, not because a condition was false
        out.append(f"fault: {fault.get('node')}: {fault.get('error')} (an error, not a condition's failure)")
    if summary["ended_by"]:
        out.append("ended by (deepest first):")
        out += [f"  {e['node']}: {e.get('reason', '(no reason given)')}" for e in summary["ended_by"]]
    if summary["running_at_end"] and summary["status"] not in ("SUCCESS", "FAILURE"):
        out.append("still running when stopped:")
        out += [f"  {node}" for node in summary["running_at_end"]]
    decided = {n: e for n, e in summary["failures"].items() if e.get("decided")}
    absorbed = {n: e for n, e in summary["failures"].items() if e.get("absorbed_by")}
    if decided:
        out.append("failures that decided the outcome (node: times — reasons):")
        for node, entry in decided.items():
            reasons = ", ".join(f"{r} (x{n})" for r, n in entry["reasons"].items())
            out.append(f"  {node}: {entry['decided']} — {reasons}")
    if absorbed:
        out.append("failures absorbed by design (a parent moved on or retried; node: times, by whom "
                   "— reasons):")
        for node, entry in absorbed.items():
            by = ", ".join(f"{path} x{n}" for path, n in entry["absorbed_by"].items())
            reasons = ", ".join(f"{r} (x{n})" for r, n in entry["reasons"].items())
            out.append(f"  {node}: {sum(entry['absorbed_by'].values())}, absorbed by {by} — {reasons}")
    if not summary["failures"]:
        out.append("no node failed")
    if summary.get("substituted"):  # the run did not run these nodes: its outcome is a test's
        out.append("substituted (stubs ran, not these nodes):")
        out += [f"  {s['node']} ({s['type']}): {s['status']} after {s['after']} s, rule at {s['where']}"
                for s in summary["substituted"]]
    for reload in summary.get("reloads") or []:
        files = ", ".join(reload.get("files") or [])
        out.append(f"reloaded {files} at {reload['t']:.2f} s" if reload["reloaded"] else
                   f"not reloaded {files} at {reload['t']:.2f} s ({reload['problems']} problem(s))")
    if summary["errors"]:
        out.append("errors:")
        out += [f"  tick {e['tick']} {e['node'] or '(run)'}: {e['error']}"
                + (f" (in {e['where']})" if e.get("where") and str(e["where"]) not in str(e["error"]) else "")
                for e in summary["errors"]]
    if summary["events"]:
        out.append("events: " + ", ".join(f"{k} {v}" for k, v in summary["events"].items()))
    out += _format_robots(summary)
    return "\n".join(out)


def _format_robots(summary: dict[str, Any]) -> list[str]:
    """A fleet run's lines: each robot's end (and loss) and events, the re-balancings."""
    robots = summary.get("robots") or {}
    if not robots:
        return []
    out = [f"robots ({len(robots)}):"]
    for name, entry in robots.items():
        lost = entry.get("lost")
        end = f"{entry['status']}" + (f" — lost at {lost['t']:.1f} s: {lost['reason']}" if lost else "")
        out.append(f"  {name}: {end}")
        out.append("    events: " + ", ".join(f"{k} {v}" for k, v in entry["events"].items()))
    for r in summary.get("rebalanced") or []:
        shares = "; ".join(f"{n}: {', '.join(ws)}" for n, ws in (r.get("assignment") or {}).items())
        out.append(f"  re-balanced at {r['t']:.1f} s after losing {r['lost']}: {shares}")
    return out


def run(args: argparse.Namespace) -> int:
    """Print the summary of one run."""
    path = log_file(args.run_path)
    lines = read_log(path)
    if not lines:
        raise ConfigError(f"{path} is empty: the run wrote no tick log lines")
    summary = summarize(lines)
    said = _outcome_said(path.parent / "summary.json")
    if said:
        summary["outcome"] = said
    if args.json:
        print_json(summary)
    else:
        print(format_summary(summary))
    return 0


def _outcome_said(path: Path) -> str:
    """What the mission said it did (summary.json's outcome text, as on the run's result line)."""
    from missiontree.cli.run import outcome_text

    if not path.is_file():
        return ""
    try:
        found = read_summary(path)
    except ConfigError:  # unreadable, or not one this version wrote: the log still speaks
        return ""
    return outcome_text(found)
