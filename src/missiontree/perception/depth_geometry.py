"""Geometry of a depth image: points from pixels, planes found in them (floor, walls), their distances.

Real depth has holes (glass, black or shiny surfaces, shadows beside near objects, the border a
Kinect leaves where its two cameras do not overlap) and noise that grows with distance, so every
function here drops NaN and non-positive depths and fits planes robustly (RANSAC with a fixed
seed, then a least-squares refit on the inliers), never trusting a single pixel.

Points are in the camera's optical frame (x right, y down, z forward along the optical axis), as
sensor_msgs/PointCloud2 from a depth camera; a plane is ``normal . p + offset = 0`` with a unit
normal pointing at the camera, so ``offset`` is the camera's distance from it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from missiontree.types import CameraIntrinsics

#: The optical frame's up for a level camera (y points down in the image).
LEVEL_UP = np.array([0.0, -1.0, 0.0])


@dataclass(frozen=True)
class Plane:
    """A plane ``normal . p + offset = 0`` (unit normal towards the camera) found in depth points.

    Attributes:
        normal: Unit normal in the optical frame, pointing at the camera.
        offset: The plane's offset; the camera is ``offset`` metres from the plane.
        inliers: Points within the fit's threshold.
        share: Share of the points given that are inliers.
        rms: Root mean square distance (m) of the inliers from the plane.
    """

    normal: np.ndarray
    offset: float
    inliers: int
    share: float
    rms: float

    @property
    def distance(self) -> float:
        """Distance (m) from the camera's optical centre to the plane."""
        return self.offset

    def angle_to(self, direction: np.ndarray) -> float:
        """Angle (rad) between the plane's normal and ``direction``."""
        d = np.asarray(direction, float)
        return math.acos(float(np.clip(abs(self.normal @ d) / np.linalg.norm(d), -1.0, 1.0)))

    def signed_distances(self, points: np.ndarray) -> np.ndarray:
        """Distance of each point from the plane, positive on the camera's side."""
        return points @ self.normal + self.offset


def back_project(depth: np.ndarray, intrinsics: CameraIntrinsics, step: int = 1) -> np.ndarray:
    """(n, 3) points of the valid depth pixels (every ``step``-th row and column) in the optical frame."""
    d = np.asarray(depth, np.float64)[::step, ::step]
    rows, cols = np.mgrid[0:depth.shape[0]:step, 0:depth.shape[1]:step]
    valid = np.isfinite(d) & (d > 0)
    z = d[valid]
    x = (cols[valid] - intrinsics.cx) * z / intrinsics.fx
    y = (rows[valid] - intrinsics.cy) * z / intrinsics.fy
    return np.column_stack([x, y, z])


def valid_share(depth: np.ndarray) -> float:
    """Share of pixels with a usable depth (finite and positive)."""
    d = np.asarray(depth)
    return float(np.mean(np.isfinite(d) & (d > 0)))


def fit_plane(points: np.ndarray, *, threshold: float = 0.02, iterations: int = 300, seed: int = 0,
              normal_near: np.ndarray | None = None, max_angle: float = math.pi) -> Plane | None:
    """The plane most points agree on (RANSAC, then a least-squares refit of its inliers).

    Args:
        points: (n, 3) points in the optical frame.
        threshold: Largest distance (m) of an inlier from the plane.
        iterations: RANSAC samples.
        seed: Seed of the sampling (the same points give the same plane).
        normal_near: Only planes whose normal is within ``max_angle`` of this direction count
            (e.g. the up direction for a floor).
        max_angle: See ``normal_near``.

    Returns:
        The plane, or None for fewer than three points or no plane of the wanted orientation.
    """
    pts = np.asarray(points, np.float64)
    if len(pts) < 3:
        return None
    rng = np.random.default_rng(seed)
    best_count, best = 0, None
    for _ in range(iterations):
        a, b, c = pts[rng.choice(len(pts), 3, replace=False)]
        normal = np.cross(b - a, c - a)
        norm = np.linalg.norm(normal)
        if norm < 1e-12:
            continue
        normal /= norm
        if normal_near is not None and _angle(normal, normal_near) > max_angle:
            continue
        count = int(np.count_nonzero(np.abs((pts - a) @ normal) < threshold))
        if count > best_count:
            best_count, best = count, (normal, float(-normal @ a))
    if best is None:
        return None
    normal, offset = best
    inliers = pts[np.abs(pts @ normal + offset) < threshold]
    centre = inliers.mean(axis=0)
    refit = np.linalg.svd(inliers - centre, full_matrices=False)[2][2]
    if normal_near is None or _angle(refit, normal_near) <= max_angle:
        normal = refit
    offset = float(-normal @ centre)
    if offset < 0:  # normal towards the camera: the origin on its positive side
        normal, offset = -normal, -offset
    dist = inliers @ normal + offset
    return Plane(normal, offset, len(inliers), len(inliers) / len(pts), float(np.sqrt(np.mean(dist**2))))


def find_floor(points: np.ndarray, up: np.ndarray = LEVEL_UP, *, max_tilt: float = math.radians(15),
               min_share: float = 0.05, threshold: float = 0.03, seed: int = 0) -> Plane | None:
    """The floor: the largest plane facing ``up`` (within ``max_tilt``) below the camera, or None.

    A floor must hold at least ``min_share`` of the points and lie below the camera (the camera on
    the side its normal points to); a shelf board seen from above is a plane facing up as well,
    which is why the share matters: a frame with no floor in view gives None rather than a board.
    """
    up = np.asarray(up, float) / np.linalg.norm(up)
    plane = fit_plane(points, threshold=threshold, seed=seed, normal_near=up, max_angle=max_tilt)
    if plane is None or plane.share < min_share:
        return None
    below = float(plane.normal @ up) > 0  # normal towards the camera and up: the camera is above it
    return plane if below else None


def remove_plane(points: np.ndarray, plane: Plane, margin: float = 0.03) -> np.ndarray:
    """The points more than ``margin`` metres off ``plane`` on the camera's side (e.g. floor removed)."""
    return points[plane.signed_distances(points) > margin]


def _angle(a: np.ndarray, b: np.ndarray) -> float:
    """Angle (rad) between two directions, regardless of their sign."""
    cos = abs(float(a @ b)) / (float(np.linalg.norm(a)) * float(np.linalg.norm(b)))
    return math.acos(min(1.0, cos))
