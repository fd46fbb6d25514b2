"""``colour_blob``: a detector provider that boxes the regions of one named colour.

A model provider from a package: it implements the Detector protocol
(:class:`missiontree.perception.detectors.Detector`) with OpenCV, no trained model. The pixels of the
named colour (the HSV colour naming of :mod:`missiontree.perception.colour`, the names world files
use) are grouped into connected regions; each region of at least ``min_area`` pixels is a detection,
its score the share of its box the colour fills. A models config picks it by name::

    roles:
      detector:
        provider: colour_blob
        colour: red
        label: red thing       # default "<colour> blob"
        min_area: 150

Options are checked as the built-ins' are: an unknown option, a colour the namer does not know or
a bad number is a :class:`~missiontree.errors.ModelConfigError` naming the provider and the fix.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import cv2
import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator

from missiontree.options import parse_provider_options
from missiontree.perception.colour import COLOUR_NAMES, canonical_colour, colour_mask
from missiontree.perception.detectors import check_image
from missiontree.types import Detection


class ColourBlobOptions(BaseModel):
    """Options of ``colour_blob`` (numbers must be finite)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    colour: str = Field(description="the colour to find: " + ", ".join(COLOUR_NAMES))
    label: str = ""
    min_area: int = Field(200, ge=1, le=10_000_000, description="smallest region, pixels")
    max_detections: int = Field(20, ge=1, le=1000)
    name: str = "colour_blob"

    @field_validator("colour")
    @classmethod
    def _known_colour(cls, value: str) -> str:
        name = canonical_colour(value)
        if name not in COLOUR_NAMES:
            raise ValueError(f"unknown colour {value!r}; known: {', '.join(COLOUR_NAMES)}")
        return name


class ColourBlobDetector:
    """Boxes the connected regions of one colour; implements the Detector protocol.

    Args:
        colour: A colour name (:data:`missiontree.perception.colour.COLOUR_NAMES` or an alias).
        label: The class name its detections carry (default ``"<colour> blob"``).
        min_area: Regions smaller than this many pixels are ignored.
        max_detections: At most this many detections, largest score first.
        name: Provider name for events and errors.
    """

    def __init__(self, colour: str, label: str = "", min_area: int = 200, max_detections: int = 20,
                 name: str = "colour_blob") -> None:
        self.colour = canonical_colour(colour)
        self.label = label or f"{self.colour} blob"
        self.min_area = min_area
        self.max_detections = max_detections
        self.name = name

    @property
    def labels(self) -> list[str]:
        """The one class it reports."""
        return [self.label]

    def detect(self, image: np.ndarray) -> list[Detection]:
        """Detections of the colour in ``image`` (HxWx3 uint8 RGB), best score first."""
        image = check_image(image, self.name)
        mask = colour_mask(image, self.colour).astype(np.uint8)
        count, _, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
        found: list[Detection] = []
        for i in range(1, count):
            x, y, w, h, area = (int(v) for v in stats[i])
            if area < self.min_area:
                continue
            score = float(area) / float(w * h)
            found.append(Detection(label=self.label, score=min(1.0, score),
                                   box=(float(x), float(y), float(x + w), float(y + h)),
                                   attributes={"colour": self.colour, "area": area}))
        found.sort(key=lambda d: (-d.score, d.box))
        return found[: self.max_detections]

    def check(self) -> str:
        """Nothing to load: a one-line description."""
        return f"{self.name}: OpenCV colour regions of {self.colour!r} (at least {self.min_area} px)"


def create_colour_blob(options: Mapping[str, Any]) -> ColourBlobDetector:
    """Build ``colour_blob`` from its models-config section (checked, see :class:`ColourBlobOptions`)."""
    parsed = parse_provider_options(ColourBlobOptions, options, "colour_blob")
    return ColourBlobDetector(colour=parsed.colour, label=parsed.label, min_area=parsed.min_area,
                              max_detections=parsed.max_detections, name=parsed.name)


# the options it takes, so a models config is checked (file:line:col) before anything is built
create_colour_blob.options_model = ColourBlobOptions  # type: ignore[attr-defined]
