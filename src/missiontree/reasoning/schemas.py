"""Pydantic schemas of the structured answers missions ask models for.

Each schema is sent to the model as a JSON schema (OpenAI ``response_format: json_schema``) and the
answer is validated against it (:mod:`missiontree.reasoning.checks`). A schema whose answer names
scene objects implements ``named_ids()``; the checks reject ids the caller's map does not hold.

- :class:`SurveillanceVerdict` — the patrol-robot thesis: "ALARM: PERSON DETECTED" or "SAFE", plus
  people boxes.
- :class:`CropMatch` — does an image crop show "grey backpack"? (object search verification).
- :class:`RoomClassification` — which room type an image shows (the NAIS paper, node 3).
- :class:`ObjectDescription` — colour, size and shape of an object crop (the NAIS paper, node 3).
- :class:`ReferenceParse` — a referential phrase as label + attributes + spatial relation.
- :class:`IntentResolution` — the scene objects that satisfy a request, by id (the NAIS paper, node 5).

Model answers are trusted no further than they are checked: every number must be finite (NaN and
infinity, which Python's JSON reader accepts, are refused), free text is cut to
:data:`MAX_TEXT` characters, lists are bounded, and an answer with boxes is checked against the
image it is about (:meth:`_Answer.image_problems`, :meth:`_Answer.fit_to_image`): a box wholly
outside the image is a wrong answer; one reaching past the border is clipped to it.
"""

from __future__ import annotations

import math
from typing import Literal, Self

from pydantic import BaseModel, ConfigDict, Field, field_validator

#: Room types the shipped worlds and the offline stand-in use; models may answer others.
ROOM_TYPES = ("kitchen", "office", "corridor", "hall", "living_room", "bedroom", "bathroom", "storage",
              "unknown")

#: Spatial relations a reference may use (the NAIS paper: "the laptop in front of the sofa").
RELATIONS = ("near", "next_to", "in_front_of", "behind", "left_of", "right_of", "on", "in")

#: Longest free text kept from an answer (longer text is cut: it only travels to logs and alarms).
MAX_TEXT = 500
#: Most people, candidates or evidence items an answer may list.
MAX_ITEMS = 50


def _cut(value: object) -> object:
    return value[:MAX_TEXT] if isinstance(value, str) else value


class _Answer(BaseModel):
    """Base of answers: unknown keys are refused so a wrong schema cannot pass as a right one."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    def named_ids(self) -> list[str]:
        """Scene object ids this answer names (checked against the caller's map); none by default."""
        return []

    def image_problems(self, width: int, height: int) -> list[str]:
        """Why this answer cannot be about a ``width`` x ``height`` image (boxes outside it); none here."""
        return []

    def fit_to_image(self, width: int, height: int) -> Self:
        """This answer with its boxes clipped to a ``width`` x ``height`` image; itself by default."""
        return self


class PersonBox(_Answer):
    """A person seen in the image."""

    box: tuple[float, float, float, float] = Field(
        description="Bounding box (x1, y1, x2, y2) in pixels of the image asked about.")
    score: float = Field(1.0, ge=0.0, le=1.0, description="Confidence in [0, 1].")

    @field_validator("box")
    @classmethod
    def _ordered(cls, box: tuple[float, float, float, float]) -> tuple[float, float, float, float]:
        if not all(math.isfinite(v) for v in box):
            raise ValueError(f"expected finite pixel coordinates, found {box}")
        if box[2] < box[0] or box[3] < box[1]:
            raise ValueError(f"expected x1 <= x2 and y1 <= y2, found {box}")
        return box

    def outside(self, width: int, height: int) -> bool:
        """True when the box holds no pixel of a ``width`` x ``height`` image."""
        x1, y1, x2, y2 = self.box
        return x2 <= 0 or y2 <= 0 or x1 >= width or y1 >= height or x2 <= x1 or y2 <= y1

    def clipped(self, width: int, height: int) -> PersonBox:
        """The box clipped to a ``width`` x ``height`` image."""
        x1, y1, x2, y2 = self.box
        box = (min(max(x1, 0.0), width), min(max(y1, 0.0), height),
               min(max(x2, 0.0), width), min(max(y2, 0.0), height))
        return self if box == self.box else PersonBox(box=box, score=self.score)


class SurveillanceVerdict(_Answer):
    """The patrol-robot thesis's security check: ALARM when a person (even partly visible) is in the image."""

    verdict: Literal["ALARM", "SAFE"] = Field(
        description="ALARM if a person is visible, even incompletely (legs, an arm); else SAFE.")
    description: str = Field("", description="One sentence describing what is seen.")
    people: list[PersonBox] = Field(default_factory=list, max_length=MAX_ITEMS,
                                    description="Boxes of the people seen, in pixels of the image.")

    _cut_description = field_validator("description", mode="before")(_cut)

    def image_problems(self, width: int, height: int) -> list[str]:
        """The people boxes that lie wholly outside a ``width`` x ``height`` image."""
        return [f"people.{i}.box {list(p.box)} lies outside the {width}x{height} image"
                for i, p in enumerate(self.people) if p.outside(width, height)]

    def fit_to_image(self, width: int, height: int) -> SurveillanceVerdict:
        """The verdict with its people boxes clipped to the image."""
        people = [p.clipped(width, height) for p in self.people]
        if all(a is b for a, b in zip(people, self.people, strict=True)):
            return self
        return self.model_copy(update={"people": people})

    @property
    def alarm(self) -> bool:
        """True when a person was reported."""
        return self.verdict == "ALARM"

    def as_text(self) -> str:
        """The answer in the patrol-robot thesis's form ("ALARM: PERSON DETECTED ..." / "SAFE: ...")."""
        head = "ALARM: PERSON DETECTED" if self.alarm else "SAFE:"
        return f"{head} {self.description}".strip()

    @classmethod
    def from_text(cls, text: str) -> SurveillanceVerdict:
        """Read the patrol-robot thesis's free-text answer: ALARM when it starts with or contains "ALARM"."""
        stripped = text.strip()
        alarm = stripped.upper().startswith("ALARM") or "ALARM" in stripped.upper().split(".")[0]
        for prefix in ("ALARM: PERSON DETECTED", "ALARM:", "SAFE:", "SAFE"):
            if stripped.upper().startswith(prefix):
                stripped = stripped[len(prefix):].strip(" .:-")
                break
        return cls(verdict="ALARM" if alarm else "SAFE", description=stripped)


class CropMatch(_Answer):
    """Whether an image crop shows the described object (the object-search report's verification)."""

    matches: bool = Field(description="True if the image shows the described object.")
    confidence: float = Field(ge=0.0, le=1.0, description="Confidence in [0, 1].")
    reason: str = Field("", description="Short reason, e.g. the colour and object seen.")

    _cut_reason = field_validator("reason", mode="before")(_cut)


class RoomClassification(_Answer):
    """The room type an image shows (NAIS room classification prompt)."""

    room_type: str = Field(description=f"One of {', '.join(ROOM_TYPES)} (or another short snake_case name).")
    confidence: float = Field(ge=0.0, le=1.0, description="Confidence in [0, 1].")
    evidence: list[str] = Field(default_factory=list, max_length=MAX_ITEMS,
                                description="Objects or cues that decided it.")

    @field_validator("room_type")
    @classmethod
    def _normalised(cls, value: str) -> str:
        name = value.strip().lower().replace(" ", "_").replace("-", "_")
        if not name:
            raise ValueError("expected a room type, found an empty string")
        return name


class ObjectDescription(_Answer):
    """Colour, size and shape of an object crop (NAIS object description prompt)."""

    label: str = Field(description="Object class, e.g. backpack.")
    colour: str = Field(description="Main colour name, e.g. grey.")
    size: Literal["small", "medium", "large"] = Field(description="Size relative to the room.")
    shape: str = Field(description="Shape in a word or two, e.g. boxy, round, tall.")
    description: str = Field("", description="One sentence description.")

    _cut_description = field_validator("description", mode="before")(_cut)


class ReferenceParse(_Answer):
    """A referential phrase parsed: "the grey backpack in front of the sofa"."""

    label: str = Field(description="Object class referred to, e.g. backpack.")
    attributes: list[str] = Field(default_factory=list, description="Attributes such as colours.")
    relation: Literal[RELATIONS] | None = Field(  # type: ignore[valid-type]
        None, description="Spatial relation to an anchor object, if any.")
    anchor: str | None = Field(None, description="Class of the anchor object, if any.")


class IntentResolution(_Answer):
    """The scene objects that satisfy a request, best first (NAIS interpretation node)."""

    candidates: list[str] = Field(max_length=MAX_ITEMS,
                                  description="Ids of scene objects that satisfy the request, best first.")
    reason: str = Field("", description="Why these objects satisfy the request.")

    _cut_reason = field_validator("reason", mode="before")(_cut)
    reference: ReferenceParse | None = Field(
        None, description="The parsed reference, for referential requests.")

    def named_ids(self) -> list[str]:
        """The candidate ids."""
        return list(self.candidates)
