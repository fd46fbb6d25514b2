"""SceneGraph: the NAIS JSON shape read and written exactly; dangling edges dropped; queries."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from missiontree.semantics.scene_graph import RelationEdge, SceneGraph, SceneGraphError
from missiontree.semantics.semantic_map import SemanticMap

#: A graph as the NAIS paper's pipeline writes it (numeric ids, coordinates as a mapping, an edge
#: to an object GPT-4 invented).
NAIS_GRAPH = {
    "nodes": [
        {"id": 0, "type": "building", "label": "Building", "description": ""},
        {"id": 1, "type": "room", "label": "kitchen", "description": "a kitchen with a fridge"},
        {"id": 2, "type": "room", "label": "office", "description": "an office"},
        {
            "id": 3,
            "type": "object",
            "label": "cup",
            "description": "a pink cup",
            "coordinates": {"x": 1.0, "y": 2.0, "z": 0.1},
        },
        {
            "id": 4,
            "type": "object",
            "label": "sofa",
            "description": "a grey sofa",
            "coordinates": [6.0, 3.0, 0.4],
        },
        {
            "id": 5,
            "type": "object",
            "label": "laptop",
            "description": "in front of the sofa",
            "coordinates": [6.0, 2.2, 0.1],
        },
    ],
    "edges": [
        {
            "source_id": 0,
            "source_label": "Building",
            "target_id": 1,
            "target_label": "kitchen",
            "relation": "contains",
        },
        {
            "source_id": 0,
            "source_label": "Building",
            "target_id": 2,
            "target_label": "office",
            "relation": "contains",
        },
        {
            "source_id": 1,
            "source_label": "kitchen",
            "target_id": 3,
            "target_label": "cup",
            "relation": "contains",
        },
        {
            "source_id": 2,
            "source_label": "office",
            "target_id": 4,
            "target_label": "sofa",
            "relation": "contains",
        },
        {
            "source_id": 4,
            "source_label": "sofa",
            "target_id": 5,
            "target_label": "laptop",
            "relation": "contains",
        },
        {
            "source_id": 5,
            "source_label": "laptop",
            "target_id": 4,
            "target_label": "sofa",
            "relation": "in front of",
        },
        {
            "source_id": 5,
            "source_label": "laptop",
            "target_id": 99,
            "target_label": "desk",
            "relation": "on top of",
        },
    ],
}


def test_a_graph_from_the_paper_pipeline_loads_and_its_dangling_edge_is_dropped() -> None:
    """Numeric ids and mapping coordinates load; the edge to the missing node 99 is dropped."""
    graph = SceneGraph.from_json(json.dumps(NAIS_GRAPH))
    assert len(graph.nodes) == 6
    assert len(graph.edges) == 6
    assert [e["target_id"] for e in graph.dropped] == [99]
    assert graph.node(3)["coordinates"] == [1.0, 2.0, 0.1]
    assert graph.node("3") is graph.node(3)  # ids compare as text


def test_round_trip_keeps_exactly_the_nais_keys() -> None:
    """Written JSON has only the NAIS keys, coordinates only on objects, and reads back equal."""
    graph = SceneGraph.from_json(NAIS_GRAPH)
    data = json.loads(graph.to_json())
    for node in data["nodes"]:
        expected = {"id", "type", "label", "description"} | (
            {"coordinates"} if node["type"] == "object" else set()
        )
        assert set(node) == expected
    for edge in data["edges"]:
        assert set(edge) == {"source_id", "source_label", "target_id", "target_label", "relation"}
    assert SceneGraph.from_json(data).to_dict() == graph.to_dict()


def test_room_of_follows_contains_through_a_containing_object() -> None:
    """The laptop is contained by the sofa, which the office contains: its room is the office."""
    graph = SceneGraph.from_json(NAIS_GRAPH)
    assert graph.room_of(5)["label"] == "office"
    assert graph.room_of(3)["label"] == "kitchen"
    assert graph.room_of(0) is None
    assert [e["relation"] for e in graph.relations_of(5)] == ["in front of"]


def test_build_from_instances_puts_objects_under_their_rooms(tmp_path: Path) -> None:
    """Building 0 contains the rooms, each room its objects; an object in no room hangs under the building."""

    class Room:
        id = "room_1"
        label = "kitchen"

        def describe(self) -> str:
            return "a kitchen"

    smap = SemanticMap()
    smap.add("cup", (1.0, 2.0, 0.05), 0.0, room="room_1")
    smap.add("chair", (4.0, 2.0, 0.4), 0.0)
    graph = SceneGraph.build(
        list(smap),
        [Room()],
        [RelationEdge("cup_1", "chair_1", "near"), RelationEdge("cup_1", "ghost_9", "near")],
    )
    contains = {(str(e["source_id"]), e["target_id"]) for e in graph.edges if e["relation"] == "contains"}
    assert contains == {("0", "room_1"), ("room_1", "cup_1"), ("0", "chair_1")}
    assert [e["target_id"] for e in graph.dropped] == ["ghost_9"]
    path = graph.save(tmp_path / "scene_graph.json")
    assert SceneGraph.load(path).to_dict() == graph.to_dict()


@pytest.mark.parametrize(
    "text, fragment",
    [
        ("not json", "not JSON"),
        ('{"nodes": [{"id": 1, "label": "x"}], "edges": []}', "missing type"),
        ('{"nodes": [{"id": 1, "type": "planet", "label": "x"}], "edges": []}', "not one of"),
        (
            '{"nodes": [{"id": 1, "type": "room", "label": "a"}, {"id": 1, "type": "room", "label": "b"}]}',
            "unique",
        ),
        ('{"nodes": [{"id": 1, "type": "object", "label": "a", "coordinates": "here"}]}', "coordinates"),
        ('{"edges": []}', "'nodes' list"),
    ],
)
def test_malformed_graphs_are_refused_saying_why(text: str, fragment: str) -> None:
    """Each shape error is a SceneGraphError naming the node and the problem."""
    with pytest.raises(SceneGraphError, match=fragment):
        SceneGraph.from_json(text)


def test_json_text_has_one_node_or_edge_a_line_and_reads_back_exactly() -> None:
    """Indented text puts each item on its own line; quotes, unicode and control characters survive."""
    graph = SceneGraph.from_json(NAIS_GRAPH)
    graph.nodes[1]["description"] = 'a "big" kitchen },{ with\x1e a tab\there and ünïcode'
    text = graph.to_json()
    lines = text.splitlines()
    assert lines[0] == "{" and lines[1] == '  "nodes": [' and lines[-1] == "}"
    assert sum(line.startswith('    {"id": ') for line in lines) == len(graph.nodes)
    assert sum(line.startswith('    {"source_id": ') for line in lines) == len(graph.edges)
    assert json.loads(text) == graph.to_dict()
    assert json.loads(graph.to_json(indent=None)) == graph.to_dict()
    assert "\n" not in graph.to_json(indent=None)
    assert json.loads(SceneGraph().to_json()) == {"nodes": [], "edges": []}


def test_non_finite_coordinates_are_refused_without_echoing_the_file() -> None:
    """A NaN, infinite or overflowing coordinate is a SceneGraphError, and the message stays short."""
    from missiontree.semantics.scene_graph import SceneGraph, SceneGraphError

    for bad in ("[1.0, NaN, 0.2]", "[1.0, Infinity]", "[1e400, 0, 0]", '{"x": 1, "y": -Infinity}'):
        node = '{"id": "cup_1", "type": "object", "label": "cup", "coordinates": ' + bad + "}"
        text = '{"nodes": [' + node + '], "edges": []}'
        with pytest.raises(SceneGraphError, match="expected finite numbers") as caught:
            SceneGraph.from_json(text)
        assert len(str(caught.value)) < 200


def test_an_id_must_be_text_or_an_integer() -> None:
    """A NaN, boolean, list or empty id is refused; 3.0 reads as the integer id 3."""
    from missiontree.semantics.scene_graph import SceneGraph, SceneGraphError

    for bad in ("NaN", "true", "[1]", '""'):
        text = '{"nodes": [{"id": ' + bad + ', "type": "room", "label": "hall"}], "edges": []}'
        with pytest.raises(SceneGraphError, match="expected a text or integer id"):
            SceneGraph.from_json(text)
    graph = SceneGraph.from_json('{"nodes": [{"id": 3.0, "type": "room", "label": "hall"}], "edges": []}')
    assert graph.nodes[0]["id"] == 3
