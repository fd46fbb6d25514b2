"""What a mission shows the ROS world: detections as coloured cubes, the scene graph, alarms.

The NAIS paper draws every object of its semantic map as a coloured cube in RViz — chairs green,
umbrellas blue, bottles purple, cups pink, sofas lime — and publishes its scene graph as a JSON
``std_msgs/String`` on ``/scene_graph``. :class:`WorldPublisher` does the same from a mission,
plus alarms as ``std_msgs/String`` JSON on their own topic. Message building is pure
(:func:`detection_markers`), so it is tested without a node.

Leaves do not call it: :class:`RosEvents` mirrors the mission's own events (installed by
:mod:`missiontree.backends.ros2.plugin` when a mission starts on this backend):

- ``alarm`` (fields of ``behaviours.alarms.Alarm``) → the alarms topic;
- ``object_confirmed`` / ``detection_confirmed`` / ``semantic_object`` with ``label``, ``x``, ``y``
  (and optionally ``id``, ``z``) → one more cube in the MarkerArray;
- ``scene_graph`` with ``graph`` (a JSON-able mapping) → /scene_graph.
"""

from __future__ import annotations

import hashlib
import json
import zlib
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import ColorRGBA, String
from visualization_msgs.msg import Marker, MarkerArray

from missiontree.backends.ros2.conversions import sec_to_time

#: NAIS's marker colours (RGB in [0, 1]); other labels get a stable colour from their name.
NAIS_COLOURS: dict[str, tuple[float, float, float]] = {
    "chair": (0.0, 0.8, 0.0),
    "umbrella": (0.0, 0.3, 1.0),
    "bottle": (0.6, 0.2, 0.8),
    "cup": (1.0, 0.4, 0.7),
    "couch": (0.6, 1.0, 0.2),
    "sofa": (0.6, 1.0, 0.2),
}
CUBE_SIZE = 0.25


@dataclass(frozen=True)
class PlacedObject:
    """An object at a map position, as a marker shows it.

    Attributes:
        label: Class name (sets the colour).
        x: Map x (m).
        y: Map y (m).
        z: Height of the object's centre (m).
        object_id: Stable id; markers with the same id replace each other in RViz.
    """

    label: str
    x: float
    y: float
    z: float = 0.3
    object_id: int = 0


def label_colour(label: str) -> tuple[float, float, float]:
    """NAIS's colour for ``label``, else one derived from a hash of the name (stable across runs)."""
    if label in NAIS_COLOURS:
        return NAIS_COLOURS[label]
    digest = hashlib.sha1(label.encode("utf-8")).digest()
    return digest[0] / 255.0, digest[1] / 255.0, digest[2] / 255.0


def detection_markers(objects: Iterable[PlacedObject], stamp: float, frame_id: str = "map",
                      namespace: str = "missiontree") -> MarkerArray:
    """A MarkerArray that clears the previous markers, then draws a cube and a text label per object."""
    clear = Marker()
    clear.action = Marker.DELETEALL
    markers = [clear]
    for index, obj in enumerate(objects):
        r, g, b = label_colour(obj.label)
        marker_id = obj.object_id or index + 1
        cube = Marker()
        cube.header.stamp = sec_to_time(stamp)
        cube.header.frame_id = frame_id
        cube.ns = namespace
        cube.id = 2 * marker_id
        cube.type = Marker.CUBE
        cube.action = Marker.ADD
        cube.pose.position.x, cube.pose.position.y, cube.pose.position.z = obj.x, obj.y, obj.z
        cube.pose.orientation.w = 1.0
        cube.scale.x = cube.scale.y = cube.scale.z = CUBE_SIZE
        cube.color = ColorRGBA(r=r, g=g, b=b, a=0.9)
        text = Marker()
        text.header = cube.header
        text.ns = f"{namespace}/labels"
        text.id = 2 * marker_id + 1
        text.type = Marker.TEXT_VIEW_FACING
        text.action = Marker.ADD
        text.pose.position.x, text.pose.position.y = obj.x, obj.y
        text.pose.position.z = obj.z + CUBE_SIZE
        text.pose.orientation.w = 1.0
        text.scale.z = 0.15
        text.color = ColorRGBA(r=1.0, g=1.0, b=1.0, a=1.0)
        text.text = obj.label
        markers += [cube, text]
    return MarkerArray(markers=markers)


class WorldPublisher:
    """Publishes detections, the scene graph and alarms from a mission's node.

    Args:
        node: The robot's node.
        topics: The profile's topics (``markers``, ``scene_graph``, ``alarms``).
    """

    def __init__(self, node: Node, topics: Any) -> None:
        self._node = node
        latched = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL, depth=1)
        events = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST, depth=10)
        self._markers = node.create_publisher(MarkerArray, topics.markers, latched)
        self._scene_graph = node.create_publisher(String, topics.scene_graph, latched)
        self._alarms = node.create_publisher(String, topics.alarms, events)

    def _stamp(self) -> float:
        return self._node.get_clock().now().nanoseconds * 1e-9

    def detections(self, objects: Iterable[PlacedObject]) -> None:
        """Replace the cubes in RViz with one per object."""
        self._markers.publish(detection_markers(objects, self._stamp()))

    def scene_graph(self, graph: Mapping[str, Any]) -> None:
        """Publish the scene graph as a JSON string (NAIS's /scene_graph); a NAIS-shaped one also as markers.

        The markers (:mod:`missiontree.backends.ros2.scene`) go on the detections topic.
        """
        self._scene_graph.publish(String(data=json.dumps(graph, sort_keys=True, default=str)))
        if isinstance(graph.get("nodes"), list):
            from missiontree.backends.ros2.scene import scene_markers

            self._markers.publish(scene_markers(graph, self._stamp(), label_colour))

    def alarm(self, message: str, **fields: Any) -> None:
        """Publish an alarm as JSON: ``{"stamp": ..., "message": ..., **fields}``."""
        payload = {"stamp": self._stamp(), "message": message, **fields}
        self._alarms.publish(String(data=json.dumps(payload, sort_keys=True, default=str)))


#: Events whose ``label``, ``x``, ``y`` place an object in the map (see the module docstring).
OBJECT_EVENTS = frozenset({"object_confirmed", "detection_confirmed", "semantic_object"})


class RosEvents:
    """An event sink that records as before and mirrors alarms, objects and scene graphs to ROS.

    Args:
        inner: The sink being wrapped (the runner's tick log); every event still reaches it first.
        world: Where to publish.
    """

    def __init__(self, inner: Any, world: WorldPublisher) -> None:
        self.inner = inner
        self.world = world
        self.objects: dict[str, PlacedObject] = {}

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)

    def emit(self, event: str, **fields: Any) -> None:
        """Record the event, then publish what the ROS world should see of it."""
        self.inner.emit(event, **fields)
        try:
            self._mirror(event, fields)
        except Exception as error:  # noqa: BLE001 - a publishing problem must never stop the mission
            import structlog

            structlog.get_logger("missiontree.ros2").warning("publishing an event to ROS failed", event=event,
                                                             error=f"{type(error).__name__}: {error}")

    def _mirror(self, event: str, fields: dict[str, Any]) -> None:
        if event == "alarm":
            verdict = str(fields.get("verdict") or "")
            self.world.alarm(f"ALARM: PERSON DETECTED{': ' + verdict if verdict else ''}", **fields)
        elif event in OBJECT_EVENTS and {"label", "x", "y"} <= fields.keys():
            key = str(fields.get("id", f"{fields['label']}@{fields['x']:.1f},{fields['y']:.1f}"))
            marker_id = zlib.crc32(key.encode()) % 1_000_000 + 1  # stable per object across updates
            self.objects[key] = PlacedObject(str(fields["label"]), float(fields["x"]), float(fields["y"]),
                                             float(fields.get("z", 0.3)), marker_id)
            self.world.detections(self.objects.values())
        elif event == "scene_graph" and isinstance(fields.get("graph"), Mapping):
            self.world.scene_graph(fields["graph"])


class FleetRosEvents:
    """A fleet's event sink: records as before, mirrors each robot's events to that robot's namespace.

    An event with ``robot: robot2`` (every event of a fleet robot's leaves carries it) goes to
    ``/robot2/missiontree/alarms``, robot2's markers and its scene graph topic; fleet-level events
    (no robot, or one not in ``worlds``) are only recorded.

    Args:
        inner: The sink being wrapped (the runner's tick log).
        worlds: Each robot's publisher, by robot name.
    """

    def __init__(self, inner: Any, worlds: Mapping[str, WorldPublisher]) -> None:
        self.inner = inner
        self.mirrors = {name: RosEvents(_Discard(), world) for name, world in worlds.items()}

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)

    def emit(self, event: str, **fields: Any) -> None:
        """Record the event, then mirror it on its robot's topics."""
        self.inner.emit(event, **fields)
        mirror = self.mirrors.get(str(fields.get("robot", "")))
        if mirror is not None:
            mirror.emit(event, **fields)


class _Discard:
    """A sink that records nothing (the fleet's tick log already has the event)."""

    def emit(self, event: str, **fields: Any) -> None:
        """Drop the event."""
