"""What the fusion knows between frames: the state its helpers (absence, merging) read and change.

:class:`FusionState` holds the semantic map, the fusion's parameters, a :class:`Track` per instance
(what the fusion remembers of it besides the instance itself), the candidates' voting and the
latest frame's stamp and intrinsics. :class:`~missiontree.semantics.fusion.InstanceFusion` is a
``FusionState`` that processes frames; :class:`~missiontree.semantics.absence.AbsenceJudge` and
:class:`~missiontree.semantics.merge.InstanceMerger` are given it and import only this module, so
the three never import each other.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field

from missiontree.perception.footprint import outline_centre
from missiontree.perception.tracking import Candidate, TemporalVoting
from missiontree.semantics.fusion_params import FusionParams
from missiontree.semantics.semantic_map import Instance, SemanticMap
from missiontree.types import CameraIntrinsics

__all__ = ["FusionState", "Track", "majority"]


@dataclass
class Track:
    """What the fusion remembers of an instance besides the instance itself."""

    colours: Counter[str] = field(default_factory=Counter)
    xs: list[tuple[float, float, float]] = field(default_factory=list)
    sizes: list[tuple[float, float, float]] = field(default_factory=list)
    empty_seen: float = -math.inf
    unexplained: int = 0
    clipped: list[tuple[float, float, float]] = field(default_factory=list)
    cells: Counter[tuple[int, int]] = field(default_factory=Counter)
    checked: float = -math.inf
    #: Each class's score summed over the boxes that refined the instance (its class evidence).
    evidence: Counter[str] = field(default_factory=Counter)
    #: Labels the detector gives this instance besides its own (it was relabelled from them).
    seen_as: set[str] = field(default_factory=set)
    #: Views that refined it judged for an instance of its label behind it in the box, and the
    #: instances found so (:meth:`.merge.InstanceMerger.note_fronted`).
    judged: int = 0
    fronted: Counter[str] = field(default_factory=Counter)
    #: Places where boxes of its label fell on something before it (a removed front instance).
    shadows: list[tuple[float, float]] = field(default_factory=list)


_NO_TRACK = Track()


def majority(votes: Counter[str], default: str) -> str:
    """The most voted name (ties by name), ``default`` without votes."""
    if not votes:
        return default
    return sorted(votes.items(), key=lambda kv: (-kv[1], kv[0]))[0][0]


class FusionState:
    """The semantic map with what the fusion remembers of its instances and candidates."""

    def __init__(
        self, semantic_map: SemanticMap | None, params: FusionParams | None, voting: TemporalVoting
    ) -> None:
        self.map = semantic_map if semantic_map is not None else SemanticMap()
        self.params = params or FusionParams()
        self.voting = voting
        self.tracks: dict[str, Track] = {}
        #: Colour votes of each candidate's boxes, by the candidate's id().
        self.candidate_colours: dict[int, Counter[str]] = {}
        #: Stamp of the latest frame processed.
        self.last_stamp = -math.inf
        #: Intrinsics of the latest frame (None before the first).
        self.intrinsics: CameraIntrinsics | None = None
        self.image_width = 0

    def track(self, instance_id: str) -> Track:
        """What the fusion remembers of an instance besides the instance (made on first use)."""
        return self.tracks.setdefault(instance_id, Track())

    def new_track(self) -> Track:
        """An empty track (for an instance that takes another's place)."""
        return Track()

    def instances_labelled(self, label: str) -> list[Instance]:
        """Instances a box of ``label`` may show (of that label, or relabelled from it)."""
        return [i for i in self.map if i.label == label or label in self.tracks.get(i.id, _NO_TRACK).seen_as]

    def labels_of(self, inst: Instance) -> set[str]:
        """The labels a box showing ``inst`` may carry: its own and those it was relabelled from."""
        return {inst.label} | self.tracks.get(inst.id, _NO_TRACK).seen_as

    def candidate_colour(self, cand: Candidate) -> str:
        """The colour most of a candidate's boxes showed so far (``unknown`` without votes)."""
        return majority(self.candidate_colours.get(id(cand), Counter()), "unknown")

    def outline_centre(
        self, track: Track, fused: tuple[float, ...], inst: Instance
    ) -> tuple[float, float] | None:
        """The centre of the footprint its surface cells outline (footprint's ``outline_centre``).

        Cells of smaller instances that are not large are left out (see ``explained_margin``).
        """
        extent = max(inst.size[0], inst.size[1])
        margin = self.params.explained_margin
        others = [] if margin is None else [
            (o.position[0], o.position[1], 0.5 * max(o.size[0], o.size[1]) + margin)
            for o in self.map
            if o.id != inst.id and max(o.size[0], o.size[1]) < min(extent, self.params.large_size)
        ]
        return outline_centre(
            track.cells, fused, extent, self.params.surface_cell, others, self.params.outline_margin
        )
