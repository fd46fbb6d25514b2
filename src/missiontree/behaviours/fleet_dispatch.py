"""The fleet patrol's dispatcher: the route cut into one contiguous stretch per robot, re-cut on a loss.

One :class:`PatrolDispatcher` per fleet (``context.fleet.shared``), asked by every robot's
:class:`~missiontree.behaviours.fleet_patrol.FleetPatrol` leaf for its next waypoint.

**Partition.** The route's distinct waypoints, in tour order, are cut into as many contiguous
stretches as there are live robots. Every rotation of the tour is tried; for each, waypoint ``i``
goes to stretch ``floor(k * d_i / L)`` (``d_i`` its distance along the tour, ``L`` the tour's
length), and the rotation whose longest stretch *loop* (the stretch driven out and closed back to its
first waypoint) is shortest wins. Distances are straight lines between waypoints, not planned
paths. Stretches go to robots by the assignment with the smallest sum of distances from each
robot's pose estimate to its stretch's nearest waypoint (all permutations up to 7 robots, greedy
beyond). A robot starts at its stretch's waypoint nearest to it and loops the stretch in tour order.

**Loss.** A lost robot's stretch is not left unwatched: the whole route is cut again among the
robots still live (from where they are now), and waypoints a finite patrol still owes visits go to
their new owners. ``fleet_rebalanced`` says who has what.

**Alarm dispatch** (the patrol-robot thesis §5.3.4). An alarm a robot raises with a position is
handed to the nearest free robot other than the one that raised it (straight-line distance from
its pose estimate; free: live and not already answering an alarm); that robot leaves its stretch,
drives to look and comes back (``alarm_dispatched``, ``alarm_looked``). An alarm within
``SAME_ALARM`` m of one being answered, or answered in the last ``ALARM_MEMORY`` s, is the same
person: nobody more is sent (the robot that went to look raises its own alarm on arriving).

**Done.** With ``laps`` > 0 the fleet is done when every waypoint has had ``laps`` visits (by any
robot) or was skipped as unreachable by the robot it was given to; ``laps: 0`` patrols until stopped.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from typing import Any

from missiontree.behaviours.waypoints import Waypoint
from missiontree.types import Pose2D

#: Up to this many robots every assignment of stretches to robots is tried; beyond, greedily.
EXACT_ASSIGNMENT = 7
#: An alarm this close (m) to one being answered, or answered recently, is taken for the same person.
SAME_ALARM = 2.0
#: How long (s) an answered alarm's spot is remembered: the robot sent there sees the person and
#: raises its own alarm, which must not send another robot back (a ping-pong between robots).
ALARM_MEMORY = 60.0

__all__ = ["EXACT_ASSIGNMENT", "PatrolDispatcher", "distinct_waypoints", "partition_tour"]


def distinct_waypoints(route: list[Waypoint]) -> list[Waypoint]:
    """The route's waypoints once each, in the order they first appear (a loop out and back counts once)."""
    seen: set[str] = set()
    found: list[Waypoint] = []
    for waypoint in route:
        if waypoint.name not in seen:
            seen.add(waypoint.name)
            found.append(waypoint)
    return found


def _dist(a: Pose2D, b: Pose2D) -> float:
    return math.hypot(a.x - b.x, a.y - b.y)


def _loop_length(points: list[Pose2D]) -> float:
    """A stretch driven in order and closed back to its first point."""
    if len(points) < 2:
        return 0.0
    return sum(_dist(points[i], points[(i + 1) % len(points)]) for i in range(len(points)))


def partition_tour(points: list[Pose2D], count: int) -> list[list[int]]:
    """Cut the closed tour ``points`` into ``count`` contiguous stretches of indices (see module doc).

    Stretches may be empty when there are fewer points than robots.
    """
    n = len(points)
    if count <= 1 or n <= 1:
        return [list(range(n))] + [[] for _ in range(max(0, count - 1))]
    legs = [_dist(points[i], points[(i + 1) % n]) for i in range(n)]
    total = sum(legs) or 1.0
    best: list[list[int]] | None = None
    best_cost = math.inf
    for start in range(n):
        stretches: list[list[int]] = [[] for _ in range(count)]
        along = 0.0
        for step in range(n):
            i = (start + step) % n
            stretches[min(count - 1, int(count * along / total))].append(i)
            along += legs[i]
        if any(not s for s in stretches) and n >= count:
            stretches = _even_split([(start + s) % n for s in range(n)], count)
        cost = max(_loop_length([points[i] for i in s]) for s in stretches)
        if cost < best_cost - 1e-9:
            best, best_cost = stretches, cost
    assert best is not None
    return best


def _even_split(order: list[int], count: int) -> list[list[int]]:
    """``order`` cut into ``count`` runs of (nearly) equal size."""
    size, extra = divmod(len(order), count)
    runs, at = [], 0
    for k in range(count):
        take = size + (1 if k < extra else 0)
        runs.append(order[at:at + take])
        at += take
    return runs


def assign_stretches(stretches: list[list[int]], points: list[Pose2D],
                     poses: list[Pose2D | None]) -> list[int]:
    """For each robot (by position in ``poses``), the stretch it gets: the smallest summed approach."""
    def approach(robot: int, stretch: int) -> float:
        pose = poses[robot]
        if pose is None or not stretches[stretch]:
            return 0.0
        return min(_dist(pose, points[i]) for i in stretches[stretch])

    count = len(poses)
    if count <= EXACT_ASSIGNMENT:
        best = min(itertools.permutations(range(count)),
                   key=lambda perm: sum(approach(r, perm[r]) for r in range(count)))
        return list(best)
    free, chosen = set(range(count)), []
    for robot in range(count):
        pick = min(sorted(free), key=lambda s: approach(robot, s))
        chosen.append(pick)
        free.discard(pick)
    return chosen


class PatrolDispatcher:
    """Who patrols which waypoints; counts visits; re-cuts the route when a robot is lost.

    Args:
        route: The patrol route (repeats allowed; each distinct waypoint is patrolled).
        laps: Visits each waypoint is owed (0: patrol until stopped).
        names: The fleet's robots.
        emit: Where the dispatcher's events go (``fleet_assigned``, ``fleet_rebalanced``).
        clock: The fleet's clock.
    """

    def __init__(self, route: list[Waypoint], laps: int, names: list[str],
                 emit: Callable[..., None], clock: Callable[[], float]) -> None:
        self.waypoints = distinct_waypoints(route)
        self.laps = laps
        self.names = list(names)
        self.emit = emit
        self.clock = clock
        self.live = list(names)
        self.poses: dict[str, Pose2D] = {}
        self.assignment: dict[str, list[int]] = {}
        self.cursor: dict[str, int] = {}
        self.visits = [0] * len(self.waypoints)
        self.skipped: dict[int, str] = {}
        self.rebalances: list[dict[str, Any]] = []
        #: Alarms being answered: robot -> {"x", "y", "alarm", "raised_by", "t"}.
        self.responses: dict[str, dict[str, Any]] = {}
        self.dispatched: list[dict[str, Any]] = []
        #: Spots of alarms answered lately: (x, y, when answered).
        self.answered: list[tuple[float, float, float]] = []

    @property
    def started(self) -> bool:
        """Whether the route has been cut (every live robot has reported its pose)."""
        return bool(self.assignment)

    def join(self, name: str, pose: Pose2D | None) -> None:
        """Note robot ``name``'s pose estimate; cut the route once every live robot has reported."""
        if pose is not None:
            self.poses[name] = pose
        if not self.started and all(n in self.poses for n in self.live):
            self._cut("fleet_assigned", lost="")

    def _cut(self, event: str, lost: str) -> None:
        points = [w.pose for w in self.waypoints]
        stretches = partition_tour(points, len(self.live))
        poses = [self.poses.get(n) for n in self.live]
        chosen = assign_stretches(stretches, points, poses)
        self.assignment = {}
        for robot, name in enumerate(self.live):
            stretch = stretches[chosen[robot]]
            self.assignment[name] = stretch
            pose = poses[robot]
            if stretch and pose is not None:
                nearest = min(range(len(stretch)), key=lambda j: _dist(pose, points[stretch[j]]))
            else:
                nearest = 0
            self.cursor[name] = nearest
        shown = {n: [self.waypoints[i].name for i in s] for n, s in self.assignment.items()}
        fields: dict[str, Any] = {"assignment": shown, "live": list(self.live)}
        if lost:
            fields["lost"] = lost
            self.rebalances.append({"t": self.clock(), "lost": lost, "assignment": shown})
        self.emit(event, **fields)

    def next_for(self, name: str) -> int | None:
        """The index (into :attr:`waypoints`) robot ``name`` should drive to next; None when it has none."""
        stretch = self.assignment.get(name) or []
        if name not in self.live or not stretch:
            return None
        start = self.cursor.get(name, 0) % len(stretch)
        for step in range(len(stretch)):
            index = stretch[(start + step) % len(stretch)]
            if self._owed(index):
                self.cursor[name] = (start + step) % len(stretch)
                return index
        return None

    def _owed(self, index: int) -> bool:
        if index in self.skipped:
            return False
        return self.laps == 0 or self.visits[index] < self.laps

    def visited(self, name: str, index: int) -> None:
        """Robot ``name`` reached waypoint ``index``: count it and move its place on."""
        self.visits[index] += 1
        self.skipped.pop(index, None)
        self._advance(name)

    def skip(self, name: str, index: int, reason: str) -> None:
        """Robot ``name`` could not reach waypoint ``index``: no visit is owed to it any more."""
        self.skipped[index] = reason
        self._advance(name)

    def _advance(self, name: str) -> None:
        stretch = self.assignment.get(name) or []
        if stretch:
            self.cursor[name] = (self.cursor.get(name, 0) + 1) % len(stretch)

    def lose(self, name: str, reason: str) -> bool:
        """Robot ``name`` is lost: cut the route again among the others. Whether anyone took the work."""
        if name not in self.live:
            return bool(self.live)
        self.live.remove(name)
        self.responded(name, "lost")
        if not self.live:
            return False
        if self.started:
            self._cut("fleet_rebalanced", lost=name)
        return True

    def alarm(self, raised_by: str, x: float, y: float, alarm_id: Any) -> str | None:
        """An alarm at (x, y) raised by ``raised_by``: the robot sent to look, or None.

        None when it is the person an answer is already on its way to, or no other robot is free.
        """
        now = self.clock()
        self.answered = [a for a in self.answered if now - a[2] <= ALARM_MEMORY]
        near = [(t["x"], t["y"]) for t in self.responses.values()] + [(a[0], a[1]) for a in self.answered]
        if any(math.hypot(px - x, py - y) < SAME_ALARM for px, py in near):
            return None
        free = [n for n in self.live if n != raised_by and n not in self.responses and n in self.poses]
        if not free:
            return None
        chosen = min(free, key=lambda n: (math.hypot(self.poses[n].x - x, self.poses[n].y - y), n))
        distance = math.hypot(self.poses[chosen].x - x, self.poses[chosen].y - y)
        task = {"x": x, "y": y, "alarm": alarm_id, "raised_by": raised_by, "t": self.clock()}
        self.responses[chosen] = task
        self.dispatched.append({**task, "robot": chosen, "distance_m": round(distance, 2)})
        self.emit("alarm_dispatched", robot=chosen, raised_by=raised_by, alarm=alarm_id, x=x, y=y,
                  distance_m=round(distance, 2))
        return chosen

    def response_for(self, name: str) -> dict[str, Any] | None:
        """The alarm robot ``name`` has been sent to look at, if any."""
        return self.responses.get(name)

    def responded(self, name: str, outcome: str) -> None:
        """Robot ``name`` is done looking (``outcome``: reached, unreachable, timeout, lost)."""
        task = self.responses.pop(name, None)
        if task is not None:
            self.answered.append((task["x"], task["y"], self.clock()))
            for entry in reversed(self.dispatched):
                if entry["robot"] == name and "outcome" not in entry:
                    entry["outcome"] = outcome
                    entry["answered_s"] = round(self.clock() - task["t"], 2)
                    break

    def done(self) -> bool:
        """Whether a finite patrol owes no waypoint a visit (never for ``laps: 0``)."""
        if self.laps == 0:
            return False
        return self.started and not any(self._owed(i) for i in range(len(self.waypoints)))

    def report(self) -> dict[str, Any]:
        """The summary's view: assignment, visits and skips per waypoint, the re-cuts."""
        return {
            "assignment": {n: [self.waypoints[i].name for i in s] for n, s in self.assignment.items()},
            "visits": {w.name: self.visits[i] for i, w in enumerate(self.waypoints)},
            "skipped": {self.waypoints[i].name: r for i, r in sorted(self.skipped.items())},
            "rebalances": list(self.rebalances), "live": list(self.live), "laps": self.laps,
            "alarms_dispatched": list(self.dispatched),
        }
