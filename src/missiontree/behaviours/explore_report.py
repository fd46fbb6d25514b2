"""What the Explore leaf writes when it ends: ``exploration.json``'s content and its one-line outcome.

Kept apart from the leaf (:mod:`missiontree.behaviours.explore`) as the part that only reads: the
planner's blacklist, the frontiers left and the map.
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np

from missiontree.mapping.exploration import ExplorationPlanner, LeftOpen
from missiontree.mapping.grid import unknown_mask
from missiontree.mapping.mapfile import write_map
from missiontree.types import OccupancyGrid


def exploration_report(planner: ExplorationPlanner | None, outcome: str, goals: int, grid: OccupancyGrid,
                       left_open: list[LeftOpen] | None,
                       robot_xy: tuple[float, float] | None) -> dict[str, Any]:
    """How the exploration ended, what is left (positions, why, unknown area) and what was given up.

    ``left_open``: the frontiers a partial end left; ``robot_xy``: where the robot stands, to list
    what it would have gone to next when it was stopped or failed (None: not listed).
    """
    left: list[dict[str, Any]] = []
    unknown_left = 0.0
    if planner is not None:
        if outcome == "partial" and left_open:
            left = [{"x": round(o.candidate.target[0], 3), "y": round(o.candidate.target[1], 3),
                     "reason": o.entry.reason} for o in left_open]
            unknown_left = planner.unknown_behind(grid, [o.candidate.target for o in left_open])
        elif outcome in ("stopped", "failed") and robot_xy is not None:
            # the frontiers (or scan points) only: a search's places to look from are no exploration left
            offered = [c for c in planner.candidates(grid, robot_xy) if c.kind in ("frontier", "scan_point")]
            left = [{"x": round(c.target[0], 3), "y": round(c.target[1], 3),
                     "reason": "not explored yet"} for c in offered]
            unknown_left = planner.unknown_behind(grid, [c.target for c in offered])
    slivers = [] if planner is None else planner.slivers
    return {
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


def save_exploration(leaf: Any, grid: OccupancyGrid, report: dict[str, Any]) -> None:
    """Write what an ending Explore ``leaf`` leaves: its outputs, the map files, exploration.json.

    The outputs (``explored_area``, ``explore_complete``, ``unexplored``, ``map_yaml``), the run's
    ``exploration`` report, ``map.pgm`` + ``map.yaml`` and ``exploration.json`` in the run directory.
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
    _, yaml_path = write_map(grid, run_dir, name)
    leaf.write("map_yaml", str(yaml_path))
    leaf.emit("map_saved", path=str(yaml_path), known_m2=round(known_area(grid), 3))
    stem = "" if name == "map" else f"{name}_"
    (run_dir / f"{stem}exploration.json").write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")


def said(report: dict[str, Any]) -> str:
    """How the exploration ended, in a line for the run's result (summary.json's outcome text)."""
    if report["outcome"] == "explored":
        n = len(report["slivers_left"])
        small = (f"; {n} small unknown sliver{'s' if n != 1 else ''} left as not worth a trip, "
                 f"{report['slivers_m2']:.1f} m^2") if n else ""
        return (f"explored: no reachable frontier worth a trip left ({report['known_m2']:.0f} m^2 "
                f"known{small})")
    left = report["frontiers_left"]
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
    area = planner.unknown_behind(grid, [o.candidate.target for o in left])
    where = "; ".join(f"({o.candidate.target[0]:.2f}, {o.candidate.target[1]:.2f}): {o.entry.reason}"
                      for o in left[:5])
    more = f"; and {len(left) - 5} more" if len(left) > 5 else ""
    n = len(left)
    return (f"partial: {n} frontier{'s' if n > 1 else ''} left unexplored though the map shows a way "
            f"({where}{more}); about {area:.1f} m^2 unknown behind "
            f"{'them' if n > 1 else 'it'} ({summary})")
