"""Test helpers for runs: a synthetic run directory of any length, and a watch on Dask's chunks.

Used by tests and the benchmarks (the viewer's size, the batch engines' scaling), never by the
product. :func:`observe_dask_chunks` records how many runs each Dask task of an engine holds.

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


class _Patrol:
    """The state of a synthetic patrol tick by tick: which nodes run, where the robot is."""

    def __init__(self, tree: dict[str, Any], ticks: int, leaves: int, seed: int) -> None:
        self.rng = random.Random(seed)
        self.ticks = ticks
        self.leaves = leaves
        self.group_paths = [child["path"] for child in tree["children"][1:]]
        self.active: dict[str, str] = {}
        self.leaf_at = [0] * len(self.group_paths)
        self.x, self.y, self.heading = 0.0, 0.0, 0.0
        self.alarm_id = 0

    def change(self, changed: list[dict[str, Any]], path: str, status: str, **extra: Any) -> None:
        """Record ``path`` turning ``status`` (nothing when it already is)."""
        was = self.active.get(path, "INVALID")
        if was == status:
            return
        changed.append({"node": path, "status": status, "was": was, **extra})
        if status == "INVALID":
            self.active.pop(path, None)
        else:
            self.active[path] = status

    def step_groups(
        self, n: int, changed: list[dict[str, Any]], bb: dict[str, Any], events: list[dict[str, Any]]
    ) -> None:
        """Tick ``n`` of every group: start a leaf, fail it every 30 s, finish it every 12 s."""
        for g, group in enumerate(self.group_paths):
            step = f"{group}/step{self.leaf_at[g]}"
            if n == self.ticks:
                self.change(changed, step, "SUCCESS", feedback="done")
                self.change(changed, group, "SUCCESS")
                continue
            if step not in self.active or self.active[step] != "RUNNING":
                self.change(changed, step, "RUNNING", feedback=f"to waypoint {self.leaf_at[g]}")
                self.change(changed, group, "RUNNING")
                events.append(
                    {
                        "event": "goal_sent",
                        "node": step.rsplit("/", 1)[1],
                        "x": round(self.x + self.rng.uniform(-3, 3), 3),
                        "y": round(self.y + self.rng.uniform(-3, 3), 3),
                    }
                )
            elif n % 300 == 0:
                self.change(
                    changed, step, "FAILURE", feedback="goal aborted", reason="no path to the goal: blocked"
                )
                self.change(changed, group, "FAILURE")
                events.append({"event": "goal_aborted", "node": step.rsplit("/", 1)[1], "reason": "blocked"})
                self.leaf_at[g] = 0
            elif n % 120 == 0:
                self.change(changed, step, "SUCCESS", feedback="reached")
                self.leaf_at[g] = (self.leaf_at[g] + 1) % self.leaves
                bb[f"waypoint_{g}"] = {"index": self.leaf_at[g], "x": round(self.x, 3), "y": round(self.y, 3)}

    def surveillance(self, n: int, events: list[dict[str, Any]]) -> None:
        """A model call every other tick, an alarm every minute."""
        if n % 2 == 0:
            events.append(
                {
                    "event": "model_call",
                    "latency": round(self.rng.uniform(0.0, 0.05), 6),
                    "node": "surveillance",
                    "outcome": "succeeded",
                    "provider": "sim_detector",
                    "role": "detector",
                }
            )
        if n % 600 == 300:
            self.alarm_id += 1
            events.append(
                {
                    "event": "alarm",
                    "id": self.alarm_id,
                    "node": "surveillance",
                    "phase": "detected",
                    "position": [round(self.x + 1.5, 4), round(self.y + 0.5, 4)],
                    "robot_pose": [round(self.x, 4), round(self.y, 4), round(self.heading, 4)],
                    "verdict": "ALARM: PERSON DETECTED",
                }
            )

    def move(self) -> None:
        """A random walk of 3 cm a tick inside the map."""
        self.heading += self.rng.uniform(-0.2, 0.2)
        self.x = max(-9.0, min(9.0, self.x + 0.03 * math.cos(self.heading)))
        self.y = max(-9.0, min(9.0, self.y + 0.03 * math.sin(self.heading)))

    def tick_lines(self, n: int, t: float, poses: list[list[float]], tick_hz: float) -> list[str]:
        """The lines of tick ``n`` at time ``t`` (its events, then the tick); a pose each 1/4 s."""
        changed: list[dict[str, Any]] = []
        bb: dict[str, Any] = {}
        events: list[dict[str, Any]] = []
        if n == 1:
            for path in ("root/servo_then_resume/servo", "root/servo_then_resume"):
                self.change(changed, path, "FAILURE", feedback="no new alarm", reason="no new alarm")
        self.step_groups(n, changed, bb, events)
        if n == 1 or (n == self.ticks):
            self.change(changed, "root", "SUCCESS" if n == self.ticks else "RUNNING")
        self.surveillance(n, events)
        self.move()
        if n % max(1, round(tick_hz / 4)) == 0:
            poses.append([round(t, 3), round(self.x, 3), round(self.y, 3)])
        lines = [_line({**event, "mission": "synthetic", "t": t, "tick": n}) for event in events]
        record: dict[str, Any] = {
            "event": "tick",
            "mission": "synthetic",
            "t": t,
            "tick": n,
            "status": self.active.get("root", "RUNNING"),
        }
        if changed:
            record["changed"] = changed
        if bb:
            record["bb"] = bb
        lines.append(_line(record))
        return lines


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
    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    tree = synthetic_tree(leaves, groups)
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
    patrol = _Patrol(tree, ticks, leaves, seed)
    poses: list[list[float]] = []
    for n in range(1, ticks + 1):
        lines += patrol.tick_lines(n, round((n - 1) * period, 6), poses, tick_hz)
    lines += _closing_lines(patrol.active, ticks, period)
    log = run_dir / "ticks.jsonl"
    log.write_text("\n".join(lines) + "\n", encoding="utf-8")
    _write_view_and_summary(run_dir, tree, poses, ticks, tick_hz)
    return log


def _write_view_and_summary(
    run_dir: Path, tree: dict[str, Any], poses: list[list[float]], ticks: int, tick_hz: float
) -> None:
    """runview.json with the tree, a walled 20 m map and the trajectory; summary.json."""
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


def _closing_lines(active: dict[str, str], ticks: int, period: float) -> list[str]:
    """The run's last lines: the nodes halted, then the mission finished with SUCCESS."""
    lines: list[str] = []
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
    return lines


def observe_dask_chunks(engine: Any) -> list[int]:
    """The runs in each Dask task ``engine`` submits from now on (its client's ``map`` observed).

    Args:
        engine: A :class:`~missiontree.evaluation.dask_engine.DaskEngine`.

    Returns:
        A list that grows by one size a task as the engine submits them (clear it between rounds).
    """
    sizes: list[int] = []
    submit = engine.client.map

    def observed(func: Any, *iterables: Any, **kwargs: Any) -> Any:
        sizes.extend(len(chunk) for chunk in iterables[1])  # (the run function, the chunks)
        return submit(func, *iterables, **kwargs)

    engine.client.map = observed
    return sizes
