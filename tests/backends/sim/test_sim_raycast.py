"""The ray-casting kernels: culled numba loops agree with the brute-force numpy reference."""

from __future__ import annotations

import math

import numpy as np
import pytest

from missiontree.backends.sim.raycast import (
    BOX,
    CYLINDER,
    HAVE_NUMBA,
    SEGMENT,
    Primitives,
    column_hits,
    fan_first_hit,
)


def _random_scene(seed: int) -> Primitives:
    rng = np.random.default_rng(seed)
    rows = []
    for i in range(30):
        x, y = rng.uniform(-6, 6, 2)
        kind = [SEGMENT, BOX, CYLINDER][i % 3]
        if kind == SEGMENT:
            geom = (x, y, x + rng.uniform(-3, 3), y + rng.uniform(-3, 3))
        elif kind == BOX:
            yaw = rng.uniform(-math.pi, math.pi)
            geom = (x, y, math.cos(yaw), math.sin(yaw), rng.uniform(0.05, 1.0), rng.uniform(0.05, 1.0))
        else:
            geom = (x, y, rng.uniform(0.03, 0.8))
        rows.append((kind, geom, 0.0, float(rng.uniform(0.1, 2.0)), (100, 100, 100), i + 2))
    return Primitives.build(rows)


@pytest.mark.skipif(not HAVE_NUMBA, reason="numba not installed")
@pytest.mark.parametrize("seed", range(5))
def test_fan_kernel_matches_numpy(seed):
    """Every beam's nearest range is the same with bound culling (numba) and brute force (numpy)."""
    prims = _random_scene(seed)
    args = (0.3, -0.2, 0.7, 2 * math.pi / 720, 720, prims.kind, prims.geom)
    fast = fan_first_hit(*args, accelerate=True)
    slow = fan_first_hit(*args, accelerate=False)
    assert np.array_equal(np.isfinite(fast), np.isfinite(slow))
    assert np.allclose(fast[np.isfinite(fast)], slow[np.isfinite(slow)], atol=1e-9)


@pytest.mark.skipif(not HAVE_NUMBA, reason="numba not installed")
@pytest.mark.parametrize("seed", range(5))
def test_column_kernel_matches_numpy(seed):
    """The k nearest hits per camera column agree between the culled kernel and numpy."""
    prims = _random_scene(seed)
    a = (159.5 - np.arange(320)) / 228.5
    fast = column_hits(0.3, -0.2, 2.0, a, 228.5, 159.5, prims, 8, accelerate=True)
    slow = column_hits(0.3, -0.2, 2.0, a, 228.5, 159.5, prims, 8, accelerate=False)
    tin_f, tin_s = fast[0], slow[0]
    assert np.array_equal(np.isfinite(tin_f), np.isfinite(tin_s))
    finite = np.isfinite(tin_f)
    assert np.allclose(tin_f[finite], tin_s[finite], atol=1e-9)
    assert np.allclose(fast[1][finite], slow[1][finite], atol=1e-9)


def test_segment_box_and_cylinder_distances():
    """Analytic entry and exit: a wall 2 m ahead, a box's near face, a cylinder's surface."""
    prims = Primitives.build([
        (SEGMENT, (2.0, -1.0, 2.0, 1.0), 0.0, 2.0, (1, 1, 1), 1),
        (BOX, (1.0, 3.0, 1.0, 0.0, 0.5, 0.25), 0.0, 1.0, (1, 1, 1), 2),
        (CYLINDER, (-3.0, 0.0, 0.5), 0.0, 1.0, (1, 1, 1), 3),
    ])
    ranges = fan_first_hit(0.0, 0.0, 0.0, math.pi / 2, 4, prims.kind, prims.geom, accelerate=False)
    # beams: +x (wall at 2), +y (nothing: the box is at x 0.5..1.5), -x (cylinder at 2.5), -y (nothing)
    assert ranges[0] == pytest.approx(2.0) and ranges[2] == pytest.approx(2.5)
    assert math.isinf(ranges[1]) and math.isinf(ranges[3])
    hits = fan_first_hit(1.0, 0.0, math.pi / 2, 1.0, 1, prims.kind, prims.geom, accelerate=False)
    assert hits[0] == pytest.approx(3.0 - 0.25)
