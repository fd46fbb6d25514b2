"""Tests that a large world's images are built without whole-image float temporaries, same pixels."""

from __future__ import annotations

import numpy as np

from missiontree.backends.sim.camera import _TILE, Floor
from missiontree.backends.sim.world import load_world


def _floor_at_once(rgb: np.ndarray, ox: float, oy: float, res: float) -> np.ndarray:
    """The floor texture as it was computed before: the whole image in one float64 pass."""
    rows, cols = rgb.shape[:2]
    xs = ox + (np.arange(cols) + 0.5) * res
    ys = oy + (np.arange(rows) + 0.5) * res
    parity = (np.floor(ys / _TILE)[:, None] + np.floor(xs / _TILE)[None, :]) % 2
    return np.clip(rgb * np.where(parity > 0, 0.94, 1.0)[..., None], 0, 255).astype(np.uint8)


def test_floor_texture_in_bands_is_the_whole_image_pass() -> None:
    """Baking the floor in bands of rows gives the same texture as one pass over the whole image."""
    rgb = np.random.default_rng(3).integers(0, 256, (700, 90, 3)).astype(np.uint8)
    floor = Floor.build(rgb, -1.3, 2.7, 0.05, 2.5)
    assert np.array_equal(floor.texture, _floor_at_once(rgb, -1.3, 2.7, 0.05))


def test_floor_colours_are_bytes() -> None:
    """A world's per-cell floor colours are uint8 (whole numbers 0-255), not float64."""
    world = load_world("office")
    assert world.floor_rgb.dtype == np.uint8
    assert world.floor_rgb.shape == world.grid.data.shape + (3,)


def test_the_grid_holds_only_free_and_occupied_values() -> None:
    """The rasterised grid of a wall world is int8 with 0 and 100 only."""
    grid = load_world("office").grid
    assert grid.data.dtype == np.int8
    assert set(np.unique(grid.data).tolist()) <= {0, 100}
