"""Worlds on MRPT's real occupancy grids: ``mrpt:uwb`` and ``mrpt:malaga`` (``mrpt:<name>:<seed>``).

Debian's ``mrpt-common`` package (BSD-3) ships the Mobile Robot Programming Toolkit's sample
datasets, among them two occupancy grids MRPT built from real laser scans:

- ``uwb``: ``uwb_ro-localization_demo_map.gridmap.gz``, 28 x 26 m at 4 cm, loaded whole;
- ``malaga-full``: ``2006-MalagaCampus.gridmap.gz`` whole, 151 x 219 m at 8 cm (1,888 x 2,738 =
  5.2 M cells, within the world loader's 6 M);
- ``malaga``: the same map cropped to a :data:`CROP_METRES` square (what the test split uses: a
  building-sized piece, so a benchmark world costs what the others do), chosen from the map alone by
  :func:`crop_window`: the window holding the most cells of the largest piece of floor a
  TurtleBot 4 can drive (free cells farther than its radius plus :data:`PASS_MARGIN` from anything
  not free), searched at a 1 m stride, the first such window in row-major order on a tie.

Every map is closed where its scans end: unknown cells beside free floor and free cells on the
outer edge become occupied (a one-cell wall), so no floor runs into space the scans never saw or off
the map (the simulator would otherwise let the robot drive and see through those unknown cells).
The grid is written as a map_server pair (``mrpt_<name>.yaml`` and ``.pgm``) into
a cache folder, and :func:`missiontree.backends.sim.placement.map_world` builds the world on it:
a seeded start, rooms found by segmentation and typed, objects and decoys placed, two walkers.

The datasets folder is the first of :func:`missiontree.mapping.mrpt_datasets.candidate_dirs`
that holds the maps (``$MISSIONTREE_MRPT_DATASETS``, apt's folder, or the package ``make setup-mrpt``
extracted); when none does, loading ends in a problem naming the apt package.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import cv2
import numpy as np
import yaml

from missiontree.backends.sim.placement import map_world
from missiontree.backends.sim.placer import PASS_MARGIN, ROBOT_RADIUS
from missiontree.backends.sim.world import register_world_source
from missiontree.errors import Problem, WorldFileError
from missiontree.mapping.clearance import clearance_metres
from missiontree.mapping.mapfile import write_map
from missiontree.mapping.mrpt_datasets import APT_PACKAGE as APT_PACKAGE
from missiontree.mapping.mrpt_datasets import DATASETS_ENV as DATASETS_ENV
from missiontree.mapping.mrpt_datasets import INSTALL_HINT as INSTALL_HINT
from missiontree.mapping.mrpt_datasets import SYSTEM_DIRS, candidate_dirs
from missiontree.mapping.mrpt_grid import GridmapError, read_gridmap
from missiontree.types import OccupancyGrid, Pose2D
from missiontree.yamlio import Located, parse_yaml

#: World names of this source start with this.
MRPT_PREFIX = "mrpt:"
#: Where Debian's (and a source build's) ``mrpt-common`` puts the datasets.
DATASET_DIRS = SYSTEM_DIRS
#: World name -> gridmap file in the datasets folder.
MAPS = {
    "uwb": "uwb_ro-localization_demo_map.gridmap.gz",
    "malaga": "2006-MalagaCampus.gridmap.gz",
    "malaga-full": "2006-MalagaCampus.gridmap.gz",
}
#: World names loaded whole, however large (within the world loader's ``MAX_MAP_CELLS``).
UNCROPPED = frozenset({"malaga-full"})
#: Side (m) of the square a larger map is cropped to: a building-sized piece, within the loader's limit.
CROP_METRES = 40.0
#: Stride (m) of the crop search.
CROP_STRIDE = 1.0
#: Environment variable for the cache folder of the converted maps (default: the user's cache).
CACHE_ENV = "MISSIONTREE_MRPT_CACHE"


def datasets_dir() -> Path:
    """The folder holding MRPT's datasets (see the module docstring).

    Raises:
        FileNotFoundError: No such folder holds the maps (the message names the apt package).
    """
    candidates = candidate_dirs()
    for folder in candidates:
        if any((folder / name).is_file() for name in MAPS.values()):
            return folder.resolve()
    looked = ", ".join(str(c) for c in candidates)
    raise FileNotFoundError(f"MRPT's datasets are not installed (looked in {looked}): {INSTALL_HINT}")


def mrpt_available() -> bool:
    """Whether every map of :data:`MAPS` is installed (then ``mrpt:<name>`` worlds load)."""
    try:
        folder = datasets_dir()
    except FileNotFoundError:
        return False
    return all((folder / name).is_file() for name in MAPS.values())


def gridmap_path(name: str) -> Path:
    """The installed gridmap file of a world name of :data:`MAPS`.

    Raises:
        KeyError: Not a name of :data:`MAPS`.
        FileNotFoundError: The datasets or the file are missing (names the apt package).
    """
    filename = MAPS[name]
    path = datasets_dir() / filename
    if not path.is_file():
        raise FileNotFoundError(f"{path} does not exist: {INSTALL_HINT}")
    return path


def crop_window(grid: OccupancyGrid, metres: float = CROP_METRES) -> tuple[int, int, int, int]:
    """The crop (row0, col0, rows, cols) of a map, chosen from the map alone.

    The whole map when it fits a ``metres`` square; else the ``metres`` square holding the most
    cells of the largest drivable piece of floor (see the module docstring).
    """
    rows, cols = grid.data.shape
    side = int(round(metres / grid.resolution))
    if rows <= side and cols <= side:
        return 0, 0, rows, cols
    free = (grid.data == 0).astype(np.uint8)
    dist = clearance_metres(free, grid.resolution)
    drivable = (dist > ROBOT_RADIUS + PASS_MARGIN).astype(np.uint8)
    count, labels = cv2.connectedComponents(drivable, connectivity=8)
    sizes = np.bincount(labels.ravel(), minlength=count)
    sizes[0] = 0
    piece = (labels == int(sizes.argmax())).astype(np.int64)
    integral = np.zeros((rows + 1, cols + 1), np.int64)
    integral[1:, 1:] = piece.cumsum(0).cumsum(1)
    h, w = min(side, rows), min(side, cols)
    step = max(1, int(round(CROP_STRIDE / grid.resolution)))
    r0 = np.arange(0, rows - h + 1, step)
    c0 = np.arange(0, cols - w + 1, step)
    rr, cc = np.meshgrid(r0, c0, indexing="ij")
    score = integral[rr + h, cc + w] - integral[rr, cc + w] - integral[rr + h, cc] + integral[rr, cc]
    best = np.unravel_index(int(np.argmax(score)), score.shape)  # first maximum, row-major
    return int(r0[best[0]]), int(c0[best[1]]), h, w


def world_grid(name: str) -> OccupancyGrid:
    """The grid a ``mrpt:<name>`` world is drawn on: the gridmap, cropped, closed where its scans end.

    Names in :data:`UNCROPPED` keep the whole map.

    Raises:
        KeyError, FileNotFoundError: As :func:`gridmap_path`.
        GridmapError: The file is malformed.
    """
    grid = read_gridmap(gridmap_path(name))
    rows, cols = grid.data.shape
    r0, c0, h, w = (0, 0, rows, cols) if name in UNCROPPED else crop_window(grid)
    data = grid.data[r0:r0 + h, c0:c0 + w].copy()
    # the simulator has no truth for what the scans never saw: unknown cells touching free floor, and
    # free cells on the edge, become wall, so the robot drives and looks only where the map is known
    near_free = cv2.dilate((data == 0).astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    data[near_free & (data == -1)] = 100
    edge = np.zeros(data.shape, bool)
    edge[0, :] = edge[-1, :] = edge[:, 0] = edge[:, -1] = True
    data[edge & (data == 0)] = 100
    res = grid.resolution
    origin = Pose2D(round(grid.origin.x + c0 * res, 4), round(grid.origin.y + r0 * res, 4), 0.0)
    return OccupancyGrid(grid.stamp, grid.resolution, origin, data)


def cache_dir() -> Path:
    """Where the converted map_server pairs are written.

    ``$MISSIONTREE_MRPT_CACHE``, else ``missiontree/mrpt`` in the user's cache folder
    (``$XDG_CACHE_HOME`` or ~/.cache), else (not writable) a folder in the temp folder.
    """
    override = os.environ.get(CACHE_ENV)
    if override:
        return Path(override)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    folder = Path(base) / "missiontree" / "mrpt"
    try:
        folder.mkdir(parents=True, exist_ok=True)
        return folder
    except OSError:
        return Path(tempfile.gettempdir()) / f"missiontree-mrpt-{os.getuid()}"


def map_yaml(name: str) -> Path:
    """Write the world grid of ``name`` as ``<cache>/mrpt_<name>.yaml`` + ``.pgm``; the yaml's path.

    Written whole each time (the same bytes for the same installed file), so no stale copy survives
    a package upgrade; each file is replaced by a rename, so a concurrent reader never sees half.

    Raises:
        KeyError, FileNotFoundError, GridmapError: As :func:`world_grid`.
    """
    grid = world_grid(name)
    folder = cache_dir()
    folder.mkdir(parents=True, exist_ok=True)
    # written in a folder of this process's own, then moved: processes loading at once never collide
    with tempfile.TemporaryDirectory(dir=folder, prefix=".write-") as scratch:
        image, meta = write_map(grid, scratch, f"mrpt_{name}")
        for made in (image, meta):  # the image first: a yaml in place always finds its image
            target = folder / made.name
            if not (target.is_file() and target.read_bytes() == made.read_bytes()):
                os.replace(made, target)
    return (folder / meta.name).resolve()


def mrpt_document(argument: str) -> tuple[Located, Path]:
    """The world source behind ``mrpt:<name>[:<seed>]`` (seed 0 when left out), two walkers.

    Raises:
        WorldFileError: An unknown name or a bad seed; the datasets are missing (names the apt
            package) or a gridmap is malformed.
    """
    name, _, seed = argument.partition(":")
    where = f"{MRPT_PREFIX}{argument}"
    hint = f"write e.g. mrpt:uwb or mrpt:malaga:4 (a map of {', '.join(MAPS)} and a seed)"
    if name not in MAPS or (seed and (not seed.isdigit() or len(seed) > 18)):
        message = (f"expected `mrpt:<map>[:<seed>]` with a map of {', '.join(MAPS)} and a whole-number "
                   f"seed, found {argument!r}")
        raise WorldFileError([Problem(where, 0, 0, "", message, hint)])
    try:
        path = map_yaml(name)
    except (GridmapError, OSError) as exc:  # FileNotFoundError names the apt package
        raise WorldFileError([Problem(where, 0, 0, "", str(exc))]) from None
    number = int(seed or 0)
    data = map_world(path, number, name=f"mrpt_{name}_{number}", people=2)
    data["description"] = (f"MRPT's {MAPS[name]} (mrpt-common, BSD-3), a grid built from real laser "
                           f"scans, with objects placed (seed {number}).")
    text = yaml.dump(data, Dumper=getattr(yaml, "CSafeDumper", yaml.SafeDumper), sort_keys=False)
    return parse_yaml(text, f"<{where}>", error=WorldFileError), path.parent / f"{data['name']}.yaml"


register_world_source(MRPT_PREFIX, mrpt_document)
