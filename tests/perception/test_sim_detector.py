from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from missiontree.backends.sim import create_robot
from missiontree.perception.detectors import iou_matrix
from missiontree.perception.providers import SIM_DETECTOR_MODEL, create_sim_detector

# A room the detector never saw: a person 3.4 m ahead, a chair, a sofa and a backpack around them.
WORLD = """
name: sim_detector_test
robot: {profile: turtlebot4, start: {x: 1.0, y: 0.0, yaw: 0.0}}
walls: {height: 2.5, polygons: [[[0, -3], [7, -3], [7, 3], [0, 3]]]}
rooms: [{name: room, type: office, polygon: [[0, -3], [7, -3], [7, 3], [0, 3]], floor_rgb: [190, 185, 170]}]
objects:
  - {id: chair_1, label: chair, color: red, size: [0.5, 0.5, 0.95], pose: {x: 3.6, y: 1.2}}
  - {id: sofa_1, label: sofa, color: blue, size: [2.0, 0.9, 0.8], pose: {x: 5.8, y: -1.2, yaw: 1.5708}}
  - {id: backpack_1, label: backpack, color: grey, size: [0.32, 0.22, 0.45], pose: {x: 2.8, y: -0.8}}
people:
  - {id: alice, route: [[4.4, 0.3]], speed: 0.0, shirt_rgb: [180, 40, 40]}
"""


@pytest.fixture(scope="module")
def frame_and_truth(tmp_path_factory: pytest.TempPathFactory):  # noqa: ANN201 - (frame, {name: (label, box)})
    """One rendered frame of the test room and the true boxes of what it shows."""
    path = Path(tmp_path_factory.mktemp("world")) / "room.yaml"
    path.write_text(WORLD)
    robot = create_robot({"world": str(path)})
    frame = robot.rgbd()
    mask = robot.truth.instance_mask(frame.stamp)
    truth = {}
    for inst, info in robot.truth.instances.items():
        if info.kind in ("object", "person") and (mask == inst).sum() >= 40:
            rows, cols = np.nonzero(mask == inst)
            truth[info.name] = (info.label, (cols.min(), rows.min(), cols.max() + 1, rows.max() + 1))
    robot.close()
    return frame, truth


def test_shipped_model_is_small_and_carries_its_class_names() -> None:
    """The committed model is about 1 MB and names person first among its classes."""
    assert SIM_DETECTOR_MODEL.stat().st_size < 3_000_000
    detector = create_sim_detector({})
    assert detector.labels[0] == "person"
    assert {"chair", "sofa", "backpack", "cup", "bottle"} <= set(detector.labels)


def test_finds_the_person_and_the_objects_in_a_rendered_frame(frame_and_truth) -> None:  # noqa: ANN001
    """Each visible person and object is found with its label, its box overlapping the truth."""
    frame, truth = frame_and_truth
    assert {label for label, _ in truth.values()} >= {"person", "chair", "sofa", "backpack"}
    found = create_sim_detector({}).detect(frame.color)
    for name, (label, box) in truth.items():
        same = [d for d in found if d.label == label]
        assert same, f"{name}: no {label} among {[(d.label, round(d.score, 2)) for d in found]}"
        best = iou_matrix(np.array([box], float), np.array([d.box for d in same], float)).max()
        assert best >= 0.5, f"{name}: best {label} box overlaps the truth by only {best:.2f}"


def test_reports_nothing_at_mission_confidence_in_an_empty_room(tmp_path: Path) -> None:
    """Facing a bare room, nothing reaches 0.7, the confidence filter of seed 000 that missions use."""
    path = tmp_path / "empty.yaml"
    path.write_text(WORLD.split("objects:")[0] + "objects: []\npeople: []\n")
    robot = create_robot({"world": str(path)})
    assert create_sim_detector({"score_threshold": 0.7}).detect(robot.rgbd().color) == []
    robot.close()


def test_with_the_mirror_pass_a_mirrored_frame_gives_the_mirrored_detections(frame_and_truth) -> None:  # noqa: ANN001
    """Both passes pooled: the frame and its mirror image give the same detections, mirrored."""
    frame, _ = frame_and_truth
    detector = create_sim_detector({"score_threshold": 0.05, "flip_band": None})
    assert detector.test_time_flip  # the provider's default
    image = frame.color
    width = image.shape[1]
    found = detector.detect(image)
    mirrored = detector.detect(np.ascontiguousarray(image[:, ::-1]))
    assert len(found) >= 4
    as_found = sorted((d.label, round(d.score, 4), *np.round(d.box, 2)) for d in found)
    unmirror = lambda b: (width - b[2], b[1], width - b[0], b[3])  # noqa: E731
    mirrored_back = sorted((d.label, round(d.score, 4), *np.round(unmirror(d.box), 2)) for d in mirrored)
    assert [row[:2] for row in as_found] == [row[:2] for row in mirrored_back]
    np.testing.assert_allclose(np.array([row[2:] for row in as_found], float),
                               np.array([row[2:] for row in mirrored_back], float), atol=0.02)


def test_the_mirror_pass_can_be_switched_off() -> None:
    detector = create_sim_detector({"test_time_flip": False})
    assert detector.test_time_flip is False and detector.describe()["test_time_flip"] is False


def test_the_shipped_detector_mirrors_only_frames_with_a_candidate_in_its_band(frame_and_truth) -> None:  # noqa: ANN001
    """By default the mirror pass runs on a frame with objects near the decision, not on a blank one."""
    frame, _ = frame_and_truth
    detector = create_sim_detector({})
    assert detector.flip_band == (0.3, 0.7)
    detector.detect(np.zeros_like(frame.color))
    assert detector.passes == {"single": 1, "mirror": 0}
    detector.detect(frame.color)
    assert detector.passes == {"single": 2, "mirror": 1}
