"""Why the scene-graph benchmark's ``ours`` got an object wrong: each false and missed object with its cause.

``scene_graph_eval.py --diagnose`` records, beside the run, what the simulator's truth says each
frame showed (the instance mask: which object a detection's box really covers, and how many frames
showed each object) and every change the semantic map made. After each phase it prints, per world:

- ``FP``: a graph object matched to no true object, with its cause: ``ignored`` (it stands on an
  object of a class the detector does not know: not counted in precision), ``offset`` (a true object
  of its label within 1.5 m is unmatched: its centre is off), ``duplicate`` (that true object is
  matched by another instance), ``confusion`` (its boxes mostly cover an object of another class),
  ``phantom`` (nothing); with what its boxes covered, how many frames and viewpoints placed it and
  the share of its boxes cut by the image border;
- ``FN``: a true object no graph object matched, with the frames that showed it (>= 100 pixels),
  the detections covering it by label (confident ones), how far their projections fell from it,
  and what the semantic map did near it (added, merged, removed and why);
- ``change``: each change of the dynamic phase, reflected or not, with the graph objects of its label
  near its old and new place.

With ``SCENE_DIAG_DUMP=<folder>`` it also pickles, per world and phase, the fusion's instances and
tracks (positions, surface cells, class evidence), the truth, the sights and the map's changes, to
study merging and centring rules offline on what a run saw.

Truth is read here for the diagnosis only, as for scoring; the pipelines never see it.
"""

from __future__ import annotations

import math
from collections import Counter, defaultdict
from dataclasses import dataclass, field
from typing import Any

from missiontree.perception.projection import project
from missiontree.semantics.semantic_map import Change

#: Pixels an object must show in a frame to count as shown.
SHOWN_PIXELS = 100
#: Print every occluded verdict (debugging one world).
DETAIL = bool(__import__("os").environ.get("SCENE_DIAG_DETAIL"))
#: Farthest detection the shipped mission places (``max_range`` in trees/map_scene.yaml), metres.
RANGE = 6.0
#: Border, pixels, within which a box counts as cut by the image's edge.
EDGE = 2.0
#: Directory to pickle, per world and phase, the fusion's instances and tracks beside the truth (for
#: studying merging and centring rules offline on what a run saw); unset: no dump.
DUMP = __import__("os").environ.get("SCENE_DIAG_DUMP")


def miss_cause(
    shown: int,
    seen: list[tuple[str, int]],
    ranges: list[float],
    changes: list[str],
    near: list[str],
) -> str:
    """One word for why a true object is not in the graph, in the order the pipeline loses it.

    ``never shown`` (no frame held 100 of its pixels), ``no box`` (shown, never boxed confidently),
    ``confused`` (boxed only as other classes), ``beyond range`` (its boxes all farther than the
    mission's 6 m), ``merged`` (an instance of it was joined into another), ``mislocated`` (an
    instance of its label stands within 1.5 m), else ``under min_frames`` (a candidate that never
    passed the votes and the whole-view checks).
    """
    if shown == 0 and not seen:
        return "never shown"
    if not seen:
        return "no box"
    if not ranges:
        return "confused"
    if min(ranges) > RANGE:
        return "beyond range"
    if any(c.startswith("removed") and "same" in c for c in changes):
        return "merged"
    if near:
        return "mislocated"
    return "under min_frames"


@dataclass
class Sight:
    """One confident detection, what it really covered and where ours placed it."""

    label: str
    truth: str | None
    truth_label: str | None
    xy: tuple[float, float] | None
    camera: tuple[float, float]
    cut: str
    stamp: float
    score: float


@dataclass
class Diagnosis:
    """Records a run for :meth:`report` (see module docstring)."""

    robot: Any
    classes: set[str]
    depth_method: str = "centre"
    sights: list[Sight] = field(default_factory=list)
    shown: Counter[str] = field(default_factory=Counter)
    changes: list[Change] = field(default_factory=list)
    verdicts: defaultdict[str, Counter[str]] = field(default_factory=lambda: defaultdict(Counter))
    fusion: Any = None
    #: Camera positions of the frames, on a 0.25 m grid (how near the route brought the camera).
    cameras: set[tuple[int, int]] = field(default_factory=set)

    def watch(self, semantic_map: Any, fusion: Any = None) -> None:
        """Record every change of ``semantic_map`` and, with ``fusion``, its judgements of unseen places."""
        semantic_map.subscribe(self.changes.append)
        self.fusion = fusion
        if fusion is None:
            return
        judge = fusion.absence  # the fusion's misses and moves (semantics/absence.py)
        expected, judged = judge.expected_view, judge.place_seen

        def expected_view(frame: Any, inst: Any) -> Any:
            view = expected(frame, inst)
            if view is not None:
                self.verdicts[inst.id]["expected"] += 1
            return view

        def place_seen(frame: Any, inst: Any, u: float, v: float, forward: float) -> str:
            verdict = judged(frame, inst, u, v, forward)
            self.verdicts[inst.id][verdict] += 1
            if verdict == "occluded" and DETAIL:
                print(f"  occluded {inst.id} fwd {forward:.2f} u {u:.0f} v {v:.0f} cam {frame.camera_pose}")
            return verdict

        judge.expected_view = expected_view
        judge.place_seen = place_seen

    def new_phase(self) -> None:
        """Count the judgements of unseen places afresh (the dynamic phase's pass)."""
        self.verdicts.clear()

    def frame(self, frame: Any, detections: list[Any]) -> None:
        """Record one frame: who it showed, what each confident detection covered."""
        truth = self.robot.truth
        self.cameras.add((round(frame.camera_pose.x / 0.25), round(frame.camera_pose.y / 0.25)))
        for name, sighting in truth.visible_at(frame.stamp, SHOWN_PIXELS).items():
            if sighting.kind == "object":
                self.shown[name] += 1
        mask = truth.instance_mask(frame.stamp)
        infos = truth.instances
        w, h = frame.intrinsics.width, frame.intrinsics.height
        for d in detections:
            if d.score < 0.7 or d.label == "person":
                continue
            x1, y1, x2, y2 = (int(round(v)) for v in d.box)
            name, label = None, None
            if mask is not None:
                cx, cy = (x2 - x1) // 4, (y2 - y1) // 4
                top, left = max(0, y1 + cy), max(0, x1 + cx)
                patch = mask[top : max(top + 1, y2 - cy), left : max(left + 1, x2 - cx)]
                ids = Counter(patch.ravel().tolist())
                for inst, _ in ids.most_common():
                    info = infos.get(int(inst))
                    if info is not None and info.kind == "object":
                        name, label = info.name, info.label
                        break
            p = project(frame, d, method=self.depth_method)  # type: ignore[arg-type]
            cut = "".join(
                s
                for s, c in (
                    ("L", d.box[0] <= EDGE),
                    ("R", d.box[2] >= w - EDGE),
                    ("T", d.box[1] <= EDGE),
                    ("B", d.box[3] >= h - EDGE),
                )
                if c
            )
            self.sights.append(
                Sight(
                    d.label,
                    name,
                    label,
                    p.xy if p is not None else None,
                    (frame.camera_pose.x, frame.camera_pose.y),
                    cut,
                    frame.stamp,
                    float(d.score),
                )
            )

    def report(
        self,
        world_name: str,
        scored: dict[str, Any],
        world: Any,
        ignored: Any,
        truth_label: Any,
        phase: str = "first",
    ) -> list[str]:
        """Lines for each false and missed object of a scored phase (see module docstring)."""
        lines: list[str] = []
        preds, truths, pairs = scored["preds"], scored["truths"], scored["pairs"]
        if DUMP:
            self.dump(f"{DUMP}/{world_name.replace(':', '_').replace('/', '_')}_{phase}.pkl", scored, world)
        causes: Counter[str] = Counter()
        matched_p = {i for i, _ in pairs}
        matched_t = {j for _, j in pairs}
        for i, p in enumerate(preds):
            if i in matched_p:
                continue
            x, y = p["position"][0], p["position"][1]
            radius = max(0.6, 0.5 * max(p.get("size", (0, 0, 0))[:2] or (0,)))
            track = self.fusion.tracks.get(p["id"]) if self.fusion is not None else None
            labels = {p["label"]} | (track.seen_as if track is not None else set())
            evidence = (
                {k: round(v, 2) for k, v in track.evidence.most_common(3)} if track is not None else {}
            )
            mine = [
                s
                for s in self.sights
                if s.label in labels
                and s.xy is not None
                and math.hypot(s.xy[0] - x, s.xy[1] - y) <= radius
            ]
            covered = Counter(f"{s.truth_label}:{s.truth}" for s in mine).most_common(3)
            views = len({(round(s.camera[0] / 0.5), round(s.camera[1] / 0.5)) for s in mine})
            cut = sum(1 for s in mine if s.cut) / max(len(mine), 1)
            same = [
                (math.hypot(t.pose.x - x, t.pose.y - y), j, t)
                for j, t in enumerate(truths)
                if truth_label(t.label) == p["label"]
            ]
            same.sort(key=lambda e: e[0])
            if ignored(p, world):
                cause = "ignored"
            elif same and same[0][0] <= 1.5 and same[0][1] not in matched_t:
                cause = f"offset {same[0][0]:.2f} m from {same[0][2].id}"
            elif same and same[0][0] <= 1.5:
                cause = f"duplicate of {same[0][2].id} ({same[0][0]:.2f} m)"
            elif covered and covered[0][0].split(":")[0] not in (p["label"], "None"):
                cause = "confusion"
            else:
                cause = "phantom"
            cuts = Counter(s.cut for s in mine if s.cut).most_common(2)
            lines.append(
                f"{world_name} {phase} FP {p['id']} {p['label']} ({x:.2f}, {y:.2f}) size "
                f"{[round(v, 2) for v in p.get('size', ())]}: {cause}; boxes cover {covered}; "
                f"{len(mine)} sights, {views} viewpoints, cut {cut:.0%} {cuts}; class evidence {evidence}"
            )
        for j, t in enumerate(truths):
            if j in matched_t:
                continue
            mine = [s for s in self.sights if s.truth == t.id]
            seen = Counter(s.label for s in mine).most_common(3)
            right = [s for s in mine if s.label == truth_label(t.label) and s.xy is not None]
            dists = sorted(math.hypot(s.xy[0] - t.pose.x, s.xy[1] - t.pose.y) for s in right)  # type: ignore[index]
            views = len({(round(s.camera[0] / 0.5), round(s.camera[1] / 0.5)) for s in right})
            apart = max(
                (math.dist(a.camera, b.camera) for a in right for b in right), default=0.0
            )  # cells on a 0.5 m grid split one place standing on a cell edge: say how far apart too
            ranges = sorted(math.hypot(s.camera[0] - t.pose.x, s.camera[1] - t.pose.y) for s in right)
            spread = (
                f"proj dist median {dists[len(dists) // 2]:.2f} min {dists[0]:.2f}, {views} viewpoints "
                f"({apart:.2f} m apart), range min {ranges[0]:.1f} median {ranges[len(ranges) // 2]:.1f} m; "
                f"{self._candidates(t, truth_label)}"
                if dists
                else "no projection"
            )
            near_changes = [
                f"{c.kind} {c.id}" + (f" ({c.reason})" if c.kind == "removed" else "")
                for c in self.changes
                if c.label == truth_label(t.label)
                and c.kind in ("added", "removed", "moved")
                and math.hypot(c.position[0] - t.pose.x, c.position[1] - t.pose.y) <= 1.0
            ]
            near_preds = [
                f"{p['id']}@{math.hypot(p['position'][0] - t.pose.x, p['position'][1] - t.pose.y):.2f}"
                for p in preds
                if p["label"] == truth_label(t.label)
                and math.hypot(p["position"][0] - t.pose.x, p["position"][1] - t.pose.y) <= 1.5
            ]
            nearest = min(
                (math.hypot(0.25 * cx - t.pose.x, 0.25 * cy - t.pose.y) for cx, cy in self.cameras),
                default=math.inf,
            )
            cause = miss_cause(self.shown[t.id], seen, ranges, near_changes, near_preds)
            causes[cause] += 1
            lines.append(
                f"{world_name} {phase} FN {t.id} {t.label} ({t.pose.x:.2f}, {t.pose.y:.2f}) size "
                f"{[round(v, 2) for v in t.size]} elev {t.elevation}: {cause}; "
                f"nearest camera {nearest:.1f} m; "
                f"shown in {self.shown[t.id]} frames; "
                f"detected as {seen}; {spread}; graph near {near_preds}; map changes {near_changes[-4:]}"
            )
        if causes:
            lines.append(f"{world_name} {phase} FN causes {dict(causes.most_common())}")
        return lines

    def _candidates(self, t: Any, truth_label: Any) -> str:
        """The fusion's unconfirmed candidates of the object's label within 1 m: why each waits."""
        fusion = self.fusion
        if fusion is None:
            return "no fusion"
        out = []
        for c in fusion.voting.candidates:
            if c.label != truth_label(t.label) or math.hypot(c.x - t.pose.x, c.y - t.pose.y) > 1.0:
                continue
            judged = [fusion._bounded[id(q)] for q in c.projections if id(q) in fusion._bounded]
            out.append(
                f"cand {c.frames}/{fusion._frames_needed(c)} frames, whole {fusion._whole_enough(c)}, "
                f"size ok {fusion._plausible_size(c)}, bounded {sum(judged)}/{len(judged)}"
            )
        return "; ".join(out) or "no candidate"

    def dump(self, path: str, scored: dict[str, Any], world: Any) -> None:
        """Pickle the fusion's instances and tracks, the truth and the sights to ``path`` (see ``DUMP``)."""
        import pickle
        from pathlib import Path

        fusion = self.fusion
        instances = [
            {
                "id": i.id,
                "label": i.label,
                "position": tuple(i.position),
                "size": tuple(i.size),
                "observations": i.observations,
                "colour": i.colour,
            }
            for i in (fusion.map if fusion is not None else [])
        ]
        tracks = {
            key: {
                "xs": list(t.xs),
                "clipped": list(t.clipped),
                "sizes": list(t.sizes),
                "cells": dict(t.cells),
                "evidence": dict(t.evidence),
                "seen_as": set(t.seen_as),
            }
            for key, t in (fusion.tracks.items() if fusion is not None else [])
        }
        truths = [
            {
                "id": o.id,
                "label": o.label,
                "pose": (o.pose.x, o.pose.y, o.pose.yaw),
                "size": tuple(o.size),
                "elevation": o.elevation,
            }
            for o in world.objects
        ]
        pairs = [(scored["preds"][i]["id"], scored["truths"][j].id) for i, j in scored["pairs"]]
        changes = [(c.kind, c.id, c.label, tuple(c.position), c.reason) for c in self.changes]
        data = {
            "instances": instances,
            "tracks": tracks,
            "truths": truths,
            "pairs": pairs,
            "sights": self.sights,
            "changes": changes,
        }
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        with open(path, "wb") as fh:
            pickle.dump(data, fh)

    def report_changes(
        self, world_name: str, changes: list[dict[str, Any]], preds: list[dict[str, Any]], reflected: Any
    ) -> list[str]:
        """Lines for each change of the dynamic phase."""
        lines = []
        for c in changes:
            ok = reflected(preds, c)
            where = []
            for key in ("from", "to"):
                if key not in c:
                    continue
                px, py = c[key]
                near = [
                    f"{p['id']}@{math.hypot(p['position'][0] - px, p['position'][1] - py):.2f}"
                    f"{dict(self.verdicts.get(p['id'], {}))} z {p['position'][2]:.2f} "
                    f"size {[round(v, 2) for v in p.get('size', ())]}"
                    for p in preds
                    if p["label"] == c["label"]
                    and math.hypot(p["position"][0] - px, p["position"][1] - py) <= 1.5
                ]
                shown = [s for s in self.sights if s.truth == c["id"]]
                where.append(f"{key} ({px:.2f}, {py:.2f}) graph {near}")
            log = [
                f"{ch.kind} {ch.id} {ch.reason}"
                for ch in self.changes
                if ch.label == c["label"]
                and ch.kind in ("added", "removed", "moved")
                and any(
                    math.hypot(ch.position[0] - c[k][0], ch.position[1] - c[k][1]) <= 1.0
                    or (
                        ch.previous is not None
                        and math.hypot(ch.previous[0] - c[k][0], ch.previous[1] - c[k][1]) <= 1.0
                    )
                    for k in ("from", "to")
                    if k in c
                )
            ]
            lines.append(
                f"{world_name} change {c['kind']} {c['id']} {c['label']} {'OK' if ok else 'MISSED'}: "
                f"{'; '.join(where)}; sights of it {len(shown)}; map log {log[-4:]}"
            )
        return lines
