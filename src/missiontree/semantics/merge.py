"""Joining instances that are one object seen twice.

:class:`InstanceMerger` is held by :class:`~missiontree.semantics.fusion.InstanceFusion`
(``fusion.merger``) and is given only its :class:`~missiontree.semantics.fusion_state.FusionState`
(the semantic map, the per-instance tracks and the parameters). Two instances are one object when:

1. one box of their label holds both centres (a sofa seen end-on from two sides places its near
   faces a metre apart: :meth:`InstanceMerger.merge_pair`, called from the fusion's frame loop);
2. they are of one label and close for their size (:meth:`InstanceMerger.same_object`);
3. they are of two labels the detector gave one object (a cup also boxed as a bottle): their
   centres closer than a quarter of the smaller footprint, or, both small, their footprints
   overlapping, at overlapping heights;
4. one's views nearly all held the other, of its label and seen more often, behind it in the box:
   the box's depth fell on something in front of the object (a door frame, a desk's edge), so it
   is that object again (:meth:`InstanceMerger.drop_fronted`).

Of one label, the instance seen more often stays and takes the other's observations and evidence;
of two, the one with more score mass for its label stays. The other is removed with the reason.
Nothing here reads ground truth.
"""

from __future__ import annotations

import numpy as np

from missiontree.perception.projection import Projection, to_camera
from missiontree.semantics.fusion_state import FusionState, Track
from missiontree.semantics.semantic_map import Instance


class InstanceMerger:
    """Joins a fusion's instances that are one object (see module docstring).

    Args:
        fusion: The fusion whose map, tracks and parameters are read.
    """

    def __init__(self, fusion: FusionState) -> None:
        self.fusion = fusion

    def _absorb(self, keep: Instance, drop: Instance) -> Track:
        """``drop``'s track joined into ``keep``'s (positions, cells, colours, evidence); ``keep``'s track."""
        tracks = self.fusion.tracks
        track = self.fusion.track(keep.id)
        dropped = tracks.pop(drop.id, None) or self.fusion.new_track()
        track.xs.extend(dropped.xs)
        track.clipped.extend(dropped.clipped)
        track.cells.update(dropped.cells)
        track.colours.update(dropped.colours)
        track.evidence.update(dropped.evidence)
        track.seen_as |= dropped.seen_as
        return track

    def _cut_beside(self, a: Instance, b: Instance, d: float) -> bool:
        """Whether two large instances of a label overlap and the less seen one stands on cut boxes.

        Footprints overlap: centres closer than the sum of their half widths. A box cut by the
        image's side places its centre off the object's (a dining table seen at the image's edge
        made a second table at its end, 11 of 14 views cut), so such an instance beside one of its
        label is that one; two objects seen whole stay apart (dining chairs side by side).
        """
        params = self.fusion.params
        wa, wb = max(a.size[0], a.size[1]), max(b.size[0], b.size[1])
        if params.cut_share is None or max(wa, wb) < params.large_size or d > 0.5 * (wa + wb):
            return False
        less = a if a.observations < b.observations else b
        track = self.fusion.tracks.get(less.id)
        if track is None:
            return False
        placed = len(track.xs) + len(track.clipped)
        return placed > 0 and len(track.clipped) >= params.cut_share * placed

    def _mass(self, inst: Instance) -> float:
        """The instance's score mass for its own label (its observations without class evidence)."""
        track = self.fusion.tracks.get(inst.id)
        if track is None or inst.label not in track.evidence:
            return float(inst.observations)
        return float(track.evidence[inst.label])

    def merge_pair(self, keep: Instance, drop: Instance, stamp: float) -> str:
        """One object seen as two instances of its label: the less often seen joins the other; its id."""
        fusion = self.fusion
        if keep.observations < drop.observations:
            keep, drop = drop, keep
        fusion.map.remove(drop.id, stamp, reason=f"the same {drop.label} as {keep.id} (one box holds both)")
        track = self._absorb(keep, drop)
        points = np.array(track.xs or track.clipped or [keep.position])
        position = tuple(float(v) for v in np.median(points, axis=0))
        outline = fusion.outline_centre(track, position, keep)
        if outline is not None:
            position = (outline[0], outline[1], position[2])
        fusion.map.update(keep.id, position=position, observations=keep.observations + drop.observations)
        return keep.id

    def same_object(self, a: Instance, b: Instance) -> bool:
        """Whether two instances are one object seen twice.

        Same label: their centres within 0.9 of the larger half-footprint (``associate_radius`` at
        least), or within half of it when the colours differ (big furniture looks another colour
        from another side); or, large, their footprints overlapping while the less often seen one
        was placed mostly by boxes the image's border cut (see ``cut_share``).
        Different labels (the detector named one object two ways): centres within a quarter of the
        smaller footprint's larger side and heights overlapping over half of the lower one, so a cup
        on a table or a chair beside it stays apart. Two small instances (both at most ``twin_size``
        wide) are one object also when their footprints overlap: centres within ``twin_overlap`` of
        the sum of their half widths (two real objects can at most touch; a bottle box on a cup put
        its centre 4 cm from the cup's, more than a quarter of its 9 cm).
        """
        params = self.fusion.params
        d = a.distance_to(*b.xy)
        wa, wb = max(a.size[0], a.size[1]), max(b.size[0], b.size[1])
        if a.label == b.label and self._cut_beside(a, b, d):
            return True
        if a.label == b.label:
            half = max(0.5 * wa, 0.5 * wb)
            if a.colour == b.colour:
                return d <= 0.9 * max(params.associate_radius, half)
            return d <= 0.5 * half
        limit = 0.25 * min(wa, wb)
        if max(wa, wb) <= params.twin_size:
            limit = max(limit, params.twin_overlap * 0.5 * (wa + wb))
        if d > limit:
            return False
        lo = max(a.position[2] - a.size[2] / 2, b.position[2] - b.size[2] / 2)
        hi = min(a.position[2] + a.size[2] / 2, b.position[2] + b.size[2] / 2)
        return hi - lo >= 0.5 * max(min(a.size[2], b.size[2]), 1e-3)

    # -- an object seen on something in front of it ------------------------------------------------

    def _behind(self, p: Projection, other: Instance) -> bool:
        """Whether ``other``'s centre lies in the inner part of ``p``'s box, ``front_gap`` past its depth."""
        k, params = self.fusion.intrinsics, self.fusion.params
        if k is None:
            return False
        forward, left = to_camera(p.camera_pose, *other.xy)
        if forward <= 0.2 or forward < p.depth + params.front_gap:
            return False
        u = k.cx - left * k.fx / forward
        x1, _, x2, _ = p.box
        inset = params.inner_share * max(x2 - x1, 1.0)
        if not x1 + inset <= u <= x2 - inset:
            return False
        return params.front_fit is None or x2 - x1 <= params.front_fit * self._width_px(other, forward)

    def _width_px(self, inst: Instance, forward: float) -> float:
        """Pixels the instance's median measured width spans at ``forward`` metres from the camera."""
        k = self.fusion.intrinsics
        assert k is not None
        track = self.fusion.tracks.get(inst.id)
        widths = [s[0] for s in track.sizes] if track is not None and track.sizes else [inst.size[0]]
        return float(np.median(widths)) * k.fx / forward

    def note_fronted(self, refined: dict[str, Projection]) -> None:
        """Count, for each instance a frame refined, whether its box held one of its label behind it.

        Args:
            refined: Instance id → the projection that refined it in this frame.
        """
        fusion = self.fusion
        if fusion.params.front_share <= 0:
            return
        for inst_id, p in refined.items():
            inst = fusion.map.get(inst_id)
            if inst is None:
                continue
            track = fusion.track(inst_id)
            track.judged += 1
            for other in fusion.map.by_label(inst.label):
                if other.id in refined or other.observations <= inst.observations:
                    continue
                if self._behind(p, other):
                    track.fronted[other.id] += 1
                    break

    def drop_fronted(self, stamp: float) -> None:
        """Remove instances whose views mostly held another of their label behind them (``front_share``)."""
        fusion = self.fusion
        params = fusion.params
        if params.front_share <= 0:
            return
        for inst in list(fusion.map):
            track = fusion.tracks.get(inst.id)
            if track is None or track.judged < params.front_views or not track.fronted:
                continue
            behind_id, count = track.fronted.most_common(1)[0]
            behind = fusion.map.get(behind_id)
            if behind is None or sum(track.fronted.values()) < params.front_share * track.judged:
                continue
            why = (
                f"the {inst.label} {behind.id} seen on something before it: {count} of the "
                f"{track.judged} views that placed it here held {behind.id} behind in the box"
            )
            fusion.map.remove(inst.id, stamp, reason=why)
            fusion.tracks.pop(inst.id, None)
            fusion.track(behind.id).shadows.append(inst.xy)

    def shadowed(self, p: Projection) -> bool:
        """Whether ``p`` falls where a front instance was removed, its box holding the one behind again."""
        fusion = self.fusion
        radius = fusion.params.associate_radius
        for inst in fusion.map.by_label(p.label):
            shadows = fusion.tracks[inst.id].shadows if inst.id in fusion.tracks else []
            for sx, sy in shadows:
                if abs(p.xy[0] - sx) <= radius and abs(p.xy[1] - sy) <= radius and self._behind(p, inst):
                    return True
        return False

    # -- close instances --------------------------------------------------------------------------

    def merge_overlapping(self, stamp: float) -> None:
        """Join instances that are one object (:meth:`same_object`); the more often seen one stays.

        Instances seen on something in front of another of their label go first (:meth:`drop_fronted`).
        """
        fusion = self.fusion
        self.drop_fronted(stamp)
        items = list(fusion.map)
        gone: set[str] = set()
        for i, a in enumerate(items):
            if a.id in gone:
                continue
            for b in items[i + 1 :]:
                if b.id in gone or not self.same_object(a, b):
                    continue
                keep, drop = (a, b) if a.observations >= b.observations else (b, a)
                if keep.label != drop.label:
                    keep, drop = (a, b) if self._mass(a) >= self._mass(b) else (b, a)
                    why = f"the same object as {keep.id}, seen as a {keep.label} more often"
                    fusion.map.remove(drop.id, stamp, reason=why)
                    fusion.tracks.pop(drop.id, None)
                    gone.add(drop.id)
                    if drop is a:
                        break
                    continue
                fusion.map.remove(drop.id, stamp, reason=f"the same {drop.label} as {keep.id}")
                total = keep.observations + drop.observations
                position = tuple(
                    (keep.position[k] * keep.observations + drop.position[k] * drop.observations) / total
                    for k in range(3)
                )
                fusion.map.update(keep.id, position=position, observations=total)
                self._absorb(keep, drop)
                gone.add(drop.id)
                if drop is a:
                    break
