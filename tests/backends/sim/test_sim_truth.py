"""The ground truth's kept instance masks: one buffer, bounded by the horizon, copies handed out."""

from __future__ import annotations

import numpy as np

from missiontree.backends.sim.truth import MaskRing


def mask(value: int, shape: tuple[int, int] = (6, 8)) -> np.ndarray:
    """An int32 mask (as the camera renders) filled with ``value``."""
    return np.full(shape, value, dtype=np.int32)


def test_ring_keeps_the_horizon_and_finds_frames_by_stamp():
    """Frames within the horizon are found by stamp (nearest within the gap); older ones are dropped."""
    ring = MaskRing(horizon=1.0, dtype=np.uint16)
    for i in range(30):
        ring.push(i * 0.2, mask(i))
    assert len(ring) == 6  # 4.8 s back to 4.0 s
    found = ring.nearest(5.0, max_gap=1e-3)
    assert found is not None and found.dtype == np.uint16 and found.shape == (6, 8)
    assert (found == 25).all()
    assert ring.nearest(5.05, max_gap=1e-3) is None
    assert (ring.nearest(5.05) == 25).all()
    assert ring.nearest(3.8, max_gap=1e-3) is None  # left the horizon


def test_ring_allocates_once_for_a_constant_frame_rate():
    """Over a long run at a constant rate the buffer stops growing after the first horizon."""
    ring = MaskRing(horizon=10.0, dtype=np.uint16)
    for i in range(100):
        ring.push(i * 0.2, mask(i))
    buffer, capacity = ring._buffer, ring.capacity
    assert 51 <= capacity <= 70
    for i in range(100, 5000):  # 1000 s more
        ring.push(i * 0.2, mask(i % 60000))
    assert ring._buffer is buffer and ring.capacity == capacity
    assert len(ring) == 51
    assert ring.nbytes == capacity * 6 * 8 * 2
    oldest = ring.nearest(4990 * 0.2, max_gap=1e-3)
    assert oldest is not None and (oldest == 4990).all()


def test_ring_hands_out_copies_that_outlive_the_slot():
    """A mask taken from the ring keeps its content after its slot is reused."""
    ring = MaskRing(horizon=0.5, dtype=np.int32)
    ring.push(0.0, mask(7))
    taken = ring.nearest(0.0)
    assert taken is not None
    for i in range(1, 50):
        ring.push(i * 0.2, mask(100 + i))
    assert (taken == 7).all()
    assert ring.nearest(0.0, max_gap=1e-3) is None


def test_ring_cast_keeps_uint16_ids_and_bounds_frames():
    """Ids up to 65,535 survive the cast; ``max_frames`` bounds the kept frames whatever the horizon."""
    ring = MaskRing(horizon=1e9, dtype=np.uint16, max_frames=8)
    ring.push(0.0, mask(65535))
    got = ring.nearest(0.0)
    assert got is not None and int(got[0, 0]) == 65535
    for i in range(1, 100):
        ring.push(float(i), mask(i))
    assert len(ring) == 8 and ring.capacity <= 8
    assert ring.nearest(91.0, max_gap=0.1) is None and (ring.nearest(92.0, max_gap=0.1) == 92).all()


def test_ring_restarts_when_the_frame_size_changes():
    """A mask of another size starts the ring anew (no stale frames of the old size)."""
    ring = MaskRing(horizon=10.0)
    ring.push(0.0, mask(1))
    ring.push(0.2, mask(2, (3, 4)))
    assert len(ring) == 1 and ring.nearest(0.0, max_gap=1e-3) is None
    got = ring.nearest(0.2)
    assert got is not None and got.shape == (3, 4)
