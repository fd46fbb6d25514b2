"""Publishing to the ROS world: NAIS's coloured cubes, /scene_graph JSON and alarms, from mission events."""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from typing import Any

import pytest

pytest.importorskip("rclpy", reason="ROS 2 extra not installed: pip install -e .[ros2]; setup-ros2.sh")
pytestmark = pytest.mark.ros2

from std_msgs.msg import String  # noqa: E402
from visualization_msgs.msg import Marker, MarkerArray  # noqa: E402

from missiontree.backends.ros2 import plugin  # noqa: E402
from missiontree.backends.ros2.publish import (  # noqa: E402
    PlacedObject,
    RosEvents,
    detection_markers,
    label_colour,
)
from missiontree.backends.ros2.robot import latched_qos, reliable_qos  # noqa: E402
from missiontree.backends.ros2.testing import SpinningPeer  # noqa: E402
from missiontree.engine.context import MissionContext  # noqa: E402


def test_markers_clear_then_draw_a_coloured_cube_and_label_per_object() -> None:
    """The array starts with DELETEALL, then a cube in NAIS's colour and a text label for each object."""
    array = detection_markers([PlacedObject("chair", 1.0, 2.0, object_id=7), PlacedObject("cup", 3.0, 1.0)],
                              stamp=5.0)
    clear, cube, text, cube2, _ = array.markers
    assert clear.action == Marker.DELETEALL
    assert cube.type == Marker.CUBE and (cube.pose.position.x, cube.pose.position.y) == (1.0, 2.0)
    assert (cube.color.r, cube.color.g, cube.color.b) == pytest.approx(label_colour("chair"))
    assert cube.color.g > cube.color.r and cube.color.g > cube.color.b  # chairs are green in NAIS
    assert text.type == Marker.TEXT_VIEW_FACING and text.text == "chair"
    assert len({m.id for m in array.markers[1:]}) == 4
    assert cube.header.frame_id == "map" and cube2.header.stamp.sec == 5


def test_unknown_labels_get_a_stable_colour() -> None:
    """A label NAIS did not colour gets the same colour every run."""
    assert label_colour("stapler") == label_colour("stapler") != label_colour("lamp")


class Listener(SpinningPeer):
    """A peer node recording what arrives on the three publishing topics."""

    def __init__(self, domain: int) -> None:
        super().__init__(domain, "listener")
        self.markers: list[MarkerArray] = []
        self.graphs: list[dict[str, Any]] = []
        self.alarms: list[dict[str, Any]] = []
        node = self.node
        node.create_subscription(MarkerArray, "/missiontree/detections", self.markers.append, latched_qos())
        node.create_subscription(String, "/scene_graph", lambda m: self.graphs.append(json.loads(m.data)),
                                 latched_qos())
        node.create_subscription(String, "/missiontree/alarms",
                                 lambda m: self.alarms.append(json.loads(m.data)), reliable_qos())
        self.start()



class RecordingSink:
    def __init__(self) -> None:
        self.events: list[tuple[str, dict[str, Any]]] = []

    def emit(self, event: str, **fields: Any) -> None:
        self.events.append((event, fields))


@pytest.fixture
def listener(domain_id: int) -> Iterator[Listener]:
    peer = Listener(domain_id)
    yield peer
    peer.close()


def test_mission_events_reach_ros_topics_on_the_ros2_backend(domain_id: int, listener: Listener,
                                                             make_robot: Callable,
                                                             wait_until: Callable) -> None:
    """With the plugin's hook, alarms, confirmed objects and scene graphs are published and still logged."""
    robot = make_robot(domain_id)
    sink = RecordingSink()
    context = MissionContext(robot=robot, events=sink)
    plugin.missiontree_mission_started(context=context, mission=None)
    assert isinstance(context.events, RosEvents)
    wait_until(lambda: listener.node.count_publishers("/missiontree/alarms") > 0, 10.0, "discovery")

    def send_alarm() -> bool:
        context.events.emit("alarm", node="surveillance", id=1, verdict="a person by the door",
                            position=[1.0, 2.0])
        return bool(listener.alarms)

    wait_until(send_alarm, 10.0, "the alarm on /missiontree/alarms")
    assert listener.alarms[0]["message"].startswith("ALARM: PERSON DETECTED")
    assert listener.alarms[0]["position"] == [1.0, 2.0]
    context.events.emit("object_confirmed", id="chair_red", label="chair", x=3.0, y=3.6)
    context.events.emit("object_confirmed", id="cup_1", label="cup", x=1.0, y=1.0)
    context.events.emit("object_confirmed", id="chair_red", label="chair", x=3.1, y=3.6)  # moved, not added

    def cube_xs() -> list[float]:
        latest = listener.markers[-1].markers if listener.markers else []
        return sorted(round(m.pose.position.x, 1) for m in latest if m.type == Marker.CUBE)

    # the array published after the second object already holds two cubes: wait for the moved chair
    wait_until(lambda: cube_xs() == [1.0, 3.1], 10.0, "the moved chair's cube")
    assert len(listener.markers[-1].markers) == 5  # two cubes, their labels: moved, not added
    context.events.emit("scene_graph", graph={"building": {"rooms": [{"name": "kitchen"}]}})
    wait_until(lambda: listener.graphs, 10.0, "the scene graph on /scene_graph")
    assert listener.graphs[-1]["building"]["rooms"][0]["name"] == "kitchen"
    assert [e for e, _ in sink.events].count("object_confirmed") == 3  # the tick log still gets everything


def test_hook_leaves_other_backends_alone() -> None:
    """On a robot that is not a Ros2Robot the hook changes nothing."""
    sink = RecordingSink()
    context = MissionContext(robot=object(), events=sink)  # type: ignore[arg-type]
    plugin.missiontree_mission_started(context=context, mission=None)
    assert context.events is sink
