"""What the Explore leaf writes when it ends: ``exploration.json``'s content and its one-line outcome.

Kept apart from the leaf (:mod:`missiontree.behaviours.explore`) as the part that only reads: the
planner's blacklist, the frontiers left and the map.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

import numpy as np

from missiontree.mapping.exploration import Candidate, ExplorationPlanner, LeftOpen
from missiontree.mapping.grid import unknown_mask
from missiontree.mapping.mapfile import write_map
from missiontree.types import OccupancyGrid


def exploration_report(planner: ExplorationPlanner | None, outcome: str, goals: int, grid: OccupancyGrid,
                       left_open: list[LeftOpen] | None, robot_xy: tuple[float, float] | None,
                       time_budget: float | None = None) -> dict[str, Any]:
    """How the exploration ended, what is left (positions, why, unknown area) and what was given up.

    ``left_open``: the frontiers a partial end left; ``robot_xy``: where the robot stands, to list
    what it would have gone to next when it was stopped or failed, or its time budget (s;
    ``time_budget``, then ``time_budget_s`` in the report) was spent (None: not listed).
    """
    left: list[dict[str, Any]] = []
    unknown_left = 0.0
    if planner is not None:
        if outcome == "partial" and left_open:
            left = [{"x": round(o.candidate.target[0], 3), "y": round(o.candidate.target[1], 3),
                     "reason": o.entry.reason} for o in left_open]
            unknown_left = planner.unknown_behind(grid, [o.candidate.target for o in left_open])
        elif outcome in ("stopped", "failed", "partial") and robot_xy is not None:
            offered = not_explored_yet(planner, grid, robot_xy)
            left = [{"x": round(c.target[0], 3), "y": round(c.target[1], 3),
                     "reason": "not explored yet"} for c in offered]
            unknown_left = planner.unknown_behind(grid, [c.target for c in offered])
    slivers = [] if planner is None else planner.slivers
    budget = {} if time_budget is None else {"time_budget_s": time_budget}
    return {**budget,
        "outcome": outcome, "complete": outcome == "explored",
        "known_m2": round(known_area(grid), 3),
        "goals": goals, "frontiers_left": left, "unknown_left_m2": round(unknown_left, 2),
        "slivers_left": [{"x": round(s.candidate.target[0], 3), "y": round(s.candidate.target[1], 3),
                          "unknown_m2": round(s.unknown_m2, 2), "gain_m2": round(s.candidate.gain_m2, 2),
                          "path_m": round(s.candidate.path_m, 1)} for s in slivers],
        "slivers_m2": round(0.0 if planner is None else planner.sliver_area(), 2),
        "given_up": [] if planner is None else [
            {"x": round(b.x, 3), "y": round(b.y, 3), "reason": b.reason, "proved_closed": b.proved_closed}
            for b in planner.blacklist],
    }


def not_explored_yet(planner: ExplorationPlanner, grid: OccupancyGrid,
                     robot_xy: tuple[float, float]) -> list[Candidate]:
    """The frontiers (or scan points) the planner offers now (a search's places to look from are not)."""
    return [c for c in planner.candidates(grid, robot_xy) if c.kind in ("frontier", "scan_point")]


def save_leaf(leaf: Any) -> None:
    """Write what an ending Explore ``leaf`` leaves (:func:`save_exploration`), from its last map.

    exploration.json lists what the robot would have gone to next when the leaf was stopped, failed
    or ran out of time (its ``left`` is None then, and its ``time_budget_spent`` says the last).
    """
    grid = leaf.last_grid
    if grid is None and leaf.ctx is not None:
        grid = leaf.ctx.robot.occupancy()
    if grid is None:
        return
    robot_xy = None
    if leaf.outcome != "explored" and leaf.left is None and leaf.ctx is not None:
        stamped = leaf.ctx.robot.pose()
        robot_xy = None if stamped is None else (stamped.pose.x, stamped.pose.y)
    budget = leaf.params.time_budget if leaf.time_budget_spent else None
    save_exploration(leaf, grid, exploration_report(leaf.planner, leaf.outcome, leaf.goals, grid, leaf.left,
                                                    robot_xy, budget))


def save_exploration(leaf: Any, grid: OccupancyGrid, report: dict[str, Any]) -> None:
    """Write what an ending Explore ``leaf`` leaves: its outputs, the map files, exploration.json.

    The outputs (``explored_area``, ``explore_complete``, ``unexplored``, ``map_yaml``), the run's
    ``exploration`` report, ``map.pgm`` + ``map.yaml`` and ``exploration.json`` in the run directory.
    The map files are written only when the map changed since this leaf last wrote them (or they
    are gone): a search ends its exploration leaf once per round, and on the Malaga campus rewrote
    the same 5 MB map about 200 times.
    """
    leaf.write("explored_area", round(known_area(grid), 3))
    leaf.write("explore_complete", report["complete"])
    leaf.write("unexplored", report["frontiers_left"])
    ctx = leaf.ctx
    if ctx is not None and report["outcome"] in ("explored", "partial"):
        ctx.report("exploration", {**{k: report[k] for k in (
            "outcome", "complete", "known_m2", "unknown_left_m2", "slivers_m2")},
            "slivers_left": len(report["slivers_left"]),
            "frontiers_left": report["frontiers_left"][:20], "text": said(report)})
    run_dir = ctx.run_dir if ctx is not None else None
    if run_dir is None:
        return
    name = leaf.params.map_name
    yaml_path = run_dir / f"{name}.yaml"
    key = _map_key(grid, run_dir, name)
    if key != getattr(leaf, "map_written", None) or not (yaml_path.is_file()
                                                         and (run_dir / f"{name}.pgm").is_file()):
        _, yaml_path = write_map(grid, run_dir, name)
        leaf.map_written = key
        leaf.emit("map_saved", path=str(yaml_path), known_m2=round(known_area(grid), 3))
    leaf.write("map_yaml", str(yaml_path))
    stem = "" if name == "map" else f"{name}_"
    (run_dir / f"{stem}exploration.json").write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")


def _map_key(grid: OccupancyGrid, run_dir: Path, name: str) -> tuple[Any, ...]:
    """What the written map files depend on: where, the geometry and a digest of the cells.

    A digest, not the map's stamp: a map's stamp moves on with the clock while its cells stay the
    same, and an array changed in place keeps its identity.
    """
    digest = hashlib.blake2b(np.ascontiguousarray(grid.data).data, digest_size=16).hexdigest()
    return (str(run_dir), name, grid.data.shape, grid.resolution, grid.origin.x, grid.origin.y,
            grid.origin.yaw, digest)


def said(report: dict[str, Any]) -> str:
    """How the exploration ended, in a line for the run's result (summary.json's outcome text)."""
    if report["outcome"] == "explored":
        n = len(report["slivers_left"])
        small = (f"; {n} small unknown sliver{'s' if n != 1 else ''} left as not worth a trip, "
                 f"{report['slivers_m2']:.1f} m^2") if n else ""
        return (f"explored: no reachable frontier worth a trip left ({report['known_m2']:.0f} m^2 "
                f"known{small})")
    left = report["frontiers_left"]
    if report.get("time_budget_s") is not None:
        return (f"exploration partial: the time budget of {report['time_budget_s']:g} s was spent with "
                f"{len(left)} frontier(s) not explored yet, about {report['unknown_left_m2']:.0f} m^2 "
                f"unknown behind them ({report['known_m2']:.0f} m^2 known; exploration.json lists them)")
    return (f"exploration partial: {len(left)} frontier(s) left though the map shows a way, about "
            f"{report['unknown_left_m2']:.0f} m^2 unknown behind them ({report['known_m2']:.0f} m^2 known; "
            "exploration.json lists them)")


def known_area(grid: OccupancyGrid) -> float:
    """Area of the map's known cells, free or occupied (m^2)."""
    return float(np.count_nonzero(~unknown_mask(grid))) * grid.resolution ** 2


def slivers_text(planner: ExplorationPlanner | None) -> str:
    """', 3 small unknown slivers left (1.2 m^2)' for the slivers the planner's last ranking left; or ''.

    The frontiers not worth a trip (:meth:`ExplorationPlanner._worth_trip`) are said, not dropped
    silently: "explored" then names how much small unknown it left.
    """
    if planner is None or not planner.slivers:
        return ""
    n = len(planner.slivers)
    return f", {n} small unknown sliver{'s' if n != 1 else ''} left ({planner.sliver_area():.1f} m^2)"


def partial_text(planner: ExplorationPlanner, grid: OccupancyGrid, left: list[LeftOpen], summary: str) -> str:
    """'partial: N frontiers left ... at (x, y) (why) ...; about A m^2 unknown behind them (summary)'."""
    places = [(o.candidate.target, o.entry.reason) for o in left]
    return "partial: " + _left_text(planner, grid, places, summary, " though the map shows a way")


def _left_text(planner: ExplorationPlanner, grid: OccupancyGrid,
               places: list[tuple[tuple[float, float], str]], summary: str, how: str = "") -> str:
    """'N frontiers left unexplored{how} ((x, y): why; ...); about A m^2 unknown behind them (summary)'."""
    if not places:
        return f"no frontier left to go to ({summary})"
    area = planner.unknown_behind(grid, [xy for xy, _ in places])
    where = "; ".join(f"({x:.2f}, {y:.2f}): {why}" for (x, y), why in places[:5])
    more = f"; and {len(places) - 5} more" if len(places) > 5 else ""
    n = len(places)
    return (f"{n} frontier{'s' if n > 1 else ''} left unexplored{how} ({where}{more}); about {area:.1f} m^2 "
            f"unknown behind {'them' if n > 1 else 'it'} ({summary})")


def budget_text(planner: ExplorationPlanner, grid: OccupancyGrid, robot_xy: tuple[float, float],
                budget: float, summary: str) -> str:
    """'partial: the time budget of N s was spent: ' + what is left, as :func:`partial_text` says it.

    What is left: the frontiers given up while the map shows a way, then those not explored yet.
    """
    places = [(o.candidate.target, o.entry.reason) for o in planner.left_open(grid, robot_xy)]
    places += [(c.target, "not explored yet") for c in not_explored_yet(planner, grid, robot_xy)]
    return f"partial: the time budget of {budget:g} s was spent: {_left_text(planner, grid, places, summary)}"
