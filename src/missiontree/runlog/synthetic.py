"""A synthetic run directory of any length, for tests and the viewer's size benchmark.

:func:`synthesize_run` writes what a patrol-like run writes — ``ticks.jsonl`` in the runner's
format (sorted keys, compact separators), ``runview.json`` with a declared tree, a map and a
trajectory, and ``summary.json`` — with event rates taken from a real patrol run (about 0.6
events a tick, mostly model calls; a waypoint every 12 s; an alarm every minute; a leaf failure
every 30 s). Deterministic for a seed.
"""

from __future__ import annotations

import json
import math
import random
from pathlib import Path
from typing import Any

import numpy as np

from missiontree.runlog.record import encode_map, write_runview


def _line(record: dict[str, Any]) -> str:
    return json.dumps(record, sort_keys=True, separators=(",", ":"), ensure_ascii=False)


def synthetic_tree(leaves: int = 4, groups: int = 1) -> dict[str, Any]:
    """A declared tree: a Selector over ``groups`` Sequences of ``leaves`` leaves (plus a servo branch)."""
    root: dict[str, Any] = {
        "path": "root",
        "name": "root",
        "type": "Selector",
        "category": "composite",
        "params": {"memory": False},
        "source": "synthetic.yaml:1:1",
        "children": [],
    }
    servo = {
        "path": "root/servo_then_resume",
        "name": "servo_then_resume",
        "type": "ForceFailure",
        "category": "decorator",
        "params": {},
        "source": "synthetic.yaml:4:7",
        "children": [
            {
                "path": "root/servo_then_resume/servo",
                "name": "servo",
                "type": "ServoToTarget",
                "category": "leaf",
                "params": {"timeout": 15.0},
                "source": "synthetic.yaml:6:11",
                "children": [],
            }
        ],
    }
    root["children"].append(servo)
    for g in range(groups):
        name = f"group{g}"
        group: dict[str, Any] = {
            "path": f"root/{name}",
            "name": name,
            "type": "Sequence",
            "category": "composite",
            "params": {"memory": True},
            "source": f"synthetic.yaml:{10 + g}:7",
            "children": [],
        }
        for k in range(leaves):
            leaf = f"step{k}"
            group["children"].append(
                {
                    "path": f"root/{name}/{leaf}",
                    "name": leaf,
                    "type": "GoTo",
                    "category": "leaf",
                    "params": {"x": float(k), "y": float(g)},
                    "source": f"synthetic.yaml:{20 + k}:11",
                    "children": [],
                }
            )
        root["children"].append(group)
    return root


def _paths(tree: dict[str, Any]) -> list[str]:
    out = [tree["path"]]
    for child in tree["children"]:
        out += _paths(child)
    return out


def synthesize_run(
    run_dir: Path,
    ticks: int = 36_000,
    *,
    leaves: int = 4,
    groups: int = 1,
    seed: int = 0,
    tick_hz: float = 10.0,
) -> Path:
    """Write a synthetic run of ``ticks`` ticks into ``run_dir``; return the tick log's path.

    The leaves of each group run in turn (one at a time, ``step0`` … then again), so status
    changes come in bursts as in a real patrol; every ``30 s`` the running leaf fails with a
    reason and the group restarts; the root never ends until the last tick, which succeeds.
    """
    rng = random.Random(seed)
    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    tree = synthetic_tree(leaves, groups)
    group_paths = [child["path"] for child in tree["children"][1:]]
    period = 1.0 / tick_hz
    lines: list[str] = [
        _line(
            {
                "event": "mission_started",
                "max_duration": ticks * period,
                "mission": "synthetic",
                "nodes": len(_paths(tree)),
                "robot": "sim",
                "seed": seed,
                "t": 0.0,
                "tick": 0,
                "tick_hz": tick_hz,
            }
        )
    ]
    active: dict[str, str] = {}
    leaf_at = [0] * groups
    poses: list[list[float]] = []
    x, y, heading = 0.0, 0.0, 0.0
    alarm_id = 0
    for n in range(1, ticks + 1):
        t = round((n - 1) * period, 6)
        changed: list[dict[str, Any]] = []
        bb: dict[str, Any] = {}
        events: list[dict[str, Any]] = []

        def change(path: str, status: str, changed: list[dict[str, Any]] = changed, **extra: Any) -> None:
            was = active.get(path, "INVALID")
            if was == status:
                return
            entry = {"node": path, "status": status, "was": was, **extra}
            changed.append(entry)
            if status == "INVALID":
                active.pop(path, None)
            else:
                active[path] = status

        if n == 1:
            change("root/servo_then_resume/servo", "FAILURE", feedback="no new alarm", reason="no new alarm")
            change("root/servo_then_resume", "FAILURE", feedback="no new alarm", reason="no new alarm")
        for g, group in enumerate(group_paths):
            step = f"{group}/step{leaf_at[g]}"
            if n == ticks:
                change(step, "SUCCESS", feedback="done")
                change(group, "SUCCESS")
                continue
            if step not in active or active[step] != "RUNNING":
                change(step, "RUNNING", feedback=f"to waypoint {leaf_at[g]}")
                change(group, "RUNNING")
                events.append(
                    {
                        "event": "goal_sent",
                        "node": step.rsplit("/", 1)[1],
                        "x": round(x + rng.uniform(-3, 3), 3),
                        "y": round(y + rng.uniform(-3, 3), 3),
                    }
                )
            elif n % 300 == 0:
                change(step, "FAILURE", feedback="goal aborted", reason="no path to the goal: blocked")
                change(group, "FAILURE")
                events.append({"event": "goal_aborted", "node": step.rsplit("/", 1)[1], "reason": "blocked"})
                leaf_at[g] = 0
            elif n % 120 == 0:
                change(step, "SUCCESS", feedback="reached")
                leaf_at[g] = (leaf_at[g] + 1) % leaves
                bb[f"waypoint_{g}"] = {"index": leaf_at[g], "x": round(x, 3), "y": round(y, 3)}
        if n == 1 or (n == ticks):
            change("root", "SUCCESS" if n == ticks else "RUNNING")
        if n % 2 == 0:
            events.append(
                {
                    "event": "model_call",
                    "latency": round(rng.uniform(0.0, 0.05), 6),
                    "node": "surveillance",
                    "outcome": "succeeded",
                    "provider": "sim_detector",
                    "role": "detector",
                }
            )
        if n % 600 == 300:
            alarm_id += 1
            events.append(
                {
                    "event": "alarm",
                    "id": alarm_id,
                    "node": "surveillance",
                    "phase": "detected",
                    "position": [round(x + 1.5, 4), round(y + 0.5, 4)],
                    "robot_pose": [round(x, 4), round(y, 4), round(heading, 4)],
                    "verdict": "ALARM: PERSON DETECTED",
                }
            )
        heading += rng.uniform(-0.2, 0.2)
        x = max(-9.0, min(9.0, x + 0.03 * math.cos(heading)))
        y = max(-9.0, min(9.0, y + 0.03 * math.sin(heading)))
        if n % max(1, round(tick_hz / 4)) == 0:
            poses.append([round(t, 3), round(x, 3), round(y, 3)])
        for event in events:
            lines.append(_line({**event, "mission": "synthetic", "t": t, "tick": n}))
        record: dict[str, Any] = {
            "event": "tick",
            "mission": "synthetic",
            "status": active.get("root", "RUNNING"),
            "t": t,
            "tick": n,
        }
        if changed:
            record["changed"] = changed
        if bb:
            record["bb"] = bb
        lines.append(_line(record))
    halted = [{"node": p, "status": "INVALID", "was": s} for p, s in sorted(active.items())]
    end = round((ticks - 1) * period, 6)
    lines.append(
        _line({"changed": halted, "event": "halted", "mission": "synthetic", "t": end, "tick": ticks})
    )
    lines.append(
        _line(
            {
                "duration": end,
                "event": "mission_finished",
                "mission": "synthetic",
                "status": "SUCCESS",
                "stopped_by": "status",
                "t": end,
                "tick": ticks,
                "ticks": ticks,
            }
        )
    )
    log = run_dir / "ticks.jsonl"
    log.write_text("\n".join(lines) + "\n", encoding="utf-8")
    grid = np.zeros((400, 400), dtype=np.int8)
    grid[0, :] = grid[-1, :] = grid[:, 0] = grid[:, -1] = 100
    grid[150:250, 200] = 100
    write_runview(
        run_dir,
        {
            "version": 1,
            "tree": tree,
            "mission_file": "synthetic.yaml",
            "map": encode_map(grid, 0.05, (-10.0, -10.0), "synthetic map"),
            "poses": poses,
        },
    )
    (run_dir / "summary.json").write_text(
        json.dumps(
            {"mission": "synthetic", "status": "SUCCESS", "ticks": ticks, "tick_hz": tick_hz}, indent=2
        )
        + "\n",
        encoding="utf-8",
    )
    return log
