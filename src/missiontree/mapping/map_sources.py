"""Any map source this project reads, loaded as one OccupancyGrid: the formats ``map convert`` knows.

- ``.gridmap`` / ``.gridmap.gz``: an MRPT occupancy grid (:mod:`missiontree.mapping.mrpt_grid`);
- ``.rawlog``: an MRPT rawlog of 2-D scans and odometry (:mod:`missiontree.mapping.rawlog`), mapped
  with the log-odds grid at the odometry poses corrected by scan matching
  (:mod:`missiontree.mapping.scan_matching`, the ``realdata`` extra), or at the raw odometry poses
  when asked;
- ``.simplemap`` / ``.simplemap.gz``: an MRPT simple map (key frames of 2-D scans at the poses
  MRPT's SLAM gave them), mapped with the log-odds grid at those poses;
- ``.yaml``: a map_server map (:mod:`missiontree.mapping.mapfile`).

What kind a file is comes from its name; a file that does not read as that kind is a
:class:`MapSourceError` naming it and what went wrong.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from missiontree.mapping.mapfile import MapFileError, read_map
from missiontree.mapping.mrpt_archive import ArchiveError
from missiontree.mapping.mrpt_grid import GridmapError, read_gridmap
from missiontree.mapping.rawlog import read_rawlog, read_simplemap
from missiontree.mapping.recorded_map import build_grid
from missiontree.types import OccupancyGrid

#: File name endings read, and what each is.
KINDS = {".gridmap": "MRPT gridmap", ".gridmap.gz": "MRPT gridmap", ".rawlog": "MRPT rawlog",
         ".simplemap": "MRPT simplemap", ".simplemap.gz": "MRPT simplemap",
         ".yaml": "map_server map", ".yml": "map_server map"}


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
                    max_range: float = 15.0) -> LoadedMap:
    """Read any known map source into an OccupancyGrid.

    Args:
        path: The file.
        correct: For a rawlog, correct the odometry by scan matching (needs the ``realdata`` extra).
        resolution: For a rawlog, the grid's cell size (m).
        max_range: For a rawlog, returns beyond this free space and draw no wall (m).

    Raises:
        MapSourceError: The file is of no known kind or does not read as its kind.
        BackendUnavailableError: A rawlog is to be corrected and KISS-ICP is not installed.
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
        return _from_rawlog(path, correct, resolution, max_range)
    except (GridmapError, ArchiveError, MapFileError) as exc:
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
