"""How far sim-ros steps its world at each turn of its pacing loop (pure arithmetic, no ROS).

sim-ros runs the simulator in step with wall time at a ``rate`` (simulated seconds per wall second).
When the machine cannot keep up -- a loaded CI runner, a process descheduled for two seconds --
stepping to wherever the wall clock says would make the world's clock leap ahead in one stride:
/clock jumps ten simulated seconds while the odometry and the camera frame of that stride are still
on their way, and a client that follows /clock sees its robot's pose ten seconds old and calls the
robot lost. A simulator does what Gazebo does instead: the world's clock slows down (its real-time
factor drops) and every stride stays short, so sensors and the clock never part.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: The longest stride of simulated time one turn of the pacing loop takes, in simulated seconds.
#: Shorter than every sensor's timeout by far (the tightest a mission uses is 1 s of frame age).
MAX_STRIDE_S = 0.25


@dataclass(frozen=True)
class Stride:
    """One turn of the pacing loop.

    Attributes:
        target: The simulated time to step to (a whole number of physics steps from the anchor).
        slipped: The wall clock ran ahead of what the simulator can do: the caller re-anchors its
            pacing at ``target`` so that the lag is dropped rather than caught up later.
    """

    target: float
    slipped: bool


def next_stride(sim_now: float, sim0: float, wall_elapsed: float, rate: float, dt: float,
                max_stride: float = MAX_STRIDE_S) -> Stride:
    """Where to step the world now.

    Args:
        sim_now: The simulator's current time.
        sim0: The simulated time at the pacing anchor.
        wall_elapsed: Wall seconds since the pacing anchor.
        rate: Simulated seconds per wall second.
        dt: The physics step.
        max_stride: The longest stride allowed (see :data:`MAX_STRIDE_S`).

    Returns:
        The target time: whole physics steps only, so that no stamp lies ahead of the clock; never
        more than ``max_stride`` (and at least one step) past ``sim_now`` when the world is behind.
    """
    steps = math.floor(wall_elapsed * rate / dt + 1e-6)
    target = sim0 + steps * dt
    if target - sim_now <= max_stride + 1e-9:
        return Stride(target, False)
    return Stride(sim_now + max(1, math.floor(max_stride / dt + 1e-6)) * dt, True)
