"""sim-ros's pacing: the world's clock slows when the machine cannot keep up, and never leaps."""

from __future__ import annotations

import pytest

from missiontree.backends.ros2.pacing import MAX_STRIDE_S, next_stride


def test_in_step_with_the_wall_clock_the_stride_follows_it() -> None:
    """Keeping up, the target is the wall clock's time in whole physics steps, with no slip."""
    stride = next_stride(sim_now=1.0, sim0=0.0, wall_elapsed=0.2626, rate=4.0, dt=0.05)
    assert stride.target == pytest.approx(1.05)
    assert not stride.slipped


def test_a_stalled_process_does_not_make_the_clock_leap() -> None:
    """After a 2.5 s stall at rate 4 the world advances one short stride, not 10 s, and re-anchors."""
    stride = next_stride(sim_now=20.0, sim0=0.0, wall_elapsed=7.5, rate=4.0, dt=0.05)
    assert stride.slipped
    assert 20.0 < stride.target <= 20.0 + MAX_STRIDE_S + 1e-9


def test_a_slow_machine_advances_at_least_one_physics_step() -> None:
    """A stride limit shorter than the physics step still moves the world one step."""
    stride = next_stride(sim_now=5.0, sim0=0.0, wall_elapsed=100.0, rate=1.0, dt=0.5, max_stride=0.1)
    assert stride.target == pytest.approx(5.5)
    assert stride.slipped


def test_never_ahead_of_the_wall_clock() -> None:
    """The target never lies ahead of the time the wall clock has reached."""
    for elapsed in (0.0, 0.01, 0.0124, 0.0125, 0.3):
        stride = next_stride(sim_now=0.0, sim0=0.0, wall_elapsed=elapsed, rate=4.0, dt=0.05)
        assert stride.target <= elapsed * 4.0 + 1e-9
