"""Depth from a rectified stereo pair: OpenCV's semi-global matching, disparity to metres.

For a rectified pair, a point seen at column ``u`` in the left image and ``u - d`` in the right lies
at depth ``z = f * B / (d + doffs)`` (``f`` the focal length in pixels, ``B`` the baseline in metres,
``doffs`` the difference of the two cameras' principal points, as Middlebury's calibration gives
it). :func:`stereo_disparity` runs OpenCV's StereoSGBM (a core dependency) with a left-right
consistency check, so occluded and textureless pixels come back as NaN rather than as a guess;
:func:`disparity_to_depth` turns disparities into the depth image an :class:`RGBDFrame` carries.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class StereoCalibration:
    """A rectified stereo pair's calibration (Middlebury's ``calib.txt`` terms).

    Attributes:
        focal: Focal length in pixels.
        baseline: Distance between the cameras in metres.
        cx: Principal point's column (left camera).
        cy: Principal point's row.
        doffs: Difference of the two principal points' columns (Middlebury's ``doffs``), added to
            every disparity before dividing.
    """

    focal: float
    baseline: float
    cx: float
    cy: float
    doffs: float = 0.0


def stereo_disparity(left: np.ndarray, right: np.ndarray, *, max_disparity: int = 64,
                     block: int = 5) -> np.ndarray:
    """Float32 disparity (pixels) of every left-image pixel; NaN where matching failed or disagreed.

    Args:
        left: Left image (HxW grey or HxWx3 RGB uint8).
        right: Right image, same size.
        max_disparity: Largest disparity searched (rounded up to a multiple of 16).
        block: Matching block size (odd).
    """
    import cv2

    if left.shape != right.shape:
        raise ValueError(f"expected two images of one size, found {left.shape} and {right.shape}")
    grey = [cv2.cvtColor(im, cv2.COLOR_RGB2GRAY) if im.ndim == 3 else im for im in (left, right)]
    count = max(16, -(-max_disparity // 16) * 16)
    channels = 1
    matcher = cv2.StereoSGBM.create(minDisparity=0, numDisparities=count, blockSize=block,
                                    P1=8 * channels * block**2, P2=32 * channels * block**2,
                                    disp12MaxDiff=1, uniquenessRatio=10, speckleWindowSize=100,
                                    speckleRange=2, mode=cv2.STEREO_SGBM_MODE_SGBM)
    raw = matcher.compute(grey[0], grey[1]).astype(np.float32) / 16.0  # fixed point, 4 fractional bits
    raw[raw <= 0] = np.nan
    return raw


def disparity_to_depth(disparity: np.ndarray, calibration: StereoCalibration) -> np.ndarray:
    """Depth (m) along the optical axis of each disparity; NaN where the disparity is NaN or not positive."""
    d = np.asarray(disparity, np.float64) + calibration.doffs
    with np.errstate(divide="ignore", invalid="ignore"):
        depth = calibration.focal * calibration.baseline / d
    depth[~(d > 0) | ~np.isfinite(d) | ~np.isfinite(depth)] = np.nan  # Middlebury marks unknown as inf
    return depth.astype(np.float32)
