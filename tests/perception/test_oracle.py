from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from missiontree.backends.sim import create_robot
from missiontree.errors import ModelConfigError, ModelError
from missiontree.perception.oracle import OracleDetector
from missiontree.perception.providers import bind_robot, create_oracle


@pytest.fixture(scope="module")
def robot():  # noqa: ANN201 - a SimRobot; the type lives in the backend tests must not depend on
    """The office world; at its start the camera sees a sofa, a chair, a backpack and a tv."""
    sim = create_robot({"world": "office", "seed": 0})
    yield sim
    sim.close()


def test_oracle_reports_what_the_instance_mask_shows(robot) -> None:  # noqa: ANN001
    """Every object visible with enough pixels is reported with its true label and tight box."""
    frame = robot.rgbd()
    found = OracleDetector(robot, min_pixels=30).detect(frame.color)
    visible = robot.truth.visible_at(frame.stamp, min_pixels=30)
    assert {d.attributes["instance"] for d in found} == set(visible)
    mask = robot.truth.instance_mask(frame.stamp)
    for d in found:
        inst = next(i for i, info in robot.truth.instances.items() if info.name == d.attributes["instance"])
        rows, cols = np.nonzero(mask == inst)
        assert d.label == visible[d.attributes["instance"]].label
        assert d.box == (cols.min(), rows.min(), cols.max() + 1, rows.max() + 1)
        assert d.mask is not None and d.mask.sum() == len(rows)


def test_min_pixels_hides_small_objects(robot) -> None:  # noqa: ANN001
    """Raising min_pixels drops the objects that show fewer pixels."""
    frame = robot.rgbd()
    visible = robot.truth.visible_at(frame.stamp)
    threshold = sorted(s.pixels for s in visible.values())[0] + 1
    found = OracleDetector(robot, min_pixels=threshold).detect(frame.color)
    assert len(found) == sum(1 for s in visible.values() if s.pixels >= threshold)


def test_miss_rate_one_sees_nothing_and_zero_sees_all(robot) -> None:  # noqa: ANN001
    """miss_rate 1 drops every object, 0 none."""
    image = robot.rgbd().color
    assert OracleDetector(robot, miss_rate=1.0).detect(image) == []
    assert len(OracleDetector(robot, miss_rate=0.0).detect(image)) >= 3


def test_miss_rate_is_seeded_and_roughly_honoured(robot) -> None:  # noqa: ANN001
    """Half the objects go missing over many frames, the same ones for the same seed."""
    image = robot.rgbd().color
    total = len(OracleDetector(robot).detect(image))
    counts = [len(OracleDetector(robot, miss_rate=0.5, seed=s).detect(image)) for s in range(200)]
    assert 0.4 < sum(counts) / (200 * total) < 0.6
    again = [len(OracleDetector(robot, miss_rate=0.5, seed=s).detect(image)) for s in range(200)]
    assert again == counts


def test_false_positive_rate_adds_made_up_boxes(robot) -> None:  # noqa: ANN001
    """With false_positive_rate 1 every answer holds one box on no object, of a known label."""
    image = robot.rgbd().color
    oracle = OracleDetector(robot, false_positive_rate=1.0, seed=3)
    for _ in range(5):
        ghosts = [d for d in oracle.detect(image) if d.attributes["kind"] == "false_positive"]
        assert len(ghosts) == 1 and ghosts[0].label in oracle.labels
        x1, y1, x2, y2 = ghosts[0].box
        assert 0 <= x1 < x2 <= image.shape[1] and 0 <= y1 < y2 <= image.shape[0]


def test_labels_restrict_what_is_reported(robot) -> None:  # noqa: ANN001
    """With labels given only those classes are reported."""
    found = OracleDetector(robot, labels=["sofa"]).detect(robot.rgbd().color)
    assert [d.label for d in found] == ["sofa"]


def test_older_frame_is_labelled_from_its_own_mask(robot) -> None:  # noqa: ANN001
    """A frame passed after the robot rendered newer ones still gets its own mask's objects."""
    oracle = OracleDetector(robot)
    first = robot.rgbd()
    expected = sorted(d.attributes["instance"] for d in oracle.detect(first.color))
    robot.drive(0.0, 1.0)
    robot.spin_until(robot.now() + 1.0)
    robot.stop()
    assert robot.rgbd().stamp > first.stamp
    assert sorted(d.attributes["instance"] for d in oracle.detect(first.color)) == expected
    assert sorted(d.attributes["instance"] for d in oracle.detect_frame(first)) == expected


def test_image_that_is_no_camera_frame_is_refused(robot) -> None:  # noqa: ANN001
    """A made-up image cannot be labelled; the error says what to pass."""
    with pytest.raises(ModelError, match="not a recent camera frame.*frame.color"):
        OracleDetector(robot).detect(np.zeros((240, 320, 3), np.uint8))


def test_non_simulated_robot_is_refused() -> None:
    """Binding to a robot without simulator ground truth names the real detectors to use."""
    real = SimpleNamespace(name="tb4", simulated=False)
    with pytest.raises(ModelConfigError, match="simulation-only.*'tb4'.*sim_detector"):
        OracleDetector(real)


def test_unbound_oracle_says_how_to_bind() -> None:
    """Detecting before binding a robot is a clear error."""
    with pytest.raises(ModelConfigError, match="not bound to a simulated robot"):
        OracleDetector().detect(np.zeros((4, 4, 3), np.uint8))


def test_rates_outside_zero_one_are_refused() -> None:
    """A miss rate of 1.5 is a configuration error naming the option."""
    with pytest.raises(ModelConfigError, match="miss_rate must lie in"):
        OracleDetector(miss_rate=1.5)


def test_factory_builds_unbound_and_bind_robot_binds_it(robot) -> None:  # noqa: ANN001
    """The registered factory builds from options; bind_robot attaches the run's robot later."""
    oracle = create_oracle({"miss_rate": 0.0, "seed": 1})
    bind_robot({"detector": oracle, "other": object()}, robot)
    assert len(oracle.detect(robot.rgbd().color)) >= 3


def test_check_describes_an_unbound_oracle_without_failing() -> None:
    """An oracle not yet bound is still usable (it binds at run time); check() says so."""
    assert "simulation-only oracle" in OracleDetector(miss_rate=0.2).check()


def test_a_prepared_frame_is_answered_on_a_worker_without_touching_the_simulator(robot) -> None:  # noqa: ANN001
    """prepare_frame reads the mask on the tick thread; the job and a later detect(image) elsewhere use it."""
    import threading

    from missiontree.perception.detectors import detection_job

    oracle = OracleDetector(robot, miss_rate=0.3, seed=4)
    frame = robot.rgbd()
    job = detection_job(oracle, frame)
    reads: list[str] = []
    truth = robot.truth
    original = truth.instance_mask
    truth.instance_mask = lambda stamp: reads.append(threading.current_thread().name) or original(stamp)
    try:
        results: list[list] = []
        worker = threading.Thread(target=lambda: results.append(job()), name="model-call-test")
        worker.start()
        worker.join()
        again: list[list] = []
        worker = threading.Thread(target=lambda: again.append(oracle.detect(frame.color)), name="vlm-test")
        worker.start()
        worker.join()
    finally:
        truth.instance_mask = original
    assert reads == []  # the workers never read the simulator
    assert [d.box for d in results[0]] == [d.box for d in again[0]]  # same frame, same (seeded) answer
    assert all(np.isfinite(d.box).all() for d in results[0])
