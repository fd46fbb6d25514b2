"""Why a search run ended as it did: where its time went and what became of the target (search_eval's).

Read after the run, for the benchmark's report only (the simulator's truth is never given to the
leaves):

- :func:`phases`: robot seconds each leaf of the search was running (from the tick log's status
  changes), and the exploring leaf's time split by what it was doing: driving to a frontier, to a
  place to look at unseen floor from (``view``), looking around there, or choosing.
- :func:`diagnose`: whether the target was ever in the camera's view (within the range the scene
  graph takes detections from, in the field of view, no wall or obstacle of the world's grid in
  between), when; whether a candidate was made of it (a search candidate within
  :data:`SAME_M` of it); what became of that candidate (rejected as wrong or unreached); and one
  cause for a miss: ``never in view``, ``in view, never a candidate``, ``candidate rejected:
  wrong``, ``candidate rejected: unreached``, ``candidate not confirmed in time``.
"""

from __future__ import annotations

import json
import math
from collections import defaultdict
from typing import Any

import numpy as np

#: A search candidate this close (m) to the target is a candidate of it.
SAME_M = 1.0
#: The camera's view for "in view": the scene graph's range filter (m) and a near range, half field of view.
FAR_M, NEAR_M, HALF_FOV_DEG = 4.5, 2.5, 35.0
#: Search leaves whose running time is counted (by node name in the shipped tree; others are ignored).
LEAVES = ("look_around", "locate", "approach", "verify")


def phases(log: str) -> dict[str, float]:
    """Robot seconds per search leaf running, and the exploring leaf's split (``locate:<doing>``)."""
    spent: dict[str, float] = defaultdict(float)
    running: set[str] = set()
    doing = "choosing"
    last = 0.0
    for line in log.splitlines():
        try:
            event = json.loads(line)
        except json.JSONDecodeError:
            continue
        t = float(event.get("t", last))
        if t > last:
            for leaf in running:
                spent[leaf] += t - last
            if "locate" in running:
                spent[f"locate:{doing}"] += t - last
            last = t
        kind = event.get("event")
        if kind == "tick":
            for change in event.get("changed", []):
                leaf = str(change.get("node", "")).rsplit("/", 1)[-1]
                if leaf in LEAVES:
                    (running.add if change.get("status") == "RUNNING" else running.discard)(leaf)
        elif kind == "explore_goal":
            doing = "to " + str(event.get("kind", "frontier"))
        elif kind == "search_view_goal":
            doing = "to view"
        elif kind in ("explore_reached", "search_look"):
            doing = "looking"
        elif kind in ("explore_blacklist", "search_view_given_up", "search_explored"):
            doing = "choosing"
    return {k: round(v, 1) for k, v in sorted(spent.items())}


def search_events(log: str) -> list[dict[str, Any]]:
    """The tick log's ``search_candidate`` and ``candidate_rejected`` events, in order."""
    out = []
    for line in log.splitlines():
        if '"search_candidate"' not in line and '"candidate_rejected"' not in line:
            continue
        try:
            event = json.loads(line)
        except json.JSONDecodeError:
            continue
        if event.get("event") in ("search_candidate", "candidate_rejected"):
            out.append({k: event.get(k) for k in ("event", "t", "id", "object", "x", "y", "source",
                                                 "colour", "kind", "reason")})
    return out


def _clear(grid: Any, a: tuple[float, float], b: tuple[float, float], skip_end: float = 0.35) -> bool:
    """Whether no occupied cell of ``grid`` lies on the segment a -> b (its last ``skip_end`` m aside)."""
    length = math.dist(a, b)
    usable = length - skip_end
    if usable <= 0:
        return True
    n = max(2, int(usable / (grid.resolution / 2.0)))
    s = np.linspace(0.0, usable / length, n)
    xs, ys = a[0] + (b[0] - a[0]) * s, a[1] + (b[1] - a[1]) * s
    rows = np.floor((ys - grid.origin.y) / grid.resolution).astype(int)
    cols = np.floor((xs - grid.origin.x) / grid.resolution).astype(int)
    h, w = grid.data.shape
    inside = (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
    return not bool(np.any(grid.data[rows[inside], cols[inside]] >= 50))


def diagnose(trace: list[list[float]], world: Any, target: Any, events: list[dict[str, Any]],
             found: bool) -> dict[str, Any]:
    """When the target was first in view (near and far), its candidates and their fate, the cause."""
    tx, ty = float(target.pose.x), float(target.pose.y)
    first: dict[str, float | None] = {"near": None, "far": None}
    closest = math.inf
    for t, x, y, yaw in trace:
        d = math.hypot(tx - x, ty - y)
        closest = min(closest, d)
        bearing = abs((math.atan2(ty - y, tx - x) - yaw + math.pi) % (2.0 * math.pi) - math.pi)
        if d > FAR_M or math.degrees(bearing) > HALF_FOV_DEG:
            continue
        if first["far"] is not None and (first["near"] is not None or d > NEAR_M):
            continue
        if not _clear(world.grid, (x, y), (tx, ty)):
            continue
        if first["far"] is None:
            first["far"] = t
        if d <= NEAR_M and first["near"] is None:
            first["near"] = t
    near_ids: dict[str, float] = {}
    fate: list[str] = []
    for e in events:
        ex, ey = e.get("x"), e.get("y")
        if ex is None or ey is None or math.hypot(float(ex) - tx, float(ey) - ty) > SAME_M:
            continue
        if e["event"] == "search_candidate":
            near_ids.setdefault(str(e["id"]), float(e["t"]))
        else:
            fate.append(f"{e.get('kind')}: {str(e.get('reason', ''))[:80]}")
    if found:
        cause = "found"
    elif near_ids and fate:
        cause = "candidate rejected: " + fate[-1].split(":", 1)[0]
    elif near_ids:
        cause = "candidate not confirmed in time"
    elif first["far"] is not None:
        cause = "in view, never a candidate"
    else:
        cause = "never in view"
    return {
        "cause": cause,
        "in_view_s": first["far"],
        "in_view_near_s": first["near"],
        "closest_m": round(closest, 2) if math.isfinite(closest) else None,
        "candidate_s": min(near_ids.values()) if near_ids else None,
        "rejections": fate[-3:],
    }
