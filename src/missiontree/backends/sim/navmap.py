"""Worlds drawn on a map_server map: finding, reading and outlining the Nav2 map a world names.

A world's ``map: {yaml: ...}`` names a Nav2 map yaml (image, resolution, origin, thresholds); the
yaml and its image must lie inside the world's folder or a folder of ``$MISSIONTREE_MAP_PATH``, are
read with size bounds, and a problem never echoes their content (a file named by mistake may hold
anything). The image becomes occupancy values as Nav2's map_server reads it, and its occupied cells
become wall segments for the sensors (:func:`contour_segments`).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pydantic

from missiontree.backends.sim.mapimage import MapImageError, read_map_image
from missiontree.backends.sim.schema import MAX_EXTENT, NavMapYaml, WorldSpec
from missiontree.errors import Problem, WorldFileError
from missiontree.types import Pose2D
from missiontree.yamlio import Located, YamlLimits, load_yaml, validation_problems

#: Folders (besides the world file's own) that a world's ``map: {yaml: ...}`` may name, from
#: ``$MISSIONTREE_MAP_PATH`` (``os.pathsep``-separated), read when a world is loaded.
MAP_PATH_ENV = "MISSIONTREE_MAP_PATH"
#: A Nav2 map yaml is a few lines; anything bigger is not one.
MAP_YAML_LIMITS = YamlLimits(max_bytes=16 * 1024, max_depth=8, max_nodes=1_000)
_MAP_YAML_HINT = "point at the .yaml that map_server wrote (image, resolution, origin)"


def map_dirs() -> list[Path]:
    """The folders ``$MISSIONTREE_MAP_PATH`` allows map files in, besides each world's own folder."""
    return [Path(p).resolve() for p in os.environ.get(MAP_PATH_ENV, "").split(os.pathsep) if p]


def resolve_reference(doc: Located, key: tuple[str | int, ...], target: str, base: Path, what: str,
                       problems: list[Problem]) -> Path | None:
    """A file a world (or its map yaml) names: inside ``base`` or an allowed map folder, and present.

    The problem never shows the file's content, and names the resolved path only when it is allowed.
    """
    try:
        resolved = (base / target).resolve()
    except (OSError, ValueError, RuntimeError):  # a NUL byte, a symlink loop
        problems.append(doc.problem_at(key, f"expected a path to a {what}, found {target!r}, which is not a "
                                       "valid path", "give a path relative to the file that names it"))
        return None
    allowed = [base.resolve(), *map_dirs()]
    if not any(resolved.is_relative_to(d) for d in allowed):
        problems.append(doc.problem_at(
            key, f"expected a {what} inside the world's folder {base.resolve()}, found {target!r} outside it",
            f"copy the map next to the world file, or add its folder to ${MAP_PATH_ENV}"))
        return None
    if not resolved.is_file():
        problems.append(doc.problem_at(key, f"{what} {target!r} does not exist (looked at {resolved})",
                                       "give a path relative to the file that names it"))
        return None
    return resolved


def read_nav2_map(spec: WorldSpec, doc: Located, path: Path,
                   problems: list[Problem]) -> tuple[np.ndarray, float, Pose2D] | None:
    """The Nav2 map ``spec.map`` names: (occupancy values, resolution, origin), or None.

    Every problem (a file outside the allowed folders or missing, not a map yaml, an unreadable
    image, a map larger than ``MAX_EXTENT`` a side) is added to ``problems`` instead of raised.
    """
    assert spec.map is not None
    map_yaml = resolve_reference(doc, ("map", "yaml"), spec.map.yaml, path.parent, "map yaml", problems)
    if map_yaml is None:
        return None
    try:
        mdoc = load_yaml(map_yaml, error=WorldFileError, limits=MAP_YAML_LIMITS)
    except WorldFileError as exc:
        # say where, never what: a file named by mistake may hold anything
        first = exc.problems[0]
        problems.append(doc.problem_at(("map", "yaml"), f"map yaml {spec.map.yaml!r} is not a Nav2 map yaml "
                                       f"({len(exc.problems)} problem(s), the first at line {first.line})",
                                       _MAP_YAML_HINT))
        return None
    if not isinstance(mdoc.data, dict):
        problems.append(doc.problem_at(("map", "yaml"), f"map yaml {spec.map.yaml!r} is not a Nav2 map yaml "
                                       f"(expected a mapping, found {type(mdoc.data).__name__})",
                                       _MAP_YAML_HINT))
        return None
    try:
        meta = NavMapYaml.model_validate(mdoc.data)
    except pydantic.ValidationError as exc:
        problems.extend(validation_problems(exc, mdoc, NavMapYaml, docs="docs/worlds.md"))
        return None
    image_path = resolve_reference(mdoc, ("image",), meta.image, map_yaml.parent, "map image", problems)
    if image_path is None:
        return None
    try:
        image = read_map_image(image_path)
    except MapImageError as exc:
        problems.append(mdoc.problem_at(("image",), f"map image {meta.image!r}: {exc}", exc.hint))
        return None
    extent = max(image.shape) * meta.resolution
    if extent > MAX_EXTENT:
        problems.append(mdoc.problem_at(
            ("resolution",), f"expected a map of at most {MAX_EXTENT:g} m a side, found "
            f"{image.shape[1]} x {image.shape[0]} cells of {meta.resolution:g} m ({extent:,.0f} m)",
            "check the resolution (metres per pixel)"))
        return None
    return map_cells(image, meta), meta.resolution, Pose2D(meta.origin[0], meta.origin[1], 0.0)


def map_cells(image: np.ndarray, meta: NavMapYaml) -> np.ndarray:
    """Occupancy values (100 occupied, 0 free, -1 unknown) as Nav2's map_server reads the image.

    Row 0 of the result is the map's lowest y (the image's bottom row), as in OccupancyGrid.
    """
    if meta.mode == "raw":
        cells = np.where(image <= 100, image, -1).astype(np.int8)
    else:
        occ = image.astype(float) / 255.0
        occ = occ if meta.negate else 1.0 - occ
        cells = np.full(image.shape, -1, np.int8)
        cells[occ < meta.free_thresh] = 0
        if meta.mode == "scale":
            between = (occ >= meta.free_thresh) & (occ <= meta.occupied_thresh)
            scaled = 99.0 * (occ - meta.free_thresh) / max(meta.occupied_thresh - meta.free_thresh, 1e-9)
            cells[between] = scaled[between].astype(np.int8)
        cells[occ > meta.occupied_thresh] = 100
    return np.flipud(cells)


def contour_segments(occupied: np.ndarray, res: float,
                      origin: Pose2D) -> list[tuple[float, float, float, float]]:
    """Outline the occupied cells of a map as wall segments along cell edges (exact to the grid)."""
    occ = np.pad(occupied.astype(bool), 1)
    segments: list[tuple[float, float, float, float]] = []
    # edges between horizontally adjacent cells run vertically at x = column boundary
    vertical = occ[:, 1:] != occ[:, :-1]          # (rows+2, cols+1)
    for boundary in np.flatnonzero(vertical.any(axis=0)):
        for r0, r1 in _runs(vertical[:, boundary]):
            x = origin.x + (boundary - 1 + 1) * res
            segments.append((x, origin.y + (r0 - 1) * res, x, origin.y + (r1 - 1) * res))
    horizontal = occ[1:, :] != occ[:-1, :]        # (rows+1, cols+2)
    for boundary in np.flatnonzero(horizontal.any(axis=1)):
        for c0, c1 in _runs(horizontal[boundary, :]):
            y = origin.y + (boundary - 1 + 1) * res
            segments.append((origin.x + (c0 - 1) * res, y, origin.x + (c1 - 1) * res, y))
    return segments


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(start, end) index pairs of the runs of True in a 1-D mask (end exclusive)."""
    padded = np.concatenate([[False], mask, [False]]).astype(np.int8)
    edges = np.flatnonzero(np.diff(padded))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist(), strict=True))
