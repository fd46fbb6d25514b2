"""tools/detector/data.py: generated worlds and labelled views for the shipped detector."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from missiontree.backends.sim.camera import Camera
from missiontree.backends.sim.schema import CameraSpec
from missiontree.backends.sim.world import load_world
from missiontree.types import Pose2D
from tools.detector import data as detector_data
from tools.detector.data import CLASSES, View, generated_world, render_views, unoccluded_share, world_spec


def test_a_world_is_the_same_for_the_same_seed_and_differs_for_another() -> None:
    assert world_spec(5) == world_spec(5)
    assert world_spec(5) != world_spec(6)


def test_tvs_are_sometimes_raised_as_the_shipped_office_hangs_its_own() -> None:
    tvs = [o for seed in range(60) for o in world_spec(seed)["objects"] if o["label"] == "tv"]
    raised = [o["elevation"] for o in tvs if "elevation" in o]
    assert 0 < len(raised) < len(tvs)
    assert all(0.4 <= e <= 1.1 for e in raised)


def test_views_are_labelled_from_the_instance_mask() -> None:
    world = generated_world(3)
    views = render_views(world, 6, np.random.default_rng(0))
    assert len(views) == 6
    for view in views:
        assert view.color.shape == (240, 320, 3)
        assert len(view.kept) == len(view.kept_ids)
        for row, inst in zip(view.kept, view.kept_ids, strict=True):
            ys, xs = np.nonzero(view.instances == inst)
            assert len(xs) >= detector_data.MIN_PIXELS
            assert CLASSES[int(row[0])] == world.instances[int(inst)].label
            assert tuple(row[1:]) == (xs.min(), ys.min(), xs.max() + 1, ys.max() + 1)
    labels = {CLASSES[int(r[0])] for v in views for r in v.kept}
    assert labels  # the views are mostly aimed at things


ROOM = """
name: occlusion
robot: {profile: turtlebot4, start: {x: 0.5, y: 0.0, yaw: 0.0}}
walls: {height: 2.5, polygons: [[[0, -3], [8, -3], [8, 3], [0, 3]]]}
rooms: [{name: room, type: room, polygon: [[0, -3], [8, -3], [8, 3], [0, 3]], floor_rgb: [190, 185, 170]}]
objects:
  - {id: chair_1, label: chair, color: red, size: [0.5, 0.5, 0.9], pose: {x: 2.5, y: 0.0}}
  - {id: sofa_1, label: sofa, color: blue, size: [2.0, 0.9, 0.8], pose: {x: 5.0, y: 0.0, yaw: 1.5708}}
  - {id: cup_1, label: bottle, color: green, shape: cylinder, size: [0.3, 0.3, 0.6], pose: {x: 2.5, y: 1.2}}
people: []
"""


def test_an_object_behind_another_counts_as_partly_hidden(tmp_path: Path) -> None:
    path = tmp_path / "room.yaml"
    path.write_text(ROOM)
    world = load_world(path)
    camera = Camera(CameraSpec(), np.random.default_rng(0))
    floor = detector_data.floor_of(world)
    pose = Pose2D(0.5, 0.0, 0.0)
    rendering = camera.render(pose, detector_data.CAMERA_HEIGHT, world.static, floor)
    kept, ignored, ids = detector_data.labels_of(rendering.instances, world)
    view = View(rendering.color, rendering.instances, kept, ignored, ids, pose, world.static)
    shares = unoccluded_share(world, view)
    share = {world.instances[int(i)].label: s for i, s in zip(ids, shares, strict=True)}
    assert share["chair"] == 1.0   # nearest: nothing in front of it
    assert share["bottle"] == 1.0  # off to the side, in full view
    assert 0.3 < share["sofa"] < 0.95  # the chair hides part of it


def test_empty_rooms_share_renders_bare_worlds_and_zero_changes_nothing() -> None:
    """``empty_share`` 1.0 gives views with nothing to find; 0.0, the default, renders furnished worlds."""
    bare = generated_world(3, empty=True)
    assert bare.objects == [] and bare.crowd.people == []
    images, kept, ignored = detector_data.render_dataset(6, seed=2, first_world=3, views_per_world=3,
                                                         empty_share=1.0)
    assert all(len(k) == 0 and len(i) == 0 for k, i in zip(kept, ignored, strict=True))
    plain = detector_data.render_dataset(6, seed=2, first_world=3, views_per_world=3)
    default = detector_data.render_dataset(6, seed=2, first_world=3, views_per_world=3, empty_share=0.0)
    assert np.array_equal(plain[0], default[0])
    assert sum(len(k) for k in plain[1]) > 0
