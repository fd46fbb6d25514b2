"""Clearance: metres from each free cell to the nearest cell that is not free."""

from __future__ import annotations

import numpy as np

from missiontree.mapping.clearance import clearance_metres


def test_clearance_grows_by_the_resolution_away_from_a_wall() -> None:
    """A free room beside a wall column: 5 cm a cell from the wall, 0 on the wall itself."""
    free = np.ones((9, 9), bool)
    free[:, 0] = False
    found = clearance_metres(free, 0.05)
    assert found[4, 0] == 0.0
    assert np.allclose(found[4, 1:5], [0.05, 0.10, 0.15, 0.20], atol=1e-3)


def test_clearance_takes_masks_of_any_integer_or_bool_type() -> None:
    """A uint8 mask and the same bool mask give the same distances."""
    free = np.zeros((7, 7), bool)
    free[1:6, 1:6] = True
    assert np.array_equal(clearance_metres(free, 0.1), clearance_metres(free.astype(np.uint8), 0.1))
