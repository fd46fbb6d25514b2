"""The offline vision-language stand-in: answers what missions ask from a detector and measured colour.

No network, no GPU. It answers the questions the shipped missions ask a VLM, chosen by the answer
schema (or, without one, by the prompt):

- :class:`SurveillanceVerdict` (the patrol-robot thesis's "ALARM: PERSON DETECTED" / "SAFE"): ALARM when the
  detector finds a ``person`` scoring at least ``min_score``; the people's boxes come along.
- :class:`CropMatch` ("does this crop show 'grey backpack'?"): the description is parsed into label
  and attributes; it matches when the detector finds that label and the colour measured in HSV
  inside the box (:mod:`missiontree.perception.colour`) is the one asked for.
- :class:`RoomClassification`: room types voted by the objects detected (a sink and a cup say
  kitchen, a laptop says office, ...), each vote weighted by score and by the box's height in the
  image (near objects, seen large, belong to the room the camera is in; far ones may be seen
  through a doorway).
- :class:`ObjectDescription`: label, measured colour, a typical size of the class and a shape from
  the box's aspect ratio.
- No schema: the patrol-robot thesis's free-text sentence for a prompt about a PERSON, else a list
  of what is seen.

It is a stand-in, not a model: it can only name what the detector knows. Provider name
``offline_vlm``; options: ``detector`` (role of the detector, default ``detector``), ``min_score``
(0.5), ``colour_share`` (0.3: least share of the box that must have the asked colour),
``room_objects`` (room type → labels, replacing the defaults).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from pydantic import BaseModel

from missiontree.errors import ModelError
from missiontree.perception.colour import dominant_colour
from missiontree.perception.detectors import Detector, detect_checked
from missiontree.reasoning.phrases import colour_words, find_label, fold_label
from missiontree.reasoning.prompts import parse_description
from missiontree.reasoning.protocols import check_image
from missiontree.reasoning.schemas import (
    CropMatch,
    ObjectDescription,
    PersonBox,
    RoomClassification,
    SurveillanceVerdict,
)
from missiontree.types import Detection

#: Objects that tell a room's type: the room types of the shipped worlds (NAIS's office has its sofa).
ROOM_OBJECTS: dict[str, tuple[str, ...]] = {
    "kitchen": ("sink", "refrigerator", "microwave", "oven", "counter", "dining table", "cup", "bottle",
                "stool", "bowl"),
    "office": ("laptop", "printer", "bookshelf", "desk", "monitor", "keyboard", "book", "chair", "sofa",
               "tv"),
    "corridor": ("door", "fire extinguisher", "bench", "trash can"),
    "hall": ("pillar", "notice board", "umbrella", "potted plant"),
    "bedroom": ("bed", "wardrobe"),
    "bathroom": ("toilet", "bathtub", "shower"),
}

#: Typical size of a class relative to a room (what a describer would say).
TYPICAL_SIZE: dict[str, str] = {
    "cup": "small", "bottle": "small", "book": "small", "laptop": "small", "umbrella": "medium",
    "backpack": "medium", "chair": "medium", "potted plant": "medium", "tv": "medium", "sink": "medium",
    "person": "large", "sofa": "large", "bed": "large", "table": "large", "refrigerator": "large",
}

#: Inner fraction of a box whose colour is measured (a box holds background at its edges).
INNER = 0.6


class OfflineVisionModel:
    """A :class:`VisionLanguageModel` stand-in built on a detector (see module docstring).

    Args:
        detector: The detector that sees for it.
        min_score: Detections below this score are ignored.
        colour_share: Least share of a box's inner pixels that must have the asked colour.
        room_objects: Room type → labels that vote for it.
        person_label: The detector's label for people.
        name: Provider name for events and errors.
    """

    def __init__(
        self,
        detector: Detector,
        min_score: float = 0.5,
        colour_share: float = 0.3,
        room_objects: Mapping[str, Sequence[str]] | None = None,
        person_label: str = "person",
        name: str = "offline_vlm",
    ) -> None:
        self.name = name
        self.detector = detector
        self.min_score = float(min_score)
        self.colour_share = float(colour_share)
        self.room_objects = {k: tuple(v) for k, v in (room_objects or ROOM_OBJECTS).items()}
        self.person_label = person_label
        self._people_labels: tuple[str, ...] | None = None

    def check(self) -> str:
        """Check the detector (its ``check()``, else a run on a blank frame); return one line."""
        check = getattr(self.detector, "check", None)
        if callable(check):
            check()
        else:
            self.detector.detect(np.zeros((64, 64, 3), dtype=np.uint8))
        labels = list(getattr(self.detector, "labels", []) or [])
        return (f"offline VLM stand-in on detector {getattr(self.detector, 'name', '?')!r} "
                f"({len(labels)} labels)")

    def ask(self, images: Sequence[np.ndarray], prompt: str, schema: type[BaseModel] | None = None) -> str:
        """Answer ``prompt`` about the first image (see module docstring for what it can answer)."""
        if isinstance(images, np.ndarray):
            images = [images]
        if not images:
            raise ModelError(f"{self.name}: expected at least one image, found none; pass [frame.color]")
        image = check_image(images[0], self.name)
        if schema is SurveillanceVerdict:
            return self.surveillance(image).model_dump_json()
        if schema is CropMatch:
            return self.crop_match(image, self._description(prompt)).model_dump_json()
        if schema is RoomClassification:
            return self.room(image).model_dump_json()
        if schema is ObjectDescription:
            return self.describe(image, parse_description(prompt)).model_dump_json()
        if schema is not None:
            raise ModelError(
                f"{self.name}: cannot answer with the {schema.__name__} schema (it answers "
                "SurveillanceVerdict, CropMatch, RoomClassification, ObjectDescription); "
                "configure a VLM provider (openai) for this question")
        if "PERSON" in prompt.upper():
            return self.surveillance(image).as_text()
        seen = self._detections(image)
        return "I see " + (", ".join(f"a {d.label}" for d in seen) if seen else "nothing I know") + "."

    # -- answers ---------------------------------------------------------------------------------

    def surveillance(self, image: np.ndarray) -> SurveillanceVerdict:
        """ALARM when a person is detected, with their boxes; SAFE otherwise.

        The detector's banded mirror pass is asked about people only: a candidate of another class
        in its band cannot change this verdict.
        """
        seen = self._detections(image, band_labels=self._person_labels())
        people = [d for d in seen if fold_label(d.label) == fold_label(self.person_label)]
        boxes = [PersonBox(box=tuple(float(v) for v in d.box), score=round(float(d.score), 4))
                 for d in people]
        if people:
            where = _position(people[0].center[0], image.shape[1])
            text = f"{'A person is' if len(people) == 1 else f'{len(people)} people are'} in view, {where}."
            return SurveillanceVerdict(verdict="ALARM", description=text, people=boxes)
        others = sorted({d.label for d in seen})
        text = f"No person in view; I see {', '.join(others)}." if others else "No person in view."
        return SurveillanceVerdict(verdict="SAFE", description=text)

    def crop_match(self, image: np.ndarray, description: str) -> CropMatch:
        """Whether ``image`` shows the described object (label and colour)."""
        labels = list(getattr(self.detector, "labels", []) or [])
        found = find_label(description, labels) if labels else None
        if found is None:
            return CropMatch(matches=False, confidence=0.0, reason=(
                f"cannot tell: the detector knows no class in {description!r} "
                f"(it knows {', '.join(labels[:12]) or 'nothing'})"))
        wanted = found[0]
        colours = colour_words(description)
        seen = [d for d in self._detections(image) if fold_label(d.label) == fold_label(wanted)]
        if not seen:
            return CropMatch(matches=False, confidence=0.9, reason=f"no {wanted} detected")
        if not colours:
            best = max(seen, key=lambda d: d.score)
            return CropMatch(matches=True, confidence=round(float(best.score), 4),
                             reason=f"a {wanted} detected (score {best.score:.2f})")
        # Several objects of the class may be in view: the one that has the asked colour decides.
        measured_all = []
        for d in seen:
            reading = dominant_colour(image, d.box, d.mask, inner=INNER)
            shares = reading.shares if reading is not None else {}
            measured_all.append((max(shares.get(c, 0.0) for c in colours), float(d.score), d, reading))
        share, _, best, reading = max(measured_all, key=lambda m: (m[0], m[1]))
        measured = reading.name if reading is not None else "unknown"
        if share >= self.colour_share:
            return CropMatch(matches=True, confidence=round(float(best.score) * min(1.0, share / 0.5), 4),
                             reason=f"a {'/'.join(colours)} {wanted} ({share:.0%} of the box)")
        return CropMatch(matches=False, confidence=round(float(best.score), 4),
                         reason=f"a {wanted}, but {measured}, not {'/'.join(colours)} "
                                f"({share:.0%} of the box)")

    def room(self, image: np.ndarray) -> RoomClassification:
        """The room type the detected objects vote for."""
        votes: dict[str, float] = {}
        evidence: dict[str, list[str]] = {}
        height = float(image.shape[0])
        for d in self._detections(image):
            weight = float(d.score) * max(d.box[3] - d.box[1], 1.0) / height
            for room, labels in self.room_objects.items():
                if fold_label(d.label) in {fold_label(x) for x in labels}:
                    votes[room] = votes.get(room, 0.0) + weight
                    evidence.setdefault(room, []).append(d.label)
        if not votes:
            return RoomClassification(room_type="unknown", confidence=0.0, evidence=[])
        best = max(sorted(votes), key=lambda r: votes[r])
        return RoomClassification(room_type=best, confidence=round(votes[best] / sum(votes.values()), 4),
                                  evidence=sorted(set(evidence[best])))

    def describe(self, image: np.ndarray, label: str | None) -> ObjectDescription:
        """Label, colour, typical size and shape of the main object in ``image``."""
        seen = self._detections(image)
        if label:
            named = [d for d in seen if fold_label(d.label) == fold_label(label)]
            seen = named or seen
        height, width = image.shape[:2]
        if seen:
            best = max(seen, key=lambda d: (d.box[2] - d.box[0]) * (d.box[3] - d.box[1]) * d.score)
            box: tuple[float, float, float, float] = best.box
            name, mask = best.label, best.mask
        else:
            box, name, mask = (0.0, 0.0, float(width), float(height)), label or "object", None
        reading = dominant_colour(image, box, mask, inner=INNER)
        colour = reading.name if reading is not None else "unknown"
        aspect = (box[3] - box[1]) / max(box[2] - box[0], 1e-6)
        shape = "tall" if aspect > 1.6 else "flat" if aspect < 0.6 else "boxy"
        size = TYPICAL_SIZE.get(fold_label(name), "medium")
        return ObjectDescription(label=name, colour=colour, size=size, shape=shape,
                                 description=f"A {colour} {name}, {shape}.")

    # -- helpers ---------------------------------------------------------------------------------

    def _person_labels(self) -> tuple[str, ...]:
        """The detector's labels that name a person (folded as the verdict folds them), found once."""
        if self._people_labels is None:
            wanted = fold_label(self.person_label)
            self._people_labels = tuple(
                label for label in getattr(self.detector, "labels", []) or [] if fold_label(label) == wanted)
        return self._people_labels

    def _detections(self, image: np.ndarray, band_labels: tuple[str, ...] | None = None) -> list[Detection]:
        # The detector is a model too: non-finite or out-of-image boxes are dropped, the rest clipped.
        found = detect_checked(self.detector, image, band_labels=band_labels)
        return [d for d in found if d.score >= self.min_score]

    def _description(self, prompt: str) -> str:
        description = parse_description(prompt)
        if not description:
            raise ModelError(
                f"{self.name}: the crop-match prompt quotes no description; build it with "
                "missiontree.reasoning.prompts.crop_match_prompt('grey backpack')")
        return description


def _position(u: float, width: int) -> str:
    third = width / 3.0
    return "on the left" if u < third else "on the right" if u >= 2 * third else "in the centre"
