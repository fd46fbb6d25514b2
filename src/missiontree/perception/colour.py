"""Colour naming of image regions in HSV, and where in the image a colour lies.

The vision-language object-search report's colour mapper thresholds the image in HSV for a named
colour, calls the colour present when the matching pixels exceed a fraction of the region
(typically 1 %), and places the matching region left, centre or right from the horizontal
position of its centroid (image moments). This
module does that, and the inverse: name the dominant colour of a box or mask, so a detection can
carry "grey backpack" or "red cup".

Hues are OpenCV's (0-179). Unsaturated pixels are named by brightness (black, grey, white);
saturated ones by hue, with dark orange called brown and pale bright orange or yellow beige. The
names are those world files use (the simulator's palette names map onto them through ALIASES).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np

Position = Literal["left", "centre", "right"]

#: Every colour name this module can return, in a fixed order (the index of a pixel's class).
COLOUR_NAMES: tuple[str, ...] = (
    "black", "grey", "white", "red", "orange", "brown", "yellow", "green", "cyan", "blue", "purple", "pink",
    "beige",
)

#: Spellings people use for the same colour.
ALIASES: dict[str, str] = {
    "gray": "grey", "silver": "grey", "violet": "purple", "magenta": "pink", "teal": "cyan",
    "navy": "blue", "tan": "beige", "cream": "beige", "golden": "yellow", "gold": "yellow",
    "dark grey": "grey", "dark gray": "grey", "light grey": "grey", "light gray": "grey",
    "wood": "brown", "wooden": "brown",
}

#: Hue upper bounds (exclusive, OpenCV 0-179) of the saturated colours, in order round the wheel.
_HUE_BINS: tuple[tuple[int, str], ...] = (
    (8, "red"), (21, "orange"), (34, "yellow"), (85, "green"), (100, "cyan"),
    (131, "blue"), (146, "purple"), (170, "pink"), (180, "red"),
)

#: Below this value (0-255) a pixel is black whatever its hue.
DARK_V = 45
#: Below this saturation (0-255) a pixel has no hue: black, grey or white by value.
GREY_S = 50
#: Unsaturated pixels brighter than this are white (a white face turned from the light is ~75 %).
WHITE_V = 175
#: Orange-hued pixels darker than this are brown.
BROWN_V = 170
#: Orange- and yellow-hued pixels this pale (saturation below) and bright (value above) are beige.
BEIGE_S, BEIGE_V = 100, 150


def canonical_colour(name: str) -> str:
    """Return the canonical name of ``name`` (``"Gray"`` → ``"grey"``); unknown names pass lowered."""
    lowered = name.strip().lower()
    return ALIASES.get(lowered, lowered)


def _hue_lut() -> np.ndarray:
    lut = np.zeros(180, dtype=np.uint8)
    start = 0
    for end, colour in _HUE_BINS:
        lut[start:end] = COLOUR_NAMES.index(colour)
        start = end
    return lut


_HUE_TO_CLASS = _hue_lut()


def colour_classes(image: np.ndarray) -> np.ndarray:
    """Index into :data:`COLOUR_NAMES` of every pixel of an HxWx3 uint8 RGB image (HxW uint8)."""
    hsv = cv2.cvtColor(np.ascontiguousarray(image), cv2.COLOR_RGB2HSV)
    h, s, v = hsv[..., 0], hsv[..., 1], hsv[..., 2]
    classes = _HUE_TO_CLASS[np.minimum(h, 179)]
    warm = (classes == COLOUR_NAMES.index("orange")) | (classes == COLOUR_NAMES.index("yellow"))
    beige = warm & (s < BEIGE_S) & (v >= BEIGE_V)
    brown = (classes == COLOUR_NAMES.index("orange")) & (v < BROWN_V)
    classes = np.where(brown, COLOUR_NAMES.index("brown"), classes)
    classes = np.where(beige, COLOUR_NAMES.index("beige"), classes)
    grey_level = np.where(v >= WHITE_V, COLOUR_NAMES.index("white"), COLOUR_NAMES.index("grey"))
    classes = np.where(s < GREY_S, grey_level, classes)
    classes = np.where(v < DARK_V, COLOUR_NAMES.index("black"), classes)
    return classes.astype(np.uint8)


def colour_mask(image: np.ndarray, colour: str) -> np.ndarray:
    """HxW bool mask of the pixels of ``image`` (RGB uint8) that have the named colour.

    Raises:
        ValueError: ``colour`` is not a name this module knows; the message lists them.
    """
    name = canonical_colour(colour)
    if name not in COLOUR_NAMES:
        raise ValueError(f"unknown colour {colour!r}; known: {', '.join(COLOUR_NAMES)}")
    return colour_classes(image) == COLOUR_NAMES.index(name)


def horizontal_position(u: float, width: int) -> Position:
    """Which third of an image ``width`` pixels wide the column ``u`` lies in."""
    if u < width / 3.0:
        return "left"
    if u >= 2.0 * width / 3.0:
        return "right"
    return "centre"


@dataclass(frozen=True, slots=True)
class ColourReading:
    """The dominant colour of a region and where the region lies.

    Attributes:
        name: Dominant colour name (one of :data:`COLOUR_NAMES`).
        fraction: Share of the region's pixels that have that colour.
        shares: Share of every colour present in the region, largest first.
        position: Left, centre or right third of the image, from the region's centroid.
        centroid: (u, v) centroid of the region in image pixels.
    """

    name: str
    fraction: float
    shares: dict[str, float]
    position: Position
    centroid: tuple[float, float]


def _region_mask(
    shape: tuple[int, int], box: tuple[float, float, float, float] | None, mask: np.ndarray | None
) -> np.ndarray:
    height, width = shape
    region = np.ones((height, width), dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
    if region.shape != (height, width):
        raise ValueError(f"mask shape {region.shape} does not match the image's {(height, width)}")
    if box is not None:
        x1, y1 = max(0, int(np.floor(box[0]))), max(0, int(np.floor(box[1])))
        x2, y2 = min(width, int(np.ceil(box[2]))), min(height, int(np.ceil(box[3])))
        inside = np.zeros_like(region)
        inside[y1:y2, x1:x2] = True
        region = region & inside
    return region


def dominant_colour(
    image: np.ndarray,
    box: tuple[float, float, float, float] | None = None,
    mask: np.ndarray | None = None,
    inner: float = 1.0,
) -> ColourReading | None:
    """Name the dominant colour of a box and/or mask of ``image`` (HxWx3 uint8 RGB).

    Args:
        image: The image.
        box: (x1, y1, x2, y2) region in pixels; the whole image when None.
        mask: HxW bool mask of the object's pixels; the whole box when None.
        inner: Keep only this central fraction of the box's width and height (a box drawn around
            an object holds background at its edges; 0.6 keeps the middle 60 %).

    Returns:
        The reading, or None when the region holds no pixel.
    """
    if box is not None and inner < 1.0:
        cx, cy = (box[0] + box[2]) / 2.0, (box[1] + box[3]) / 2.0
        hw, hh = (box[2] - box[0]) * inner / 2.0, (box[3] - box[1]) * inner / 2.0
        box = (cx - hw, cy - hh, cx + hw, cy + hh)
    region = _region_mask(image.shape[:2], box, mask)
    count = int(region.sum())
    if count == 0:
        return None
    ys, xs = np.nonzero(region)
    x1, x2, y1, y2 = xs.min(), xs.max() + 1, ys.min(), ys.max() + 1
    classes = colour_classes(image[y1:y2, x1:x2])[region[y1:y2, x1:x2]]
    counts = np.bincount(classes, minlength=len(COLOUR_NAMES))
    order = np.argsort(-counts, kind="stable")
    shares = {COLOUR_NAMES[i]: float(counts[i]) / count for i in order if counts[i] > 0}
    best = COLOUR_NAMES[int(order[0])]
    centroid = (float(xs.mean()) + 0.5, float(ys.mean()) + 0.5)
    return ColourReading(
        name=best,
        fraction=shares[best],
        shares=shares,
        position=horizontal_position(centroid[0], image.shape[1]),
        centroid=centroid,
    )


def surface_mask(depth: np.ndarray, surface: float, band: float) -> np.ndarray:
    """HxW bool mask of the pixels whose depth lies within ``band`` metres of ``surface``.

    A box holds more than its object: the wall behind a chair's legs and back, the table in front
    of a chair pushed under it. The pixels at the depth of the object's measured surface are the
    object's; those far behind or in front are not, and must not name its colour.
    """
    d = np.asarray(depth, dtype=np.float32)
    return np.isfinite(d) & (d > 0) & (np.abs(d - surface) <= band)


#: Only pixels this close in depth to the box's measured surface name its colour, metres: the
#: object's own faces (a chair 0.45 m deep, seen corner-on), not the wall behind or a table before it.
COLOUR_DEPTH_BAND = 0.35
#: Least share of the inner box's pixels at the surface's depth for the depth mask to be used (else
#: the whole inner box names the colour, as without depth).
COLOUR_MIN_SHARE = 0.1


def box_colour(
    image: np.ndarray,
    depth: np.ndarray | None,
    box: tuple[float, float, float, float],
    mask: np.ndarray | None = None,
    surface: float | None = None,
    inner: float = 0.6,
) -> str | None:
    """The colour name of a detection's box: its ``inner`` part, at the depth of its surface when given.

    With ``surface`` (the depth the box's object was measured at) and a depth image registered to
    ``image``, only the pixels within :data:`COLOUR_DEPTH_BAND` of it count (:func:`surface_mask`),
    unless fewer than :data:`COLOUR_MIN_SHARE` of the inner box's pixels are there.
    """
    if surface is not None and math.isfinite(surface) and depth is not None:
        if np.asarray(depth).shape == image.shape[:2]:
            near = surface_mask(depth, surface, COLOUR_DEPTH_BAND)
            if mask is not None:
                near = near & np.asarray(mask, dtype=bool)
            x1, y1, x2, y2 = box
            cx, cy = (x1 + x2) / 2.0, (y1 + y2) / 2.0
            hw, hh = (x2 - x1) * inner / 2.0, (y2 - y1) * inner / 2.0
            r0, r1 = max(0, int(cy - hh)), max(0, int(math.ceil(cy + hh)))
            c0, c1 = max(0, int(cx - hw)), max(0, int(math.ceil(cx + hw)))
            part = near[r0:r1, c0:c1]
            if part.size and part.mean() >= COLOUR_MIN_SHARE:
                mask = near
    reading = dominant_colour(image, box, mask, inner=inner)
    return reading.name if reading is not None else None


@dataclass(frozen=True, slots=True)
class ColourRegion:
    """Where a named colour was found in an image (the object-search report's colour mapper result).

    Attributes:
        colour: The colour asked for (canonical name).
        fraction: Share of the image's pixels that have it.
        centroid: (u, v) centroid of those pixels (image moments).
        position: Left, centre or right third of the image.
    """

    colour: str
    fraction: float
    centroid: tuple[float, float]
    position: Position


def find_colour(image: np.ndarray, colour: str, min_fraction: float = 0.01) -> ColourRegion | None:
    """Look for ``colour`` in ``image``: present when at least ``min_fraction`` of its pixels have it.

    Returns:
        The region, or None when the colour covers less than ``min_fraction`` of the image.

    Raises:
        ValueError: ``colour`` is not a known colour name.
    """
    matching = colour_mask(image, colour).astype(np.uint8)
    moments = cv2.moments(matching, binaryImage=True)
    fraction = moments["m00"] / float(matching.size)
    if moments["m00"] == 0 or fraction < min_fraction:
        return None
    u, v = moments["m10"] / moments["m00"] + 0.5, moments["m01"] / moments["m00"] + 0.5
    return ColourRegion(
        colour=canonical_colour(colour),
        fraction=float(fraction),
        centroid=(float(u), float(v)),
        position=horizontal_position(u, image.shape[1]),
    )
