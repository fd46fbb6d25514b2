"""Mapping on a real robot's laser scans: MRPT's faculty loop, raw odometry against scan matching.

Reads MRPT's ``2006-01ENE-21-SENA_Telecom Faculty_one_loop_only.rawlog`` (Debian's ``mrpt-common``:
225 SICK scans of 361 beams over 180°, with wheel odometry, a 76 m loop through a faculty hall),
corrects the odometry by scan-to-map matching (KISS-ICP, the ``realdata`` extra), then a pose
graph with loop closures (:mod:`missiontree.mapping.pose_graph`), then the same graph with every
overlapping scan pair registered directly (``refine_poses``), and prints raw odometry, the
scan-to-map poses, the pose graph's and the refined ones side by side:

- ``loop_gap_m`` (median and max) and ``loop_rot_deg``: where the robot comes back beside its
  start, the pose of each later scan relative to an early one along the trajectory, against the
  same relative pose measured by registering the later scan on ten early scans directly (pairs with
  at least 40 % of points agreeing within 0.2 m); the gap is the distance between the two. The
  pairs are picked, and their registration seeded, by the pose graph's trajectory; ``*_b`` are the
  same figures on the pairs picked and seeded by the scan-to-map trajectory instead (along a
  corridor the registration can settle in either of two places, so the seed matters);
- ``thin_share_grid``: share of the log-odds map's occupied cells on walls at most 2 cells (10 cm)
  thick (the map as the robot would use it; beams through a doubled wall erase one copy, so a
  drifted map has fewer wall cells rather than thicker walls: ``wall_cells`` says how many);
- ``thin_share_endpoints``: the same share on the image of every return's end cell (no clearing),
  where drift draws one wall two or three times side by side;
- ``second_pass_within_10cm``: of the second half's returns that fall within 1 m of a first-half
  return (places seen twice), the share within 0.1 m of one: a doubled wall lowers it, a wall
  laid on itself raises it (``second_pass_returns``: how many were counted);
- ``vs_mrpt_map_*``: how far the trajectory is from MRPT's own map of the same loop
  (``malaga-cs-fac-building.simplemap.gz``: 99 of these scans, identical, at the poses MRPT's SLAM
  gave them), both taken relative to its first key frame. A reference, not ground truth: MRPT's
  map is another estimate. ``*_keyframes``: the every-return wall figures on those 99 scans alone,
  printed for MRPT's map as well;
- ``frontiers`` and ``rooms``: what the project's frontier finder and room segmentation make of the
  log-odds map (they run on it; the faculty hall is one open space around a central block).

This is one recording, not a dev/test split: nothing here was tuned per world, and the settings
are :class:`~missiontree.mapping.scan_matching.MatchSettings`' defaults. The last line is one JSON object.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import time
from pathlib import Path

from missiontree.errors import BackendUnavailableError
from missiontree.mapping.frontiers import find_frontiers
from missiontree.mapping.mrpt_datasets import find_dataset
from missiontree.mapping.rawlog import read_rawlog, read_simplemap
from missiontree.mapping.recorded_map import (
    build_grid,
    endpoint_grid,
    loop_gap,
    loop_pairs,
    pass_agreement,
    wall_thickness,
)
from missiontree.mapping.scan_matching import correct_poses, relative
from missiontree.semantics.rooms import segment_rooms

LOOP = find_dataset(LOOP_NAME := "2006-01ENE-21-SENA_Telecom Faculty_one_loop_only.rawlog") or Path(LOOP_NAME)
#: MRPT's own map of the same loop (99 of its scans at the poses MRPT's SLAM gave them).
MRPT_MAP = find_dataset("malaga-cs-fac-building.simplemap.gz") or Path("malaga-cs-fac-building.simplemap.gz")


def against_mrpt_map(log, poses) -> dict[str, float]:  # noqa: ANN001 - a ScanLog and its poses
    """Position and heading differences from MRPT's own map of the loop, in its first key frame's frame."""
    if not MRPT_MAP.is_file():
        return {}
    reference = read_simplemap(MRPT_MAP)
    index = {round(s.stamp, 4): i for i, s in enumerate(log.scans)}
    matched = [(index[round(s.stamp, 4)], p) for s, p in zip(reference.scans, reference.poses, strict=True)
               if round(s.stamp, 4) in index]
    if not matched:
        return {}
    first, origin = matched[0]
    dist, turn = [], []
    for i, ref in matched:
        ours, theirs = relative(poses[first], poses[i]), relative(origin, ref)
        dist.append(math.hypot(ours.x - theirs.x, ours.y - theirs.y))
        turn.append(abs(math.atan2(math.sin(ours.yaw - theirs.yaw), math.cos(ours.yaw - theirs.yaw))))
    keyframes = wall_thickness(endpoint_grid([log.scans[i] for i, _ in matched],
                                             [poses[i] for i, _ in matched]))
    return {"vs_mrpt_map_m_median": round(statistics.median(dist), 3),
            "vs_mrpt_map_m_max": round(max(dist), 3),
            "vs_mrpt_map_deg_median": round(math.degrees(statistics.median(turn)), 2),
            "thin_share_endpoints_keyframes": round(keyframes.thin_share, 4),
            "cells_endpoints_keyframes": keyframes.cells}


def mrpt_map_itself() -> dict[str, float]:
    """The every-return wall figures of MRPT's own map (its key frames at its poses), for comparison."""
    if not MRPT_MAP.is_file():
        return {}
    reference = read_simplemap(MRPT_MAP)
    walls = wall_thickness(endpoint_grid(reference.scans, reference.poses))
    return {"thin_share_endpoints_keyframes": round(walls.thin_share, 4),
            "cells_endpoints_keyframes": walls.cells}


def figures(log, poses, pairs, other_pairs) -> dict[str, float]:  # noqa: ANN001 - ScanLog, poses, pairs
    gaps = [loop_gap(log.scans, poses, s, e, (pose, fit)) for s, e, pose, fit in pairs]
    other = [loop_gap(log.scans, poses, s, e, (pose, fit)).translation for s, e, pose, fit in other_pairs]
    occupancy = build_grid(log.scans, poses).to_occupancy()
    grid = wall_thickness(occupancy)
    ends = wall_thickness(endpoint_grid(log.scans, poses))
    rooms = segment_rooms(occupancy, inside=(poses[0].x, poses[0].y))
    agree, counted = pass_agreement(log.scans, poses)
    return {
        "loop_gap_m_median": round(statistics.median(g.translation for g in gaps), 3) if gaps else math.nan,
        "loop_gap_m_max": round(max(g.translation for g in gaps), 3) if gaps else math.nan,
        "loop_rot_deg_median": round(math.degrees(statistics.median(g.rotation for g in gaps)), 2)
        if gaps else math.nan,
        "loop_gap_m_median_b": round(statistics.median(other), 3) if other else math.nan,
        "loop_gap_m_max_b": round(max(other), 3) if other else math.nan,
        "loop_pairs_over_30cm_b": sum(g > 0.3 for g in other),
        "thin_share_grid": round(grid.thin_share, 4),
        "wall_cells": grid.cells,
        "thin_share_endpoints": round(ends.thin_share, 4),
        "cells_endpoints": ends.cells,
        "p90_thickness_endpoints": ends.p90,
        "second_pass_within_10cm": round(agree, 4),
        "second_pass_returns": counted,
        "frontiers": len(find_frontiers(occupancy)),
        "rooms": len(rooms.rooms),
        **against_mrpt_map(log, poses),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rawlog", type=Path, default=LOOP,
                        help="an MRPT rawlog with 2-D scans and odometry")
    args = parser.parse_args(argv)
    if not args.rawlog.exists():
        print(f"{args.rawlog}: missing (install Debian's mrpt-common: make setup-mrpt)", file=sys.stderr)
        return 2
    log = read_rawlog(args.rawlog)
    cpu = time.process_time()
    try:
        corrected = correct_poses(log.scans, log.poses)
    except BackendUnavailableError as exc:
        print(exc, file=sys.stderr)
        return 2
    match_cpu = time.process_time() - cpu
    pairs = loop_pairs(log.scans, log.poses, corrected.poses)
    pairs_b = loop_pairs(log.scans, log.poses, corrected.front_end)
    raw, front = figures(log, log.poses, pairs, pairs_b), figures(log, corrected.front_end, pairs, pairs_b)
    graph = figures(log, corrected.graph or corrected.poses, pairs, pairs_b)
    fixed = figures(log, corrected.poses, pairs, pairs_b)
    print(f"{args.rawlog.name}: {len(log.scans)} scans, odometry path {log.path_length():.1f} m, "
          f"matching {match_cpu:.1f} s CPU, {len(corrected.refused)} matches refused, "
          f"{len(corrected.closures)} loop closures in the pose graph, "
          f"{len(pairs)} loop pairs (overlap median {statistics.median(p[3] for p in pairs):.2f}), "
          f"{len(pairs_b)} pairs b")
    head = ("figure", "raw odometry", "scan-to-map", "+ pose graph", "+ refined")
    print(f"{head[0]:32s} " + " ".join(f"{h:>14s}" for h in head[1:]))
    for key in raw:
        print(f"{key:32s} {raw[key]!s:>14s} {front[key]!s:>14s} {graph[key]!s:>14s} {fixed[key]!s:>14s}")
    mrpt = mrpt_map_itself() if args.rawlog.resolve() == LOOP.resolve() else {}  # MRPT's map is of this loop
    if mrpt:
        print(f"MRPT's own map of the loop (its {MRPT_MAP.name}, same scans at its SLAM poses): "
              f"thin_share_endpoints_keyframes {mrpt['thin_share_endpoints_keyframes']}, "
              f"cells_endpoints_keyframes {mrpt['cells_endpoints_keyframes']}")
    print(json.dumps({"scans": len(log.scans), "loop_pairs": len(pairs), "loop_pairs_b": len(pairs_b),
                      "match_cpu_s": round(match_cpu, 2),
                      "closures": len(corrected.closures), "raw": raw, "scan_to_map": front,
                      "pose_graph": graph, "corrected": fixed, "mrpt_map": mrpt}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
