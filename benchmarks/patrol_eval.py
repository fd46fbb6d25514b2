"""The patrol-robot thesis's scenarios, measured: the thesis's surveillance (0.5 s and 0.2 s) against ours.

Two splits (``--split dev|test|both``, default both), reported side by side:

- ``dev`` (tune here) — the thesis's scenarios (§4.5) on the shipped worlds: A = corridor, B =
  entrance hall, C/D = the combined route, each with its hand-written waypoint table, seeds 7 and
  13. People cross the robot's path: walkers pace back and forth across every leg of the route at
  1.0-1.6 m/s, so they cross the camera's view at bearings across its 70° field of view.
- ``test`` (report only, once at the end of a change) — ``--test-worlds`` held-out worlds of the
  evaluation splits (:func:`missiontree.evaluation.splits.split_worlds` ``("test", n, people=True)``:
  a second floorplan family — long corridors with 0.8-0.9 m doors, L/T corridors, open plan, rooms
  off rooms, clutter by doors, warehouse floors — and real SLAM maps), seed 7. Nobody wrote their
  routes: the waypoints are read from the robot's own map and start pose (rooms segmented from the
  occupancy map, one spot per 36 m² of a room's floor with 0.5 m to any obstacle, spread by
  k-means, the most open cell for a small room; toured nearest first while the planned path stays
  within 60 m, up to three laps within it; unreachable spots left out). The people differ in kind
  too: the split's own walkers, plus one walker crossing each waypoint at a random angle and one
  walking each leg's planned path back and forth (kept 0.6 m to one side where the map allows), so
  people meet the robot head-on and from behind as well as across, at 0.6-1.6 m/s. Every walker's
  route keeps 0.3 m from the map's obstacles.

The test split prints its rates with 95 % Wilson intervals (detection over encounters, alarms with
an error over 1 m over alarms, waypoints reached over waypoints tried), the dev-test gap (test minus
dev) of each figure, and a markdown table of both. The VLM answers after a latency drawn from
0.5-3 s (simulated clock). Configurations, all on the same worlds, seeds and routes:

- ``seed_05`` — the thesis as built: the latest frame to the VLM every 0.5 s (scenarios A-C), the
  distance read by its ±15° front cone from the *latest* scan once the answer arrives.
- ``seed_02`` — the same every 0.2 s (scenario D).
- ``ours`` — the detector on a frame every 0.4 s (the leaf's ``detect_period``), the VLM
  confirming at most every 0.5 s (≤ 2 calls/s), the distance from the depth inside the person's
  box, fused at the frame's instant.

Each run is the real mission (loader, builder, runner, leaves) on the simulator: a Parallel of
Patrol (one lap) and Surveillance, without servoing so that every configuration drives the same
path. The runs go through the batch runner (missiontree.evaluation) on a process pool of ``--jobs``
workers; a probe scores each run inside its worker. Scoring uses the simulator's ground truth
(never seen by the leaves):

- an *encounter* is a run of frames in which a person shows (gaps up to 1 s bridged), with at least
  two frames showing them with MIN_PIXELS or more while they stand at least OVERLAP from the robot
  (a walker passing through the robot's body, which real people cannot, is not a crossing anyone
  can be asked to see; such encounters are counted apart, ``through_robot``, in the JSON and the
  per-run lines, as overlapping alarms are); it is *detected* when an alarm's frame lies inside
  it and shows that person (encounters that begin in a run's last 3 s, the longest answer latency,
  are not scored: no configuration could answer them before the patrol ends);
- the distance error of an alarm is |reported − true| against the true distance, at the frame's
  time, from the robot to the person in that frame whose distance matches best (favourable to
  every method alike); an alarm without a distance (the thesis's ``inf``) counts as an error > 1 m.
  Simulated walkers ignore the robot and may walk through its body; alarms on frames where a person
  is closer than OVERLAP (bodies overlapping, impossible for real people) are not scored for
  distance and are counted apart (``overlapping``).

``--detector oracle`` runs every configuration on the simulation oracle (a perfect detector) instead
of the shipped trained detector, to separate what the detector costs from what the design costs.
The runs are listed alternating between configurations scenario by scenario (every score is on the
simulated clock, so the order the pool finishes them in changes none of them); ratios of ours
against the thesis's are printed with min/median/max over scenarios (worlds on test). ``--quick``
runs dev seed 7 and (unless ``--test-worlds``) 3 test worlds. Last line: one JSON object,
``{"dev": {method: figures}, "test": {method: figures}, "gap": {method: test - dev},
"test_worlds": [...], ...}``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import random
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

from missiontree.backends.sim import create_robot, load_world
from missiontree.behaviours.waypoints import load_waypoints
from missiontree.evaluation import BatchPlan, PoolEngine, RunSpec, run_batch
from missiontree.evaluation.report import wilson
from missiontree.mapping.planner import Costmap
from missiontree.paths import find_config
from missiontree.plugins.manager import load_plugins
from missiontree.semantics.rooms import segment_rooms
from missiontree.session.models import BrokenProvider, build_models
from missiontree.types import OccupancyGrid

try:  # the held-out worlds (the test split); the dev split runs without them
    from missiontree.evaluation.splits import split_worlds, write_split_world
except ImportError:  # pragma: no cover - until the splits module is there
    split_worlds = write_split_world = None  # type: ignore[assignment]

#: (scenario, world, route file, laps) — C and D share the combined route; D is seed_02's scenario.
SCENARIOS = [("A", "corridor", "scenario_a", 5), ("B", "entrance_hall", "scenario_b", 3),
             ("C/D", "combined", "scenario_c", 1)]

CONFIGS: dict[str, dict[str, Any]] = {
    "seed_05": {"mode": "poll", "period": 0.5, "method": "seed", "fuse_at": "answer", "max_in_flight": 99},
    "seed_02": {"mode": "poll", "period": 0.2, "method": "seed", "fuse_at": "answer", "max_in_flight": 99},
    "ours": {"mode": "detect", "period": 0.5, "method": "depth", "fuse_at": "frame", "max_in_flight": 6},
}

LATENCY = (0.5, 3.0)          # seconds, the thesis's cloud VLM
SPEEDS = (1.0, 1.6)           # m/s, people crossing
MIN_PIXELS = 400              # a person this visible in a frame can be asked to be seen
MERGE_GAP = 1.0               # seconds out of view that still belong to the same encounter
OVERLAP = 0.36                # m: robot body (0.17) + torso (0.19); simulated walkers pass through it
WALKER_SPACING = 3.0          # metres of route between crossing walkers
BEARING_BINS = [-35, -25, -15, -5, 5, 15, 25, 35]
SEEDS = (7, 13)               # each scenario runs with walkers and simulator seeded by each


@dataclass
class RunScore:
    """What one run of one configuration on one scenario (or held-out world) measured."""

    split: str
    scenario: str
    config: str
    seed: int = 0
    sim_seconds: float = 0.0
    wall_seconds: float = 0.0
    encounters: int = 0
    detected: int = 0
    calls: int = 0
    errors: list[float] = field(default_factory=list)
    bearings: list[float] = field(default_factory=list)
    no_distance: int = 0
    overlapping: int = 0
    through_robot: int = 0
    reached: int = 0
    skipped: int = 0

    @property
    def detection_rate(self) -> float:
        """Share of encounters with an alarm."""
        return self.detected / self.encounters if self.encounters else float("nan")

    @property
    def calls_per_s(self) -> float:
        """VLM calls per simulated second."""
        return self.calls / self.sim_seconds if self.sim_seconds else float("nan")


# -- worlds with crossing people ---------------------------------------------------------------------


def crossing_world(world_name: str, route_name: str, out_dir: Path, rng: random.Random) -> Path:
    """The scenario's world with its people replaced by walkers pacing across every leg of the route."""
    source = find_config("worlds", world_name)
    data = yaml.safe_load(source.read_text())
    data["people"] = []
    empty = out_dir / f"{world_name}_empty.yaml"
    empty.write_text(yaml.safe_dump(data, sort_keys=False))
    world = load_world(empty)
    route = load_waypoints(route_name)
    legs = {(a.pose.x, a.pose.y, b.pose.x, b.pose.y)
            for a, b in zip(route, route[1:] + route[:1], strict=True) if a.name != b.name}
    people: list[dict[str, Any]] = []
    for x1, y1, x2, y2 in sorted(legs):
        if (x2, y2, x1, y1) in legs and (x2, y2) < (x1, y1):
            continue  # out and back along the same leg: one set of walkers
        length = math.hypot(x2 - x1, y2 - y1)
        nx, ny = -(y2 - y1) / max(length, 1e-9), (x2 - x1) / max(length, 1e-9)
        for k in range(max(1, int(length // WALKER_SPACING))):
            f = (k + 0.5) / max(1, int(length // WALKER_SPACING))
            cx, cy = x1 + f * (x2 - x1), y1 + f * (y2 - y1)
            ends = [_free_end(world, cx, cy, s * nx, s * ny) for s in (1.0, -1.0)]
            if math.dist(ends[0], ends[1]) < 1.0:
                continue
            people.append({
                "id": f"walker{len(people) + 1}", "route": [list(ends[0]), list(ends[1])],
                "speed": round(rng.uniform(*SPEEDS), 2), "start_time": round(rng.uniform(0.0, 15.0), 1),
                "loop": True, "pause": round(rng.uniform(1.0, 6.0), 1),
                "shirt_rgb": [rng.randrange(30, 226) for _ in range(3)],   # people dress differently
                "trousers_rgb": [rng.randrange(20, 120) for _ in range(3)],
            })
    data["people"] = people
    path = out_dir / f"{world_name}_crossing.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _free_end(world: Any, cx: float, cy: float, dx: float, dy: float) -> tuple[float, float]:
    """The farthest point up to 2.5 m from (cx, cy) along (dx, dy) with 0.35 m to any wall."""
    best = (round(cx, 2), round(cy, 2))
    for step in np.arange(0.1, 2.55, 0.1):
        x, y = cx + step * dx, cy + step * dy
        if world.clearance(x, y) < 0.35:
            break
        best = (round(float(x), 2), round(float(y), 2))
    return best


# -- the test split: held-out worlds, routes from the robot's map, walkers through them -------------


#: Held-out worlds in the test split (``--test-worlds``).
TEST_WORLDS = 8
#: The seed every test-split run uses (the worlds, not the seeds, vary).
TEST_SEED = SEEDS[0]
#: Planned path length (m) a generated route may take over its laps: about 4 minutes at 0.25 m/s.
ROUTE_LENGTH = 60.0
#: A generated waypoint keeps this far (m) from the map's obstacles: room to turn, people to pass.
ROUTE_CLEARANCE = 0.5
#: Floor area (m²) a room's waypoint stands for: a larger room gets one waypoint per this much.
ROOM_AREA = 36.0
#: A generated route has at least this many waypoints (an open-plan floor is one "room").
MIN_WAYPOINTS = 3
#: Walkers' routes keep this far (m) from the map's obstacles, and walk this far (m) to the right
#: of the robot's legs when the map allows (people keep to one side of a corridor).
WALKER_CLEARANCE = 0.3
WALKER_OFFSET = 0.6
#: Walking speeds (m/s) of the test split's people: slow ones too.
TEST_SPEEDS = (0.6, 1.6)


def clearance_map(grid: OccupancyGrid) -> np.ndarray:
    """Distance (m) from each cell to the nearest obstacle or unknown cell of ``grid``."""
    free = (grid.data >= 0) & (grid.data < 50)
    return cv2.distanceTransform(free.astype(np.uint8), cv2.DIST_L2, 5) * grid.resolution


def _clear_at(grid: OccupancyGrid, clearance: np.ndarray, x: float, y: float) -> float:
    row, col = grid.world_to_cell(x, y)
    h, w = clearance.shape
    return float(clearance[row, col]) if 0 <= row < h and 0 <= col < w else 0.0


def line_clear(grid: OccupancyGrid, clearance: np.ndarray, a: tuple[float, float], b: tuple[float, float],
               margin: float) -> bool:
    """Whether every point of the segment a-b keeps ``margin`` metres from the map's obstacles."""
    steps = max(2, int(math.ceil(math.dist(a, b) / (grid.resolution / 2))) + 1)
    t = np.linspace(0.0, 1.0, steps)
    cols = np.floor((a[0] + t * (b[0] - a[0]) - grid.origin.x) / grid.resolution).astype(int)
    rows = np.floor((a[1] + t * (b[1] - a[1]) - grid.origin.y) / grid.resolution).astype(int)
    h, w = clearance.shape
    inside = (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
    return bool(inside.all() and np.all(clearance[rows, cols] >= margin))


def room_spots(grid: OccupancyGrid, start: tuple[float, float]) -> list[tuple[float, float]]:
    """Patrol spots read from the map alone: spread over each segmented room, open spots first.

    A room gets one spot per ROOM_AREA of floor with ROUTE_CLEARANCE to obstacles (at least one,
    the room's most open cell); several are spread by a few k-means rounds over its cells and moved
    to the nearest cell with that clearance. The whole map gets at least MIN_WAYPOINTS spots.
    """
    seg = segment_rooms(grid, inside=start)
    clearance = clearance_map(grid)
    res = grid.resolution
    rooms = []
    for label in range(1, len(seg.rooms) + 1):
        rows, cols = np.nonzero((seg.labels == label) & (clearance >= ROUTE_CLEARANCE))
        if len(rows):
            xy = np.stack([grid.origin.x + (cols + 0.5) * res, grid.origin.y + (rows + 0.5) * res], axis=1)
            rooms.append((xy, clearance[rows, cols]))
    if not rooms:
        return []
    counts = [max(1, round(len(xy) * res * res / ROOM_AREA)) for xy, _ in rooms]
    largest = int(np.argmax([len(xy) for xy, _ in rooms]))
    counts[largest] += max(0, MIN_WAYPOINTS - sum(counts))
    spots: list[tuple[float, float]] = []
    for (xy, clear), k in zip(rooms, counts, strict=True):
        spots += _spread(xy, clear, min(k, len(xy)))
    return spots


def _spread(xy: np.ndarray, clear: np.ndarray, k: int) -> list[tuple[float, float]]:
    """``k`` points spread over the cells ``xy``: the most open cell, farthest-point picks, k-means."""
    cells = xy[:: max(1, len(xy) // 4000)]
    centres = [xy[int(np.argmax(clear))]]
    while len(centres) < k:
        d = np.min(np.linalg.norm(cells[:, None, :] - np.array(centres)[None], axis=2), axis=1)
        centres.append(cells[int(np.argmax(d))])
    means = np.array(centres, dtype=float)
    if k > 1:
        for _ in range(8):
            nearest = np.argmin(np.linalg.norm(cells[:, None, :] - means[None], axis=2), axis=1)
            means = np.array([cells[nearest == i].mean(axis=0) if np.any(nearest == i) else means[i]
                              for i in range(k)])
    snapped = [xy[int(np.argmin(np.linalg.norm(xy - m, axis=1)))] for m in means]
    return [(round(float(p[0]), 2), round(float(p[1]), 2)) for p in snapped]


@dataclass
class MapRoute:
    """A route generated from a map: its waypoints and the planned path of each leg to them."""

    waypoints: list[tuple[float, float]]
    legs: list[np.ndarray]    # legs[i]: planned path (N, 2) to waypoints[i] from the previous point
    length: float             # planned metres from the start through every waypoint
    closing: float | None     # planned metres from the last waypoint back to the first (None: no path)

    @property
    def laps(self) -> int:
        """Laps that keep the patrol within ROUTE_LENGTH (at least one, at most three)."""
        if self.closing is None or len(self.waypoints) < 2:
            return 1
        lap = self.length - _polyline_length([tuple(p) for p in self.legs[0]]) + self.closing
        return max(1, min(3, int((ROUTE_LENGTH - self.length) // max(lap, 1.0)) + 1))


def map_route(grid: OccupancyGrid, start: tuple[float, float], profile: Any,
              budget: float = ROUTE_LENGTH) -> MapRoute:
    """A patrol route from the robot's map: room spots in a nearest-first tour within ``budget`` metres.

    Each leg is planned on the map's costmap (the robot ``profile``'s radius and inflation); spots
    it cannot reach are left out, and the tour stops before its planned length would pass ``budget``.
    """
    nav = profile.navigation
    costmap = Costmap(grid, profile.body.radius, nav.inflation_radius, nav.cost_scaling)
    spots = room_spots(grid, start)
    here, length = start, 0.0
    route: list[tuple[float, float]] = []
    legs: list[np.ndarray] = []
    while spots:
        spots.sort(key=lambda p: math.dist(p, here))
        spot = spots.pop(0)
        path = costmap.plan(here, spot)
        if path is None:
            continue
        step = float(np.hypot(*np.diff(path.points, axis=0).T).sum()) if len(path.points) > 1 else 0.0
        if length + step > budget and route:
            break
        route.append(spot)
        legs.append(np.asarray(path.points, dtype=float))
        length += step
        here = spot
    closing = costmap.plan(route[-1], route[0]) if len(route) > 1 else None
    back = None if closing is None else _polyline_length([(float(x), float(y)) for x, y in closing.points])
    return MapRoute(route, legs, length, back)


def route_walkers(grid: OccupancyGrid, route: MapRoute, rng: random.Random) -> list[dict[str, Any]]:
    """People for a generated route: one crossing each waypoint, one walking each leg back and forth.

    A crosser paces a straight line through the waypoint at a random angle (up to 3 m each side,
    clear of the map's obstacles); a leg walker walks the leg's planned path, kept WALKER_OFFSET to
    one side where the map allows, so that it meets the robot head-on or overtakes it. Every route
    keeps WALKER_CLEARANCE from the map's obstacles (no walking through walls or furniture).
    """
    clearance = clearance_map(grid)
    people: list[dict[str, Any]] = []

    def add(points: list[tuple[float, float]]) -> None:
        people.append({
            "id": f"walker{len(people) + 1}",
            "route": [[round(float(x), 2), round(float(y), 2)] for x, y in points],
            "speed": round(rng.uniform(*TEST_SPEEDS), 2), "start_time": round(rng.uniform(0.0, 30.0), 1),
            "loop": True, "pause": round(rng.uniform(0.5, 6.0), 1),
            "shirt_rgb": [rng.randrange(30, 226) for _ in range(3)],
            "trousers_rgb": [rng.randrange(20, 120) for _ in range(3)],
        })

    for x, y in route.waypoints:
        for _ in range(12):
            angle = rng.uniform(0.0, math.pi)
            dx, dy = math.cos(angle), math.sin(angle)
            ends = [_reach(grid, clearance, (x, y), s * dx, s * dy) for s in (1, -1)]
            if math.dist(*ends) >= 2.0:
                add(ends)
                break
    for leg in route.legs:
        path = _offset_path(grid, clearance, leg)
        if path is not None and _polyline_length(path) >= 3.0:
            add(path + path[-2:0:-1])  # there and back along the same path (the loop closes on it)
    return people


def _reach(grid: OccupancyGrid, clearance: np.ndarray, centre: tuple[float, float], dx: float,
           dy: float) -> tuple[float, float]:
    """The farthest point up to 3 m from ``centre`` along (dx, dy) with a clear line to it."""
    best = centre
    for step in np.arange(0.1, 3.05, 0.1):
        point = (centre[0] + step * dx, centre[1] + step * dy)
        if _clear_at(grid, clearance, *point) < WALKER_CLEARANCE:
            break
        best = point
    return best


def _offset_path(grid: OccupancyGrid, clearance: np.ndarray,
                 leg: np.ndarray) -> list[tuple[float, float]] | None:
    """The leg's path shifted to one side where the map allows, thinned to straight clear pieces."""
    if len(leg) < 2:
        return None
    shifted: list[tuple[float, float]] = []
    for i, (x, y) in enumerate(leg):
        a, b = leg[max(0, i - 2)], leg[min(len(leg) - 1, i + 2)]
        heading = math.atan2(b[1] - a[1], b[0] - a[0])
        nx, ny = math.sin(heading), -math.cos(heading)  # to the right of the robot's direction
        for offset in (WALKER_OFFSET, WALKER_OFFSET / 2, 0.0):
            point = (float(x + offset * nx), float(y + offset * ny))
            if _clear_at(grid, clearance, *point) >= WALKER_CLEARANCE:
                shifted.append(point)
                break
    shifted = shifted[:-1:5] + shifted[-1:]  # a point every 0.25 m or so is plenty
    if len(shifted) < 2:
        return None
    thin, i = [shifted[0]], 0
    while i < len(shifted) - 1:
        if not line_clear(grid, clearance, shifted[i], shifted[i + 1], WALKER_CLEARANCE):
            return None  # two neighbouring points without a clear line: no walker on this leg
        j = i + 1
        while j + 1 < len(shifted) and line_clear(grid, clearance, shifted[i], shifted[j + 1],
                                                  WALKER_CLEARANCE):
            j += 1
        thin.append(shifted[j])
        i = j
    return thin


def _polyline_length(points: list[tuple[float, float]]) -> float:
    return sum(math.dist(a, b) for a, b in zip(points, points[1:], strict=False))


@dataclass
class HeldOutWorld:
    """A held-out world ready to run: its file (with walkers), its generated route file, the route."""

    name: str
    family: str
    world: Path
    route: Path
    waypoints: int
    length: float
    laps: int
    walkers: int
    timeout: float


def held_out_world(world: Any, out_dir: Path, rng: random.Random) -> HeldOutWorld | None:
    """Write a split world with walkers through a route generated from the robot's map, and the route.

    The route reads only what the robot has (its map and its start pose); the split's own people
    walk as they do, and the route's walkers (:func:`route_walkers`) are added. None when the map
    gives no reachable waypoint.
    """
    base = write_split_world(world, out_dir / "split")
    robot = create_robot({"world": str(base), "seed": 0})
    try:
        grid = robot.occupancy()
        pose = robot.pose()
        assert grid is not None and pose is not None
        start = (pose.pose.x, pose.pose.y)
        profile = robot.profile
    finally:
        robot.close()
    route = map_route(grid, start, profile)
    if not route.waypoints:
        return None
    data = yaml.safe_load(base.read_text(encoding="utf-8"))
    walkers = route_walkers(grid, route, rng)
    own = list(data.get("people") or [])
    taken = {str(p.get("id")) for p in own}
    for person in walkers:
        while person["id"] in taken:
            person["id"] += "b"
    data["people"] = own + walkers
    stem = "".join(ch if ch.isalnum() else "_" for ch in world.name)
    path = base.parent / f"{stem}_patrol.yaml"  # beside it: a map world reads its map from there
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    route_file = base.parent / f"{stem}_route.yaml"
    route_file.write_text(yaml.safe_dump({
        "source": f"generated from the robot's map of {world.name}: room spots, nearest first",
        "waypoints": [{"name": f"R{i + 1}", "x": x, "y": y, "yaw": 0.0}
                      for i, (x, y) in enumerate(route.waypoints)]}, sort_keys=False), encoding="utf-8")
    longest = max(_polyline_length([(float(x), float(y)) for x, y in leg]) for leg in route.legs)
    timeout = max(90.0, round(3.0 * longest / profile.limits.max_v))  # 3 x the longest leg at top speed
    return HeldOutWorld(world.name, world.family, path, route_file, len(route.waypoints), route.length,
                        route.laps, len(own) + len(walkers), timeout)


# -- one run -----------------------------------------------------------------------------------------


#: The benchmark mission: one lap of the route with surveillance, no servoing. The route, the laps
#: and the surveillance configuration are its ``params`` (set per run by the batch).
MISSION = """version: 1
description: patrol_eval run
params:
  route: scenario_a
  laps: 1
  waypoint_timeout: 90
  mode: detect
  period: 0.5
  method: depth
  fuse_at: frame
  max_in_flight: 6
root:
  Parallel:
    name: patrol_and_watch
    policy: success_on_one
    children:
      - Patrol:
          name: patrol
          waypoints_file: ${route}
          laps: ${laps}
          yaw_tolerance: 6.28
          waypoint_timeout: ${waypoint_timeout}
      - Surveillance:
          name: surveillance
          alarm_cooldown: 0
          mode: ${mode}
          period: ${period}
          method: ${method}
          fuse_at: ${fuse_at}
          max_in_flight: ${max_in_flight}
"""


def models_config(detector: str) -> dict[str, Any]:
    """A shipped models config (``offline``: the trained detector; ``oracle``) with the VLM latency pinned."""
    data = yaml.safe_load(find_config("models", detector).read_text(encoding="utf-8"))
    data["roles"]["vlm"].update(latency={"uniform": list(LATENCY)}, timeout=10.0)
    return data


def choose_models(oracle: bool) -> tuple[dict[str, Any], str]:
    """The models every run uses: the shipped trained detector, or the oracle when asked or unusable."""
    if oracle:
        return models_config("oracle"), "oracle (trained detector not used: --detector oracle)"
    models = build_models(models_config("offline"), providers=load_plugins(autoload=False).providers, seed=0)
    detector = models.get("detector")
    if not isinstance(detector, BrokenProvider):
        return models_config("offline"), "sim_detector (trained)"
    return models_config("oracle"), f"oracle (trained detector not used: {detector.reason})"


class PatrolProbe:
    """Scores one run inside its batch worker: the true pose at every camera frame, then the events.

    The leaves never see the truth; the probe reads it between ticks and, at the end, scores the
    run's tick log (its ``ticks.jsonl``) against it.
    """

    def __init__(self) -> None:
        self.poses: dict[float, Any] = {}

    def on_tick(self, session: Any) -> None:
        """The true pose of the latest frame (scoring only)."""
        frame = session.robot.rgbd()
        if frame is not None and frame.stamp not in self.poses:
            self.poses[frame.stamp] = session.robot.truth.robot_pose_at(frame.stamp)

    def finish(self, session: Any, result: Any) -> dict[str, Any]:
        """RunScore's figures (an infinite error, an alarm without a distance, as null)."""
        log = (session.run_dir / "ticks.jsonl").read_text(encoding="utf-8")
        events = [json.loads(line) for line in log.splitlines() if line.strip()]
        score = RunScore("", "", "", sim_seconds=session.robot.now())
        score_events(score, events, session.robot.truth, self.poses)
        figures = dataclasses.asdict(score)
        figures["errors"] = [None if math.isinf(e) else e for e in score.errors]
        for key in _LABELS:
            figures.pop(key)
        return figures


@dataclass(frozen=True)
class Run:
    """One run to make: a configuration on a scenario (dev) or a held-out world (test)."""

    split: str
    scenario: str
    world: Path
    route: str
    laps: int
    config: str
    seed: int
    timeout: float = 90.0


#: RunScore fields the probe does not measure (the batch knows them).
_LABELS = ("split", "scenario", "config", "seed", "wall_seconds")


def run_all(runs: list[Run], models: dict[str, Any], jobs: int, out: Path) -> list[RunScore]:
    """Every run on the batch runner, scored."""
    mission = out / "patrol_eval.yaml"
    mission.write_text(MISSION, encoding="utf-8")
    specs = [RunSpec(world=str(run.world), seed=run.seed, run_seed=run.seed,
                     params=(("route", run.route), ("laps", str(run.laps)),
                             ("waypoint_timeout", f"{run.timeout:g}"),
                             *((k, str(v)) for k, v in CONFIGS[run.config].items())))
             for run in runs]
    request = {"backend": "sim", "models": models, "tick_hz": 10, "max_duration": 900, "allow_outside": True}
    plan = BatchPlan(mission=mission, runs=specs, request=request)
    fields = {f.name for f in dataclasses.fields(RunScore)} - set(_LABELS)
    scores = []
    with PoolEngine(jobs) as engine:
        records = run_batch(plan, engine, out / "batch", probe=PatrolProbe)
    for run, record in zip(runs, records, strict=True):
        where = f"{run.split} {run.scenario}/{run.config} seed {run.seed}"
        if record.status in ("ERROR", "INFRA"):
            raise SystemExit(f"{where}: the run did not complete ({record.status}: {record.reason})")
        if record.status != "SUCCESS":
            print(f"  note: {where} ended {record.status} ({record.stopped_by})", file=sys.stderr)
        figures = {k: v for k, v in record.figures.items() if k in fields}
        figures["errors"] = [math.inf if e is None else e for e in figures.get("errors", [])]
        scores.append(RunScore(run.split, run.scenario, run.config, run.seed, wall_seconds=record.wall_time_s,
                               **figures))
    return scores


def score_events(score: RunScore, events: list[dict[str, Any]], truth: Any, poses: dict[float, Any]) -> None:
    """Fill ``score`` from the run's tick-log events and the simulator's ground truth."""
    alarms = [e for e in events if e["event"] == "alarm"]
    score.calls = sum(1 for e in events if e["event"] == "model_call" and e.get("role") == "vlm")
    score.reached = sum(1 for e in events if e["event"] == "waypoint_reached")
    score.skipped = sum(1 for e in events if e["event"] == "waypoint_skipped")
    end = truth.visibility[-1][0] if truth.visibility else 0.0

    def through_robot(name: str, stamp: float) -> bool:
        pose = poses.get(stamp)
        return pose is not None and any(pid == name and math.hypot(x - pose.x, y - pose.y) < OVERLAP
                                        for pid, x, y in truth.people_at(stamp))

    spans = [span for span in encounters(truth.visibility, through_robot) if span[1] < end - LATENCY[1]]
    score.through_robot = len([span for span in encounters(truth.visibility) if span[1] < end - LATENCY[1]]) \
        - len(spans)
    shown = [(a["stamp"], set(truth.visible_at(a["stamp"]))) for a in alarms]
    score.encounters = len(spans)
    score.detected = sum(1 for name, t0, t1 in spans
                         if any(t0 - 1e-6 <= stamp <= t1 + 1e-6 and name in seen for stamp, seen in shown))
    for alarm in alarms:
        stamp = alarm["stamp"]
        pose = poses.get(stamp)
        seen = truth.visible_at(stamp)
        people = {pid: (x, y) for pid, x, y in truth.people_at(stamp) if pid in seen}
        if pose is None or not people:
            continue
        truths = {pid: (math.hypot(x - pose.x, y - pose.y), pose.bearing_to(x, y))
                  for pid, (x, y) in people.items()}
        if min(d for d, _ in truths.values()) < OVERLAP:
            score.overlapping += 1  # a walker passing through the robot's body: no real person can
            continue
        reported = alarm.get("distance")
        if reported is None:
            score.no_distance += 1
            score.errors.append(math.inf)
            score.bearings.append(min(truths.values())[1])
            continue
        best = min(truths.values(), key=lambda tb: abs(tb[0] - reported))
        score.errors.append(abs(best[0] - reported))
        score.bearings.append(best[1])


def encounters(
    visibility: list[tuple[float, dict[str, Any]]],
    through_robot: Callable[[str, float], bool] | None = None,
) -> list[tuple[str, float, float]]:
    """(person, first frame, last frame) of every encounter.

    An encounter is a run of frames in which a person shows at all, gaps up to MERGE_GAP seconds
    bridged (a leg hidden for a frame is the same crossing); it counts when at least two of its
    frames show the person with MIN_PIXELS or more (someone a guard could be asked to notice) and,
    when ``through_robot(person, stamp)`` is given, not inside the robot's body at that frame.
    """
    spans: list[tuple[str, float, float]] = []
    current: dict[str, list[Any]] = {}  # name -> [first, last, frames with MIN_PIXELS]

    def close(name: str) -> None:
        first, last, big = current.pop(name)
        if big >= 2:
            spans.append((name, first, last))

    for stamp, seen in visibility:
        for name in [n for n, (_, last, _) in current.items() if stamp - last > MERGE_GAP]:
            close(name)
        for name, sighting in seen.items():
            if sighting.kind != "person":
                continue
            entry = current.setdefault(name, [stamp, stamp, 0])
            entry[1] = stamp
            entry[2] += sighting.pixels >= MIN_PIXELS and not (through_robot and through_robot(name, stamp))
    for name in list(current):
        close(name)
    return spans


# -- report ------------------------------------------------------------------------------------------


def stats(errors: list[float]) -> tuple[float, float, int]:
    """Median and p95 of the finite errors (inf when any error is infinite at that rank), and count > 1 m."""
    if not errors:
        return float("nan"), float("nan"), 0
    values = np.sort(np.array(errors))
    median = float(values[int(0.5 * (len(values) - 1))]) if len(values) else float("nan")
    p95 = float(values[int(math.ceil(0.95 * (len(values) - 1)))])
    return median, p95, int(np.sum(values > 1.0))


def fmt(value: float) -> str:
    return "inf" if math.isinf(value) else ("nan" if math.isnan(value) else f"{value:.3f}")


def json_number(value: float) -> float | None:
    return None if not math.isfinite(value) else round(value, 4)


#: Figures whose dev-test gap is reported (test minus dev).
GAP_FIGURES = ("detection_rate", "model_calls_per_s", "distance_error_median_m", "distance_error_p95_m",
               "share_over_1m", "waypoint_reach_rate")


def rate(hits: int, trials: int) -> dict[str, Any]:
    """A rate with its 95 % Wilson interval and its count (None for no trials)."""
    low, high = wilson(hits, trials)
    return {"value": round(hits / trials, 4) if trials else None, "ci95": [round(low, 4), round(high, 4)],
            "n": trials}


def summarise(scores: list[RunScore]) -> dict[str, Any]:
    """Each configuration's figures over one split's runs; rates carry 95 % Wilson intervals."""
    summary: dict[str, Any] = {}
    for name in CONFIGS:
        runs = [s for s in scores if s.config == name]
        if not runs:
            continue
        errors = [e for s in runs for e in s.errors]
        bearings = [b for s in runs for b in s.bearings]
        median, p95, over = stats(errors)
        encounters_n = sum(s.encounters for s in runs)
        detected = sum(s.detected for s in runs)
        reached, skipped = sum(s.reached for s in runs), sum(s.skipped for s in runs)
        per_bin = {}
        for lo, hi in zip(BEARING_BINS, BEARING_BINS[1:], strict=False):
            chosen = [e for e, b in zip(errors, bearings, strict=True) if lo <= math.degrees(b) < hi]
            m, p, o = stats(chosen)
            per_bin[f"{lo}..{hi}"] = {"n": len(chosen), "median_m": json_number(m), "p95_m": json_number(p),
                                      "over_1m": o}
        detection, share_over, reach = rate(detected, encounters_n), rate(over, len(errors)), \
            rate(reached, reached + skipped)
        summary[name] = {
            "detection_rate": detection["value"], "detection_rate_ci95": detection["ci95"],
            "model_calls_per_s": round(sum(s.calls for s in runs) / sum(s.sim_seconds for s in runs), 3),
            "distance_error_median_m": json_number(median), "distance_error_p95_m": json_number(p95),
            "errors_over_1m": over, "share_over_1m": share_over["value"],
            "share_over_1m_ci95": share_over["ci95"],
            "alarms": len(errors), "no_distance": sum(s.no_distance for s in runs),
            "overlapping_not_scored": sum(s.overlapping for s in runs),
            "through_robot_not_scored": sum(s.through_robot for s in runs),
            "encounters": encounters_n, "waypoints_reached": reached, "waypoints_skipped": skipped,
            "waypoint_reach_rate": reach["value"], "waypoint_reach_rate_ci95": reach["ci95"],
            "runs": len(runs), "worlds": len({s.scenario for s in runs}),
            "simulated_s": round(sum(s.sim_seconds for s in runs), 1), "by_bearing_deg": per_bin,
        }
    return summary


def gaps(dev: dict[str, Any], test: dict[str, Any]) -> dict[str, Any]:
    """Test minus dev for each configuration's GAP_FIGURES (None where either is missing)."""
    out: dict[str, Any] = {}
    for name in CONFIGS:
        if name in dev and name in test:
            out[name] = {k: (round(test[name][k] - dev[name][k], 4)
                             if dev[name].get(k) is not None and test[name].get(k) is not None else None)
                         for k in GAP_FIGURES}
    return out


def markdown_table(summaries: dict[str, dict[str, Any]], gap: dict[str, Any]) -> list[str]:
    """A pasteable table: each method's figures on dev and test (95 % intervals for rates), and the gap."""
    splits = list(summaries)
    lines = ["| method | figure | " + " | ".join(splits) + (" | gap (test − dev) |" if gap else " |"),
             "|---|---|" + "---|" * len(splits) + ("---|" if gap else "")]
    labels = {"detection_rate": "detection rate", "model_calls_per_s": "model calls/s",
              "distance_error_median_m": "distance error median (m)", "distance_error_p95_m":
              "distance error p95 (m)", "share_over_1m": "alarms with error > 1 m",
              "waypoint_reach_rate": "waypoints reached"}
    for name in CONFIGS:
        for key in GAP_FIGURES:
            cells = []
            for split in splits:
                figures = summaries[split].get(name)
                value = None if figures is None else figures.get(key)
                text = "–" if value is None else f"{value:.3f}"
                if figures is not None and f"{key}_ci95" in figures and value is not None:
                    low, high = figures[f"{key}_ci95"]
                    text += f" [{low:.2f}, {high:.2f}]"
                cells.append(text)
            if gap:
                g = gap.get(name, {}).get(key)
                cells.append("–" if g is None else f"{g:+.3f}")
            lines.append(f"| {name} | {labels[key]} | " + " | ".join(cells) + " |")
    return lines


def print_runs(scores: list[RunScore]) -> None:
    """One line per run."""
    for score in scores:
        median, p95, over = stats(score.errors)
        label = score.scenario
        if score.split == "dev" and score.scenario == "C/D":
            label = {"seed_05": "C", "seed_02": "D"}.get(score.config, "C/D")
        print(f"{score.split:4} seed {score.seed:2} {label:18} {score.config:8} encounters "
              f"{score.encounters:3} detected {score.detection_rate:.3f}  calls/s {score.calls_per_s:.2f}  "
              f"error median "
              f"{fmt(median)} p95 {fmt(p95)} >1m {over:3} (alarms {len(score.errors)}, no distance "
              f"{score.no_distance}, overlapping {score.overlapping}, through robot "
              f"{score.through_robot})  waypoints reached {score.reached} skipped {score.skipped}  "
              f"[{score.sim_seconds:.0f} s simulated, {score.wall_seconds:.1f} s wall]", flush=True)


def print_summary(split: str, scores: list[RunScore], summary: dict[str, Any]) -> None:
    """A split's figures per method (intervals on test), by bearing, and ours against the thesis's."""
    for name, f in summary.items():
        def ci(key: str, f: dict[str, Any] = f) -> str:
            return f" [{f[key + '_ci95'][0]:.2f}, {f[key + '_ci95'][1]:.2f}]" if split == "test" else ""

        median, p95 = (math.nan if v is None else v for v in (f["distance_error_median_m"],
                                                              f["distance_error_p95_m"]))
        print(f"{split:4} {name:8} detection {fmt(f['detection_rate'] or math.nan)}{ci('detection_rate')} "
              f"(n={f['encounters']})  calls/s {f['model_calls_per_s']:.2f}  error median "
              f"{fmt(median)} p95 {fmt(p95)}"
              f"  >1m {f['errors_over_1m']}/{f['alarms']}{ci('share_over_1m')}  waypoints reached "
              f"{f['waypoints_reached']} skipped {f['waypoints_skipped']}{ci('waypoint_reach_rate')}  "
              f"({f['runs']} runs, {f['worlds']} worlds)")
        print("          by bearing (deg): " + "  ".join(
            f"{k}: n={v['n']} med={v['median_m']} p95={v['p95_m']}" for k, v in f["by_bearing_deg"].items()))
    keys = sorted({(s.seed, s.scenario) for s in scores})
    for reference in ("seed_05", "seed_02"):
        ratios_err, ratios_det = [], []
        for seed, scenario in keys:
            by_config = {s.config: s for s in scores if (s.seed, s.scenario) == (seed, scenario)}
            ours, ref = by_config.get("ours"), by_config.get(reference)
            if ours is None or ref is None:
                continue
            m_ours, m_ref = stats(ours.errors)[0], stats(ref.errors)[0]
            if m_ours > 0 and math.isfinite(m_ref):
                ratios_err.append(m_ref / m_ours)
            if ref.detection_rate > 0:
                ratios_det.append(ours.detection_rate / ref.detection_rate)
        for label, ratios in (("median error, reference/ours", ratios_err),
                              ("detection, ours/reference", ratios_det)):
            if ratios:
                print(f"{split:4} ratio {label} vs {reference}: min {min(ratios):.2f} "
                      f"median {float(np.median(ratios)):.2f} max {max(ratios):.2f} "
                      f"over {len(ratios)} runs")


def dev_runs(seeds: tuple[int, ...], out: Path) -> list[Run]:
    """The dev split: the thesis's scenarios on the shipped worlds, walkers across every leg."""
    runs: list[Run] = []
    for i, (seed, scenario, world, route, laps) in enumerate(
            (seed, *scenario) for seed in seeds for scenario in SCENARIOS):
        world_path = crossing_world(world, route, out, random.Random(f"{seed}:{scenario}"))
        order = list(CONFIGS) if i % 2 == 0 else list(reversed(CONFIGS))  # alternate the order
        runs.extend(Run("dev", scenario, world_path, route, laps, name, seed) for name in order)
    return runs


def test_runs(count: int, first_seed: int, out: Path) -> tuple[list[Run], list[HeldOutWorld]]:
    """The test split: held-out worlds with routes from the robot's map and walkers through them."""
    worlds = []
    for world in split_worlds("test", count, first_seed=first_seed, people=True):
        held = held_out_world(world, out, random.Random(f"{TEST_SEED}:{world.name}"))
        if held is None:
            print(f"  note: test {world.name}: its map gives no reachable waypoint; left out",
                  file=sys.stderr)
            continue
        worlds.append(held)
    runs: list[Run] = []
    for i, held in enumerate(worlds):
        order = list(CONFIGS) if i % 2 == 0 else list(reversed(CONFIGS))
        runs.extend(Run("test", held.name, held.world, str(held.route), held.laps, name, TEST_SEED,
                        held.timeout) for name in order)
    return runs, worlds


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--split", choices=("dev", "test", "both"), default="both",
                        help="dev: the thesis's scenarios (tune here); test: held-out worlds (report only)")
    parser.add_argument("--detector", choices=("shipped", "oracle"), default="shipped",
                        help="the shipped trained detector, or the simulation oracle (a perfect detector)")
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 1,
                        help="runs in parallel (batch runner's process pool; default: the cores)")
    parser.add_argument("--test-worlds", type=int, default=None,
                        help=f"held-out worlds in the test split (default {TEST_WORLDS}, 3 with --quick)")
    parser.add_argument("--first-seed", type=int, default=0, help="first seed of the test split's worlds")
    parser.add_argument("--quick", action="store_true",
                        help=f"a smoke run: dev seed {SEEDS[0]} only, 3 test worlds unless --test-worlds")
    parser.add_argument("--configs", default=",".join(CONFIGS),
                        help=f"comma-separated configurations to run (default all: {', '.join(CONFIGS)})")
    args = parser.parse_args()
    chosen = [c.strip() for c in args.configs.split(",") if c.strip()]
    unknown = sorted(set(chosen) - set(CONFIGS))
    if unknown or not chosen:
        parser.error(f"unknown configuration(s) {unknown}; known: {', '.join(CONFIGS)}")
    for name in list(CONFIGS):  # the runs, summaries and tables below read CONFIGS
        if name not in chosen:
            del CONFIGS[name]
    seeds = SEEDS[:1] if args.quick else SEEDS
    splits = ["dev", "test"] if args.split == "both" else [args.split]
    started = time.perf_counter()
    models, note = choose_models(args.detector == "oracle")
    held: list[HeldOutWorld] = []
    with tempfile.TemporaryDirectory(prefix="patrol_eval_") as tmp_name:
        tmp = Path(tmp_name)
        runs = dev_runs(seeds, tmp) if "dev" in splits else []
        if "test" in splits:
            count = args.test_worlds if args.test_worlds is not None else (3 if args.quick else TEST_WORLDS)
            test, held = test_runs(count, args.first_seed, tmp)
            runs += test
        for h in held:
            print(f"test world {h.name} ({h.family}): {h.waypoints} waypoints from its map, "
                  f"{h.length:.0f} m to the last, {h.laps} lap(s), {h.walkers} people, waypoint timeout "
                  f"{h.timeout:g} s")
        scores = run_all(runs, models, max(1, args.jobs), tmp)
    print_runs(scores)
    print(f"detector: {note}")
    summaries = {split: summarise([s for s in scores if s.split == split]) for split in splits}
    for split in splits:
        print_summary(split, [s for s in scores if s.split == split], summaries[split])
    gap = gaps(summaries["dev"], summaries["test"]) if len(splits) == 2 else {}
    for name, figures in gap.items():
        print(f"gap (test − dev) {name:8} " + "  ".join(
            f"{k} {'–' if v is None else f'{v:+.3f}'}" for k, v in figures.items()))
    print()
    print("\n".join(markdown_table(summaries, gap)))
    print()
    result: dict[str, Any] = dict(summaries)
    if gap:
        result["gap"] = gap
    if held:
        result["test_worlds"] = [{"name": h.name, "family": h.family, "waypoints": h.waypoints,
                                  "route_m": round(h.length, 1), "laps": h.laps, "people": h.walkers}
                                 for h in held]
    result["detector"] = note
    result["wall_seconds"] = round(time.perf_counter() - started, 1)
    print(json.dumps(result, sort_keys=True))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
