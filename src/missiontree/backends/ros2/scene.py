"""The scene graph as ROS messages: ``/scene_graph`` JSON and an RViz MarkerArray of its objects.

Pure conversion functions (no node), used by
:meth:`missiontree.backends.ros2.publish.WorldPublisher.scene_graph`, which the ``scene_graph``
events of the ``BuildSceneGraph`` leaf reach through
:class:`~missiontree.backends.ros2.publish.RosEvents` (on every change and at least every 30 s, on a
RELIABLE, TRANSIENT_LOCAL publisher, so a late RViz or subscriber gets the latest graph):

- :func:`scene_graph_message` — ``std_msgs/String`` holding the NAIS-shaped JSON, as the NAIS
  paper publishes ``/scene_graph``;
- :func:`scene_markers` — a ``visualization_msgs/MarkerArray``: DELETEALL, then for each object a
  cube coloured by its class (the NAIS paper's colours: chairs green, umbrellas blue, bottles purple,
  cups pink, sofas lime; other classes a stable colour of their name) with a text label (its id),
  and each room's name floating over the middle of its objects.
"""

from __future__ import annotations

import json
import zlib
from collections.abc import Callable, Mapping
from typing import Any

from std_msgs.msg import ColorRGBA, String
from visualization_msgs.msg import Marker, MarkerArray

from missiontree.backends.ros2.conversions import sec_to_time

CUBE = 0.25
NAMESPACE = "scene_graph"


def scene_graph_message(graph: Mapping[str, Any]) -> String:
    """The graph as ``std_msgs/String`` JSON (keys in the NAIS order, as written to scene_graph.json)."""
    return String(data=json.dumps(graph, ensure_ascii=False, default=str))


def _marker(kind: int, marker_id: int, stamp: float, frame_id: str, namespace: str) -> Marker:
    marker = Marker()
    marker.header.stamp = sec_to_time(stamp)
    marker.header.frame_id = frame_id
    marker.ns = namespace
    marker.id = marker_id
    marker.type = kind
    marker.action = Marker.ADD
    marker.pose.orientation.w = 1.0
    return marker


def _stable_id(key: str) -> int:
    return zlib.crc32(key.encode("utf-8")) % 1_000_000 + 1


def scene_markers(
    graph: Mapping[str, Any],
    stamp: float,
    colour: Callable[[str], tuple[float, float, float]],
    frame_id: str = "map",
) -> MarkerArray:
    """Cubes coloured by class with text labels for the objects, and the rooms' names (see module docstring).

    Nodes without coordinates (rooms, the building) are placed over the middle of what they contain.
    A graph with no ``nodes`` list gives only the DELETEALL. ``colour`` maps a class label to RGB in
    [0, 1] (the publisher's :func:`~missiontree.backends.ros2.publish.label_colour`).
    """
    clear = Marker()
    clear.action = Marker.DELETEALL
    clear.ns = NAMESPACE
    markers = [clear]
    nodes = graph.get("nodes")
    if not isinstance(nodes, list):
        return MarkerArray(markers=markers)
    objects = [
        n
        for n in nodes
        if isinstance(n, Mapping)
        and n.get("type") == "object"
        and isinstance(n.get("coordinates"), list | tuple)
        and len(n["coordinates"]) >= 2
    ]
    where = {str(n["id"]): n["coordinates"] for n in objects}
    for node in objects:
        markers += _object_markers(node, stamp, frame_id, colour)
    edges = graph.get("edges")
    edges = edges if isinstance(edges, list) else []
    for node in nodes:
        if isinstance(node, Mapping) and node.get("type") == "room":
            name = _room_marker(node, edges, where, stamp, frame_id)
            if name is not None:
                markers.append(name)
    return MarkerArray(markers=markers)


def _object_markers(node: Mapping[str, Any], stamp: float, frame_id: str,
                    colour: Callable[[str], tuple[float, float, float]]) -> list[Marker]:
    """An object's cube in its class's colour and its id above it."""
    x, y = float(node["coordinates"][0]), float(node["coordinates"][1])
    z = float(node["coordinates"][2]) if len(node["coordinates"]) > 2 else CUBE / 2
    key = str(node["id"])
    r, g, b = colour(str(node.get("label", "")))
    cube = _marker(Marker.CUBE, 2 * _stable_id(key), stamp, frame_id, NAMESPACE)
    cube.pose.position.x, cube.pose.position.y, cube.pose.position.z = x, y, z
    cube.scale.x = cube.scale.y = cube.scale.z = CUBE
    cube.color = ColorRGBA(r=r, g=g, b=b, a=0.9)
    labels_ns = f"{NAMESPACE}/labels"
    text = _marker(Marker.TEXT_VIEW_FACING, 2 * _stable_id(key) + 1, stamp, frame_id, labels_ns)
    text.pose.position.x, text.pose.position.y, text.pose.position.z = x, y, z + CUBE
    text.scale.z = 0.15
    text.color = ColorRGBA(r=1.0, g=1.0, b=1.0, a=1.0)
    text.text = key
    return [cube, text]


def _room_marker(node: Mapping[str, Any], edges: list[Any], where: Mapping[str, Any], stamp: float,
                 frame_id: str) -> Marker | None:
    """A room's name over the middle of the objects it contains (None when it contains none)."""
    inside = [
        where[str(e.get("target_id"))]
        for e in edges
        if isinstance(e, Mapping)
        and e.get("relation") == "contains"
        and str(e.get("source_id")) == str(node.get("id"))
        and str(e.get("target_id")) in where
    ]
    if not inside:
        return None
    name = _marker(
        Marker.TEXT_VIEW_FACING, _stable_id(f"room:{node['id']}"), stamp, frame_id, f"{NAMESPACE}/rooms"
    )
    name.pose.position.x = sum(float(c[0]) for c in inside) / len(inside)
    name.pose.position.y = sum(float(c[1]) for c in inside) / len(inside)
    name.pose.position.z = 1.5
    name.scale.z = 0.35
    name.color = ColorRGBA(r=1.0, g=0.9, b=0.3, a=1.0)
    name.text = f"{node.get('label', 'room')} ({node['id']})"
    return name
