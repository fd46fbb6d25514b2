"""Any map source this project reads, loaded as one OccupancyGrid: the formats ``map convert`` knows.

- ``.gridmap`` / ``.gridmap.gz``: an MRPT occupancy grid (:mod:`missiontree.mapping.mrpt_grid`);
- ``.rawlog``: an MRPT rawlog of 2-D scans and odometry (:mod:`missiontree.mapping.rawlog`), mapped
  with the log-odds grid at the odometry poses corrected by scan matching
  (:mod:`missiontree.mapping.scan_matching`, the ``realdata`` extra), or at the raw odometry poses
  when asked;
- ``.simplemap`` / ``.simplemap.gz``: an MRPT simple map (key frames of 2-D scans at the poses
  MRPT's SLAM gave them), mapped with the log-odds grid at those poses;
- ``.yaml``: a map_server map (:mod:`missiontree.mapping.mapfile`);
- ``.mcap``: a ROS 2 bag (:mod:`missiontree.mapping.ros2bag`, the ``realdata`` extra): its laser
  scans laid into the log-odds grid at the poses the bag's ``/tf`` (or ``/odom``) gives at each
  scan's stamp, with the lidar's mount from ``/tf_static``; the bag's own ``/map`` is not used
  (``map convert`` of a bag is the map of its scans).

What kind a file is comes from its name; a file that does not read as that kind is a
:class:`MapSourceError` naming it and what went wrong.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from missiontree.mapping.grid import LogOddsGrid
from missiontree.mapping.mapfile import MapFileError, read_map
from missiontree.mapping.mrpt_archive import ArchiveError
from missiontree.mapping.mrpt_grid import GridmapError, read_gridmap
from missiontree.mapping.rawlog import read_rawlog, read_simplemap
from missiontree.mapping.recorded_map import build_grid
from missiontree.mapping.ros2bag import BagError, BagTopics, read_bag
from missiontree.types import OccupancyGrid

#: File name endings read, and what each is.
KINDS = {".gridmap": "MRPT gridmap", ".gridmap.gz": "MRPT gridmap", ".rawlog": "MRPT rawlog",
         ".simplemap": "MRPT simplemap", ".simplemap.gz": "MRPT simplemap",
         ".yaml": "map_server map", ".yml": "map_server map", ".mcap": "ROS 2 bag"}


class MapSourceError(ValueError):
    """A map source that cannot be read: the message names the file, what was expected and found."""


@dataclass(frozen=True)
class LoadedMap:
    """A map read from a source, with a line saying how it was made."""

    grid: OccupancyGrid
    how: str


def kind_of(path: Path) -> str:
    """The kind of map file ``path`` is, from its name; MapSourceError listing the known endings."""
    name = path.name.lower()
    for ending, kind in sorted(KINDS.items(), key=lambda item: -len(item[0])):
        if name.endswith(ending):
            return kind
    raise MapSourceError(f"{path}: expected a map file ending in {', '.join(KINDS)}, found {path.name!r}")


def load_map_source(path: str | Path, *, correct: bool = True, resolution: float = 0.05,
                    max_range: float = 15.0, namespace: str = "") -> LoadedMap:
    """Read any known map source into an OccupancyGrid.

    Args:
        path: The file.
        correct: For a rawlog, correct the odometry by scan matching (needs the ``realdata`` extra).
        resolution: For a rawlog, the grid's cell size (m).
        max_range: For a rawlog or a bag, returns beyond this free space and draw no wall (m).
        namespace: For a bag, the robot's namespace (``/robot1``: ``/robot1/scan``, ...).

    Raises:
        MapSourceError: The file is of no known kind or does not read as its kind.
        BackendUnavailableError: A rawlog is to be corrected and KISS-ICP is not installed, or a
            bag is read and mcap-ros2-support is not.
    """
    path = Path(path)
    kind = kind_of(path)
    try:
        if kind == "MRPT gridmap":
            grid = read_gridmap(path)
            return LoadedMap(grid, f"MRPT gridmap, {grid.data.shape[1]} x {grid.data.shape[0]} cells")
        if kind == "map_server map":
            grid = read_map(path)
            return LoadedMap(grid, f"map_server map, {grid.data.shape[1]} x {grid.data.shape[0]} cells")
        if kind == "MRPT simplemap":
            log = read_simplemap(path)
            if not log.scans:
                raise MapSourceError(f"{path}: expected 2-D laser scans in the simple map, found none")
            grid = build_grid(log.scans, log.poses, resolution=resolution, max_range=max_range).to_occupancy()
            return LoadedMap(grid, f"MRPT simplemap, {len(log.scans)} scans at the map's own poses")
        if kind == "ROS 2 bag":
            return _from_bag(path, resolution, max_range, namespace)
        return _from_rawlog(path, correct, resolution, max_range)
    except (GridmapError, ArchiveError, MapFileError, BagError) as exc:
        raise MapSourceError(str(exc)) from None
    except FileNotFoundError as exc:
        raise MapSourceError(f"{path}: cannot read the {kind}: {exc.strerror}") from None


def _from_rawlog(path: Path, correct: bool, resolution: float, max_range: float) -> LoadedMap:
    log = read_rawlog(path)
    if not log.scans:
        raise MapSourceError(f"{path}: expected 2-D laser scans (CObservation2DRangeScan) in the rawlog, "
                             "found none")
    poses = log.poses
    how = f"MRPT rawlog, {len(log.scans)} scans at raw odometry poses"
    if correct:
        from missiontree.mapping.scan_matching import correct_poses  # KISS-ICP only when asked for

        result = correct_poses(log.scans, log.poses)
        poses = result.poses
        how = (f"MRPT rawlog, {len(log.scans)} scans at odometry poses corrected by scan matching "
               f"({len(result.refused)} matches refused)")
    grid = build_grid(log.scans, poses, resolution=resolution, max_range=max_range).to_occupancy()
    return LoadedMap(grid, how)


def _from_bag(path: Path, resolution: float, max_range: float, namespace: str) -> LoadedMap:
    """The log-odds map of a bag's scans at the bag's poses (scans outside the pose track are left out)."""
    names = BagTopics().namespaced(namespace) if namespace else BagTopics()
    bag = read_bag(path, names, frame_rate=1e-6)   # images are not needed: keep as few as the reader allows
    if not bag.scans:
        raise MapSourceError(f"{path}: expected laser scans on {names.scan}, found none; the bag's topics: "
                             f"{', '.join(sorted(bag.topics)) or 'none'}")
    grid = LogOddsGrid(resolution, 20.0, 20.0, max_range=max_range, sensor_offset=bag.lidar_offset)
    used = 0
    for scan in bag.scans:
        pose = bag.pose_at(scan.stamp)
        if pose is not None:
            grid.integrate(scan, pose)
            used += 1
    if not used:
        raise MapSourceError(f"{path}: no scan falls within the bag's pose track "
                             f"({bag.pose_source or 'no poses'} from {names.tf} or {names.odom})")
    return LoadedMap(grid.to_occupancy(), f"ROS 2 bag, {used} of {len(bag.scans)} scans at the poses of "
                     f"{bag.pose_source}")
