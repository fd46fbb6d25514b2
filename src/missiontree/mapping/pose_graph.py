"""A 2-D pose graph: robot poses tied by measured relative poses, solved by robust least squares.

Scan-to-map matching (:mod:`missiontree.mapping.scan_matching`) keeps each scan consistent with the
ones just before it, but its error still adds up around a loop: when the robot comes back, the
place seen first and the place seen now can be a few decimetres apart. A loop closure is a
relative pose measured directly between a late scan and an early one; :func:`optimise` spreads
the disagreement between the chain of step-to-step poses and the closures over the whole
trajectory (the usual graph-SLAM back end, here with SciPy's sparse trust-region least squares
and a soft-L1 loss, so a wrong closure pulls less than a right one).

Pure NumPy/SciPy: no new dependency for a graph of a few hundred poses.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.sparse import lil_matrix

from missiontree.types import Pose2D


@dataclass(frozen=True)
class Edge:
    """A measured pose of node ``j`` in node ``i``'s frame, with its standard deviations.

    Attributes:
        i: Index of the reference pose.
        j: Index of the pose measured.
        measured: Pose of ``j`` relative to ``i`` (MRPT's ``j - i``).
        sigma_xy: Standard deviation of the position (m).
        sigma_yaw: Standard deviation of the heading (rad).
    """

    i: int
    j: int
    measured: Pose2D
    sigma_xy: float
    sigma_yaw: float


@dataclass(frozen=True)
class _EdgeArrays:
    i: np.ndarray
    j: np.ndarray
    measured: np.ndarray
    sigma: np.ndarray


def _wrap(angle: np.ndarray) -> np.ndarray:
    return np.arctan2(np.sin(angle), np.cos(angle))


def _residuals(free: np.ndarray, first: np.ndarray, edges: _EdgeArrays) -> np.ndarray:
    poses = np.vstack([first, free.reshape(-1, 3)])
    a, b = poses[edges.i], poses[edges.j]
    c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
    dx, dy = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
    rel = np.column_stack([c * dx + s * dy, -s * dx + c * dy, _wrap(b[:, 2] - a[:, 2])])
    err = rel - edges.measured
    err[:, 2] = _wrap(err[:, 2])
    return (err / edges.sigma).ravel()


def _arrays(edges: Sequence[Edge]) -> _EdgeArrays:
    return _EdgeArrays(
        np.array([e.i for e in edges], int), np.array([e.j for e in edges], int),
        np.array([(e.measured.x, e.measured.y, e.measured.yaw) for e in edges], float),
        np.array([(e.sigma_xy, e.sigma_xy, e.sigma_yaw) for e in edges], float))


def _sparsity(count: int, edges: _EdgeArrays) -> lil_matrix:
    """Which residuals depend on which free variables (pose 0 is fixed and has none)."""
    pattern = lil_matrix((3 * len(edges.i), 3 * (count - 1)), dtype=int)
    for row, (i, j) in enumerate(zip(edges.i, edges.j, strict=True)):
        for node in (i, j):
            if node > 0:
                pattern[3 * row:3 * row + 3, 3 * (node - 1):3 * node] = 1
    return pattern


def optimise(initial: Sequence[Pose2D], edges: Sequence[Edge], *, robust_scale: float = 3.0) -> list[Pose2D]:
    """The poses that best agree with ``edges``, starting from ``initial``; pose 0 stays where it is.

    Args:
        initial: A first estimate of every pose (e.g. the scan-to-map trajectory).
        edges: Measured relative poses (the chain of consecutive steps and any loop closures).
        robust_scale: Residuals beyond this many standard deviations weigh less (soft-L1 loss).

    Raises:
        ValueError: An edge names a pose that does not exist.
    """
    count = len(initial)
    if count < 2 or not edges:
        return list(initial)
    for edge in edges:
        if not (0 <= edge.i < count and 0 <= edge.j < count) or edge.i == edge.j:
            raise ValueError(f"edge ({edge.i}, {edge.j}): expected two different poses of 0..{count - 1}")
    arrays = _arrays(edges)
    start = np.array([(p.x, p.y, p.yaw) for p in initial], float)
    result = least_squares(_residuals, start[1:].ravel(), args=(start[0], arrays),
                           jac_sparsity=_sparsity(count, arrays), method="trf", loss="soft_l1",
                           f_scale=robust_scale, x_scale="jac", max_nfev=200)
    solved = result.x.reshape(-1, 3)
    return [initial[0]] + [Pose2D(float(x), float(y), float(_wrap(np.array(yaw)))) for x, y, yaw in solved]
