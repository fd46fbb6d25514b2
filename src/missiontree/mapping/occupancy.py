"""The values of an occupancy grid's cells and the thresholds that read them (constants only).

Cells hold -1 (unknown) or 0..100 (Nav2 and map_server's scale; a trinary map has only 0 and 100).
Two readings exist, each named once here:

- **map_server's reading** (:data:`OCCUPIED_FROM`, :data:`FREE_BELOW`): a cell at or above 65 is
  occupied, one below 25 free, the rest unknown. Map files, plausibility checks and coverage read
  maps this way.
- **the blocking threshold** (:data:`BLOCKED_FROM`, 50): a cell at or above it is an obstacle to the
  robot and a wall in pictures; below it (and known) it is open. The planner's lethal cells, the
  simulator's walls and standoff poses use it. On a trinary map both readings agree.

Light on purpose (no numpy, no numba): pictures and exports import it without the grid's kernels.
"""

from __future__ import annotations

#: Cell values of a trinary grid.
UNKNOWN, FREE, OCCUPIED = -1, 0, 100
#: map_server's default trinary thresholds (probability of occupancy).
OCCUPIED_THRESH = 0.65
FREE_THRESH = 0.25
#: Cell values at or above this read as occupied, values 0 up to FREE_BELOW as free (map_server's
#: thresholds on the 0..100 scale); the rest, and -1, is unknown.
OCCUPIED_FROM = int(round(OCCUPIED_THRESH * 100))
FREE_BELOW = int(round(FREE_THRESH * 100))
#: Cell values at or above this block the robot (an obstacle to plan around, a wall to draw).
BLOCKED_FROM = 50

__all__ = ["BLOCKED_FROM", "FREE", "FREE_BELOW", "FREE_THRESH", "OCCUPIED", "OCCUPIED_FROM",
           "OCCUPIED_THRESH", "UNKNOWN"]
