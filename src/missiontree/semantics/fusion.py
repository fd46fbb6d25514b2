"""Fusing projected detections into the semantic map, and keeping it true when things move.

:class:`InstanceFusion` takes each frame's detections in the map frame
(:mod:`missiontree.perception.projection`) and:

1. drops what the NAIS paper's single-frame filters drop (confidence, dynamic classes, range;
   :mod:`missiontree.perception.tracking`);
2. associates each projection with an instance of its label within ``associate_radius`` (or half
   the instance's size, for big furniture) and refines it: running mean position (the newest
   ``memory`` observations), size, colour votes (the box's pixels, :mod:`missiontree.perception.colour`),
   observation count, confidence, last seen;
3. votes the rest as candidates, accepted after ``min_frames`` frames (the paper's 10) and, with a
   ``verifier`` (the vision-language model on a crop 20 % larger than the box), only when it does
   not say the crop shows something else (a turned-down candidate starts its voting again);
   boxes cut by the image's side border count as observations but place nothing while uncut views
   exist (their centre is not the object's);
4. judges, through its :class:`~missiontree.semantics.absence.AbsenceJudge` (``absence``), every
   instance the frame should show and did not: misses, removals, and moves of an object of the same
   label and colour confirmed elsewhere while its old place is seen empty.
5. joins, through its :class:`~missiontree.semantics.merge.InstanceMerger` (``merger``), instances
   that are one object seen twice.

Its parameters are :class:`~missiontree.semantics.fusion_params.FusionParams` (re-exported here).
Every decision changes the :class:`~missiontree.semantics.semantic_map.SemanticMap`, which records
the changes. Nothing here reads ground truth.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable

import numpy as np

from missiontree.perception.colour import box_colour
from missiontree.perception.detectors import CLASS_SCORES
from missiontree.perception.footprint import (
    footprint_sides,
    plausible_size,
    size_likelihood,
    stands_out,
    surface_cells,
)
from missiontree.perception.projection import Projection, to_camera
from missiontree.perception.tracking import Candidate, NaisTracker, TemporalVoting
from missiontree.semantics.absence import AbsenceJudge
from missiontree.semantics.fusion_params import FusionParams
from missiontree.semantics.fusion_state import FusionState, Track, majority
from missiontree.semantics.merge import InstanceMerger
from missiontree.semantics.semantic_map import Instance, SemanticMap
from missiontree.types import Detection, RGBDFrame

#: Inner share of a box whose pixels name its colour (a box holds background at its edges).
COLOUR_INNER = 0.6
#: Second opinion on a candidate before it becomes an instance: (frame, its detection in it) →
#: True (it is what the detector said), False (it is not: rejected), None (cannot tell: accepted).
Verifier = Callable[[RGBDFrame, Detection], "bool | None"]

__all__ = ["COLOUR_INNER", "FusionParams", "InstanceFusion", "Verifier"]


class InstanceFusion(FusionState):
    """Projected detections → instances of a :class:`SemanticMap` (see module docstring)."""

    def __init__(
        self,
        semantic_map: SemanticMap | None = None,
        params: FusionParams | None = None,
        verifier: Verifier | None = None,
    ) -> None:
        params = params or FusionParams()
        f = params.filters
        voting = TemporalVoting(
            f.min_frames,
            f.candidate_radius,
            max(f.candidate_timeout, params.candidate_memory),
            size_aware=True,
            required=self._frames_needed,
            ready=self._whole_enough,
            reach=self._small_reach,
        )
        super().__init__(semantic_map, params, voting)
        self.verifier = verifier
        #: Candidates the verifier turned down, per label.
        self.rejected: Counter[str] = Counter()
        self._filters = NaisTracker(f)  # only its single-frame filters and counters are used
        self.frames = 0
        #: Whether each voting projection's box stands out in depth (by id; see _stands_out).
        self._bounded: dict[int, bool] = {}
        #: Instance id → the detection that showed it in the latest frame (for crops to describe).
        self.observed: dict[str, Detection] = {}
        #: Misses, removals and moves of its instances (:mod:`missiontree.semantics.absence`).
        self.absence = AbsenceJudge(self)
        #: Joins instances that are one object (:mod:`missiontree.semantics.merge`).
        self.merger = InstanceMerger(self)

    @property
    def dropped(self) -> dict[str, int]:
        """Projections each single-frame filter dropped so far."""
        return self._filters.dropped

    # -- one frame -------------------------------------------------------------------------------

    def process(
        self, frame: RGBDFrame, projections: list[Projection], detections: list[Detection] | None = None
    ) -> None:
        """Fuse one frame's projections and judge what it should have shown (a frame already seen is ignored).

        Args:
            frame: The frame (pixels for colour, depth and intrinsics for visibility).
            projections: Its detections placed in the map
                (:func:`~missiontree.perception.projection.project`).
            detections: All its detections (boxes that explain an instance even without depth);
                default: those of ``projections``.
        """
        if frame.stamp <= self.last_stamp:
            return  # a frame seen already (or older): its votes are counted
        self.last_stamp = frame.stamp
        self.image_width = frame.intrinsics.width
        self.intrinsics = frame.intrinsics
        self.frames += 1
        self.observed = {}
        stamp = frame.stamp
        kept = [p for p in projections if self._filters.accept(p) and self._off_floor(p)]
        live = {id(q) for c in self.voting.candidates for q in c.projections}
        self._bounded = {k: v for k, v in self._bounded.items() if k in live}
        for p in kept:
            self._bounded[id(p)] = self._stands_out(frame, p)
        seen: set[str] = set()
        for p in sorted(kept, key=lambda q: -q.score):
            colour = _colour(frame, p.detection, p.depth)
            instance = self._associate(p, seen)
            if instance is not None:
                self._observe(instance, p, colour, frame, seen)
            elif not self.merger.shadowed(p):  # else its depth fell on something before an instance
                self._vote(p, colour, frame, seen)
        by_box = {id(p.detection): p for p in kept}
        self.merger.note_fronted({i: by_box[id(d)] for i, d in self.observed.items() if id(d) in by_box})
        boxes = detections if detections is not None else [p.detection for p in projections]
        floor_score = self.params.filters.min_confidence * 0.7
        self.absence.judge_unseen(frame, seen, [d for d in boxes if d.score >= floor_score])
        if self.frames % 5 == 0:
            self.merge_overlapping(stamp)
        live = {id(c) for c in self.voting.candidates}
        for key in [k for k in self.candidate_colours if k not in live]:
            del self.candidate_colours[key]

    def _observe(
        self, instance: Instance, p: Projection, colour: str | None, frame: RGBDFrame, seen: set[str]
    ) -> None:
        """Refine ``instance`` with ``p`` (relabelled if needed) and join what the box also holds."""
        self._refine(instance, p, colour, frame)
        instance = self._reconsider_label(instance, frame.stamp)
        seen.add(instance.id)
        self.observed[instance.id] = p.detection
        for other in self._held_by_box(p, instance, seen):
            kept_id = self.merger.merge_pair(instance, other, frame.stamp)
            if kept_id != instance.id:  # the other was seen more often: it stays
                seen.discard(instance.id)
                self.observed.pop(instance.id, None)
                seen.add(kept_id)
                self.observed[kept_id] = p.detection
                break

    def _vote(self, p: Projection, colour: str | None, frame: RGBDFrame, seen: set[str]) -> None:
        """Count ``p`` for its candidate; confirm the candidate once the votes and the verifier allow."""
        cand = self.voting.vote(p)
        votes = self.candidate_colours.setdefault(id(self._candidate_of(p, cand)), Counter())
        if colour:
            votes[colour] += 1
        if cand is None:
            return
        colours = self.candidate_colours.pop(id(cand), Counter())
        if self.verifier is not None and self.verifier(frame, p.detection) is False:
            self.rejected[cand.label] += 1  # voting starts again: a later frame may convince
            return
        new = self._confirm(cand, colours, frame.stamp)
        seen.add(new.id)
        self.observed[new.id] = p.detection

    def _off_floor(self, p: Projection) -> bool:
        if p.position[2] >= self.params.min_elevation:
            return True
        self.dropped["floor"] = self.dropped.get("floor", 0) + 1
        return False

    # -- association and refinement --------------------------------------------------------------

    def _small_reach(self, p: Projection) -> float | None:
        """``small_radius`` for a projection at most ``small_width`` wide, else None (see FusionParams)."""
        if self.params.small_radius is None or p.size[0] > self.params.small_width:
            return None
        return self.params.small_radius

    def _associate(self, p: Projection, taken: set[str]) -> Instance | None:
        best, best_d = None, math.inf
        small = self._small_reach(p)
        for inst in self.instances_labelled(p.label):
            if inst.id in taken:
                continue
            radius = max(self.params.associate_radius, 0.5 * max(inst.size[0], inst.size[1]))
            if small is not None and max(inst.size[0], inst.size[1]) <= self.params.small_width:
                radius = small
            d = inst.distance_to(*p.xy)
            if d <= radius and d < best_d:
                best, best_d = inst, d
        if best is not None:
            return best
        offsets = [(self._box_offset(p, i), i) for i in self.instances_labelled(p.label) if i.id not in taken]
        held = [(off, inst) for off, inst in offsets if off is not None]
        return min(held, key=lambda e: e[0])[1] if held else None

    def _large(self, p: Projection, inst: Instance) -> bool:
        return max(inst.size[0], inst.size[1], p.size[0]) >= self.params.large_size

    def _box_offset(self, p: Projection, inst: Instance) -> float | None:
        """How far from the box's middle a large instance's centre falls (share of its width), None: outside.

        Inside means: in the box's inner part (``inner_share`` off each side, unless that side is cut
        by the image border) and at a depth between the box's measured surface and that surface
        plus the instance's extent.
        """
        k = self.intrinsics
        if k is None or not self._large(p, inst):
            return None
        forward, left = to_camera(p.camera_pose, *inst.xy)
        if forward <= 0.2:
            return None
        u = k.cx - left * k.fx / forward
        x1, _, x2, _ = p.box
        width = max(x2 - x1, 1.0)
        limit = self.params.edge_clip
        lo = x1 if x1 <= limit else x1 + self.params.inner_share * width
        hi = x2 if x2 >= k.width - limit else x2 - self.params.inner_share * width
        if not lo <= u <= hi:
            return None
        extent = max(inst.size[0], inst.size[1], p.size[0])
        tolerance = self.params.depth_tolerance
        if not p.depth - tolerance <= forward <= p.depth + extent + tolerance:
            return None
        return abs(u - (x1 + x2) / 2.0) / width

    def _held_by_box(self, p: Projection, inst: Instance, taken: set[str]) -> list[Instance]:
        """Other instances of the label whose centres ``p``'s box holds with ``inst``'s: one object."""
        if self._box_offset(p, inst) is None:
            return []
        return [
            other
            for other in self.map.by_label(p.label)
            if other.id != inst.id
            and other.id not in taken
            and self._box_offset(p, other) is not None
            and not self._side_by_side(inst, other)
        ]

    def _median_width(self, inst: Instance) -> float:
        """The instance's median measured width over its boxes (its largest, without a track)."""
        track = self.tracks.get(inst.id)
        if track is None or not track.sizes:
            return max(inst.size[0], inst.size[1])
        return float(np.median([s[0] for s in track.sizes]))

    def _side_by_side(self, a: Instance, b: Instance) -> bool:
        """Whether two instances of a label are two small objects standing apart (see ``apart_share``)."""
        share, large = self.params.apart_share, self.params.large_size
        if share is None:
            return False
        wa, wb = self._median_width(a), self._median_width(b)
        return max(wa, wb) < large and a.distance_to(*b.xy) > share * (wa + wb)

    def _frames_needed(self, cand: Candidate) -> int:
        """Frames a candidate needs: fewer for a small one (see ``small_min_frames``)."""
        need = self.params.filters.min_frames
        if cand.projections:
            sizes = np.median(np.array([max(q.size[0], q.size[2]) for q in cand.projections]))
            if float(sizes) <= self.params.small_size:
                need = min(need, self.params.small_min_frames)
        if self._views_agree(cand):
            need = max(self.params.view_min_frames, math.ceil(self.params.view_share * need))
        return need

    def _views_agree(self, cand: Candidate) -> bool:
        """Whether its uncut boxes came from places ``view_spread`` apart and placed it in one spot."""
        spread = self.params.view_spread
        uncut = [q for q in cand.projections if not self._clipped(q)]
        if spread is None or len(uncut) < 2:
            return False
        cams = np.array([(q.camera_pose.x, q.camera_pose.y) for q in uncut])
        if float(np.max(np.linalg.norm(cams[:, None, :] - cams[None, :, :], axis=2))) < spread:
            return False
        xy = np.array([q.xy for q in uncut])
        off = np.linalg.norm(xy - np.median(xy, axis=0), axis=1)
        width = float(np.median([q.size[0] for q in uncut]))
        return float(np.median(off)) <= max(self.params.view_agree, 0.25 * width)

    def _stands_out(self, frame: RGBDFrame, p: Projection) -> bool:
        """Whether the box's object stands out in depth at an uncut side (footprint's ``stands_out``)."""
        return stands_out(frame, p.box, self.params.edge_band, self.params.edge_step)

    def _whole_enough(self, cand: Candidate) -> bool:
        """Whether enough of a candidate's boxes stand whole (no side or bottom image border cuts them).

        The top may cut a tall object seen from close (a refrigerator), whose foot is still in view.
        """
        limit = self.params.edge_clip
        bottom = (self.intrinsics.height if self.intrinsics is not None else math.inf) - limit
        whole = sum(1 for q in cand.projections if q.box[3] < bottom and not self._clipped(q))
        share = self.params.min_uncut_share * len(cand.projections)
        enough = whole >= min(self.params.min_uncut, len(cand.projections)) and whole >= share
        judged = [self._bounded[id(q)] for q in cand.projections if id(q) in self._bounded]
        if judged and self.params.min_bounded_share > 0:
            enough = enough and sum(judged) >= self.params.min_bounded_share * len(judged)
        return enough and self._seen_whole(cand) and self._plausible_size(cand)

    def _seen_whole(self, cand: Candidate) -> bool:
        """Whether a large candidate was seen whole once: a box no image border cuts, top included.

        See ``whole_size``; a candidate smaller than it passes.
        """
        limit, size = self.params.edge_clip, self.params.whole_size
        if size is None or not cand.projections or self.intrinsics is None:
            return True
        width = float(np.median([q.size[0] for q in cand.projections]))
        height = float(np.median([q.size[2] for q in cand.projections]))
        if max(width, height) < size:
            return True
        bottom = self.intrinsics.height - limit
        return any(q.box[1] > limit and q.box[3] < bottom and not self._clipped(q) for q in cand.projections)

    def _plausible_size(self, cand: Candidate) -> bool:
        """Whether the candidate's median measured size reaches its class's least size (``SIZE_PRIORS``)."""
        return plausible_size(cand.label, cand.projections, self.params.size_margin)

    def _refine(
        self, inst: Instance, p: Projection, colour: str | None, frame: RGBDFrame | None = None
    ) -> None:
        track = self.tracks.setdefault(inst.id, Track())
        (track.clipped if self._clipped(p) else track.xs).append(p.position)
        track.sizes.append(p.size)
        del track.xs[: -self.params.memory]
        del track.clipped[: -self.params.memory]
        del track.sizes[: -self.params.memory]
        if colour:
            track.colours[colour] += 1
        track.evidence.update(_class_scores(p))
        position = tuple(float(v) for v in np.median(np.array(track.xs or track.clipped), axis=0))
        if frame is not None and self._large(p, inst):
            self._add_surface(track, frame, p)
            outline = self.outline_centre(track, position, inst)
            if outline is not None:
                position = (outline[0], outline[1], position[2])
        elif frame is not None and not self._clipped(p) and self._runner_ups(track):
            self._add_surface(track, frame, p)  # its footprint may tell the runner-up class
        size = tuple(float(v) for v in np.max(np.array(track.sizes), axis=0))
        confidence = inst.confidence + self.params.hit_gain * (1.0 - inst.confidence)
        self.map.update(
            inst.id,
            position=position,
            size=size,
            observations=inst.observations + 1,
            confidence=confidence,
            last_seen=p.stamp,
            misses=0,
            doubtful=False,
            colour=majority(track.colours, inst.colour),
        )
        track.empty_seen = -math.inf
        track.unexplained = 0
        track.checked = p.stamp

    def _add_surface(self, track: Track, frame: RGBDFrame, p: Projection) -> None:
        """Count the cells of the surface the box shows (footprint's ``surface_cells``)."""
        surface_cells(track.cells, frame, p.box, self.params.surface_cell)

    def unconfirmed(self, min_frames: int = 3) -> list[Candidate]:
        """Candidates seen in at least ``min_frames`` frames that are not instances yet: worth a second look.

        A viewpoint too close (the box cut by the image's border) or too far and oblique (a few
        frames of a small object while turning) leaves a true object a candidate; a look from a good
        distance confirms it or shows nothing there. Candidates where an instance of their label
        now stands are left out.
        """
        out = []
        for cand in self.voting.candidates:
            if cand.frames < min_frames:
                continue
            radius = self.params.associate_radius
            if not any(i.distance_to(cand.x, cand.y) <= radius for i in self.instances_labelled(cand.label)):
                out.append(cand)
        return out

    def unchecked_since(self, stamp: float) -> list[Instance]:
        """Instances to look at again since ``stamp`` (:meth:`.AbsenceJudge.unchecked_since`)."""
        return self.absence.unchecked_since(stamp)

    def _clipped(self, p: Projection) -> bool:
        """Whether the box is cut by the image's left or right border."""
        limit = self.params.edge_clip
        return p.box[0] <= limit or (self.image_width > 0 and p.box[2] >= self.image_width - limit)

    def _placing(self, projections: list[Projection]) -> tuple[list[Projection], list[Projection]]:
        """Projections split into uncut and cut boxes."""
        cut = [q for q in projections if self._clipped(q)]
        return [q for q in projections if not self._clipped(q)], cut

    def _candidate_of(self, p: Projection, accepted: Candidate | None) -> Candidate:
        if accepted is not None:
            return accepted
        for cand in self.voting.candidates:
            if cand.label == p.label and cand.last_stamp == p.stamp and cand.projections[-1] is p:
                return cand
        raise RuntimeError("projection voted without a candidate")  # pragma: no cover - voting invariant

    def _confirm(self, cand: Candidate, colours: Counter[str], stamp: float) -> Instance:
        colour = majority(colours, "unknown")
        uncut, cut = self._placing(cand.projections)
        position = (cand.x, cand.y, cand.z)
        if uncut and cut:
            mx, my, mz = np.median(np.array([q.position for q in uncut]), axis=0)  # of (x, y, z) points
            position = (float(mx), float(my), float(mz))
        sizes = np.array([q.size for q in cand.projections])
        size = tuple(float(v) for v in (np.median(sizes, axis=0) if len(sizes) else (0.0, 0.0, 0.0)))
        score = float(np.mean([q.score for q in cand.projections])) if cand.projections else 0.7
        twin = self.absence.seen_empty_twin(cand.label, colour, stamp)
        if twin is not None:
            self.map.move(
                twin.id,
                position,
                stamp,
                reason=f"its place was seen empty and a {colour} {cand.label} was seen here",
            )
            self.map.update(
                twin.id,
                size=size,
                observations=twin.observations + cand.frames,
                confidence=max(twin.confidence, score),
            )
            track = self.tracks.setdefault(twin.id, Track())
            track.xs = [q.position for q in uncut]
            track.clipped = [q.position for q in cut]
            track.empty_seen = -math.inf
            track.checked = stamp
            return twin
        inst = self.map.add(
            cand.label,
            position,
            stamp,
            size=size,
            colour=colour,
            observations=cand.frames,
            confidence=score,
            first_seen=cand.projections[0].stamp if cand.projections else stamp,
            reason=f"seen in {cand.frames} frames",
        )
        evidence: Counter[str] = Counter()
        for q in cand.projections:
            evidence.update(_class_scores(q))
        self.tracks[inst.id] = Track(
            colours=Counter(colours),
            xs=[q.position for q in uncut],
            clipped=[q.position for q in cut],
            sizes=[q.size for q in cand.projections],
            checked=stamp,
            evidence=evidence,
        )
        return inst

    # -- class evidence --------------------------------------------------------------------------

    def _runner_ups(self, track: Track) -> list[tuple[str, float]]:
        """Classes other than the evidence's best whose summed score reaches ``runner_up_share`` of it."""
        ranked = track.evidence.most_common()
        share = self.params.runner_up_share
        if share <= 0 or len(ranked) < 2:
            return []
        top = ranked[0][1]
        return [(label, mass) for label, mass in ranked[1:] if mass >= share * top]

    def _reconsider_label(self, inst: Instance, stamp: float) -> Instance:
        """``inst``, or the instance that replaces it under a runner-up label (see ``runner_up_share``).

        Judged again as evidence comes in: a runner-up chosen early (a table, the only other class
        with score mass after a few views) gives way to one that explains the views better later.
        """
        track = self.tracks.get(inst.id)
        if track is None or inst.observations < self.params.relabel_views or not track.evidence:
            return inst
        if max(inst.size[0], inst.size[1]) >= self.params.large_size:
            return inst  # its surface cells hold its neighbours too: no footprint to judge by
        top = track.evidence.most_common(1)[0][0]
        runner_ups = self._runner_ups(track)
        if not runner_ups:
            return inst  # nothing else has real score mass
        extent = max(inst.size[0], inst.size[1])
        reach = 0.5 * extent + self.params.footprint_reach
        sides = footprint_sides(track.cells, inst.position, reach, self.params.surface_cell)
        if sides is None or not track.sizes:
            return inst  # too few views of its surface yet
        shorter = sides[1]
        height = float(np.median([s[2] for s in track.sizes]))
        if size_likelihood(top, shorter, height) != 0.0:
            return inst  # the named class fits (or its sizes are not known): kept
        best, best_weight = None, 0.0
        for label, mass in runner_ups:
            weight = mass * (size_likelihood(label, shorter, height) or 0.0)
            if weight > best_weight:
                best, best_weight = label, weight
        if best is None or best == inst.label:
            return inst
        why = (
            f"{shorter:.2f} m deep and {height:.2f} m high: too large for a {top}; "
            f"a {best} by its class scores ({track.evidence[best]:.2f} against {track.evidence[top]:.2f})"
        )
        self.map.remove(inst.id, stamp, reason=f"relabelled a {best}: {why}")
        new = self.map.add(
            best,
            inst.position,
            stamp,
            size=inst.size,
            colour=inst.colour,
            observations=inst.observations,
            confidence=inst.confidence,
            first_seen=inst.first_seen,
            reason=f"relabelled from {inst.id}: {why}",
        )
        track.seen_as |= {top, inst.label}
        self.tracks[new.id] = self.tracks.pop(inst.id)
        return new

    def same_object(self, a: Instance, b: Instance) -> bool:
        """Whether two instances are one object seen twice (:meth:`.merge.InstanceMerger.same_object`)."""
        return self.merger.same_object(a, b)

    def merge_overlapping(self, stamp: float) -> None:
        """Join instances that are one object (:meth:`.merge.InstanceMerger.merge_overlapping`)."""
        self.merger.merge_overlapping(stamp)


def _class_scores(p: Projection) -> dict[str, float]:
    """The box's score per class (the detector's ``CLASS_SCORES``), or its label's score alone."""
    scores = p.detection.attributes.get(CLASS_SCORES)
    if isinstance(scores, dict) and scores:
        return {str(k): float(v) for k, v in scores.items()}
    return {p.label: p.score}


def _colour(frame: RGBDFrame, detection: Detection, surface: float | None = None) -> str | None:
    """The box's colour (colour's ``box_colour``: its inner part, at its surface's depth when given)."""
    return box_colour(frame.color, frame.depth, detection.box, detection.mask, surface, COLOUR_INNER)
