"""What the scene graph asks models: crops for descriptions, and the optional semantic-relations pass.

- :func:`expanded_crop` — the NAIS paper's object crop, 20 % larger than the box (clipped to the
  image), for the description prompt (:func:`missiontree.reasoning.prompts.object_description_prompt`
  with the :class:`~missiontree.reasoning.schemas.ObjectDescription` schema). Room types use
  :func:`missiontree.reasoning.prompts.room_prompt` with
  :class:`~missiontree.reasoning.schemas.RoomClassification` on frames taken in the room.
- :func:`crop_verifier` — the second opinion on a new instance before it enters the graph: the
  vision-language model asked (:func:`missiontree.reasoning.prompts.crop_match_prompt`, the
  :class:`~missiontree.reasoning.schemas.CropMatch` schema) whether the 20 % larger crop shows the
  detector's label; a "no" turns the candidate down, an error or unparsable answer leaves the
  decision to the detector.
- :func:`semantic_relations_messages` and :class:`SemanticRelations` — an optional language-model
  pass over the computed graph that may *add* semantic relations ("the laptop belongs to the
  desk"); the answer's edges are checked against the graph and every edge naming a missing node is
  dropped (:meth:`missiontree.semantics.scene_graph.SceneGraph.add_relations`).
"""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from missiontree.errors import ModelError
from missiontree.reasoning.prompts import crop_match_prompt
from missiontree.reasoning.protocols import Message
from missiontree.reasoning.schemas import CropMatch
from missiontree.types import Detection, RGBDFrame

#: How much larger than its box the NAIS paper crops an object for the VLM.
CROP_GROWTH = 0.2

#: The NAIS paper's scene-graph prompt (Listing 1), reduced to what is left for a model to add.
RELATIONS_PROMPT = (
    "You are an expert scene graph architect. You receive a scene graph as JSON with nodes (id, type, "
    "label, description, coordinates) and edges (source_id, source_label, target_id, target_label, "
    "relation). Its 'contains' edges and spatial relations were computed from geometry. Add only "
    "semantic relations between objects that the descriptions support (for example 'belongs to', "
    "'used with'), each with keys source_id, source_label, target_id, target_label and relation, "
    "between objects that exist in the graph. Do NOT create edges to missing entities. "
    "Return ONLY JSON with the key edges."
)


def expanded_crop(
    image: np.ndarray, box: tuple[float, float, float, float], growth: float = CROP_GROWTH
) -> np.ndarray:
    """The crop of ``box`` grown by ``growth`` of its width and height (half each side), clipped.

    Raises:
        ValueError: The box lies outside the image.
    """
    h, w = image.shape[:2]
    bw, bh = box[2] - box[0], box[3] - box[1]
    x1 = int(np.clip(np.floor(box[0] - bw * growth / 2), 0, w))
    x2 = int(np.clip(np.ceil(box[2] + bw * growth / 2), 0, w))
    y1 = int(np.clip(np.floor(box[1] - bh * growth / 2), 0, h))
    y2 = int(np.clip(np.ceil(box[3] + bh * growth / 2), 0, h))
    if x2 <= x1 or y2 <= y1:
        raise ValueError(f"box {box} lies outside the {w}x{h} image; no crop to describe")
    return np.ascontiguousarray(image[y1:y2, x1:x2])


def crop_verifier(vlm: Any, growth: float = CROP_GROWTH) -> Callable[[RGBDFrame, Detection], bool | None]:
    """A verifier for :class:`~missiontree.semantics.fusion.InstanceFusion` backed by ``vlm``.

    Args:
        vlm: A vision-language model (``ask(images, prompt, schema) -> str``).
        growth: How much larger than the box the crop is.

    Returns:
        A function (frame, detection) → True when the model says the crop shows the detection's
        label, False when it says it does not, None when it cannot answer (model error, bad JSON,
        box outside the image).
    """

    def verify(frame: RGBDFrame, detection: Detection) -> bool | None:
        try:
            crop = expanded_crop(frame.color, detection.box, growth)
            text = vlm.ask([crop], crop_match_prompt(detection.label), CropMatch)
            return bool(CropMatch.model_validate_json(text).matches)
        except (ModelError, ValidationError, ValueError):
            return None

    return verify


class RelationEdgeAnswer(BaseModel):
    """One edge a model proposes."""

    model_config = ConfigDict(extra="forbid")

    source_id: str | int
    source_label: str = ""
    target_id: str | int
    target_label: str = ""
    relation: str = Field(min_length=1)


class SemanticRelations(BaseModel):
    """The optional language-model pass's answer: edges to add."""

    model_config = ConfigDict(extra="forbid")

    edges: list[RelationEdgeAnswer] = Field(default_factory=list)

    def named_ids(self) -> list[str]:
        """Every node id the answer names (missing ones are dropped, not fatal, by the graph)."""
        return []


def semantic_relations_messages(graph: Mapping[str, Any]) -> list[Message]:
    """The conversation for the semantic-relations pass over a NAIS-shaped graph dict."""
    return [
        Message("system", RELATIONS_PROMPT),
        Message("user", "Scene graph (JSON):\n```json\n" + json.dumps(graph, ensure_ascii=False) + "\n```"),
    ]
