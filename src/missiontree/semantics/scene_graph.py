"""The hierarchical scene graph in the NAIS paper's JSON shape: building → rooms → objects.

The shape, exactly as the NAIS paper's scene-graph prompt (Listing 1) asks GPT-4 to return it::

    {"nodes": [{"id": 0, "type": "building", "label": "Building", "description": ""},
               {"id": "room_1", "type": "room", "label": "kitchen", "description": "..."},
               {"id": "cup_1", "type": "object", "label": "cup", "description": "a red cup ...",
                "coordinates": [1.2, 3.4, 0.05]}],
     "edges": [{"source_id": 0, "source_label": "Building", "target_id": "room_1",
                "target_label": "kitchen", "relation": "contains"}, ...]}

Nodes have ``id``, ``type`` (``building``, ``room`` or ``object``), ``label``, ``description`` and,
for objects only, ``coordinates``; edges have ``source_id``, ``source_label``, ``target_id``,
``target_label`` and ``relation``. The building has id 0. A graph written by the paper's pipeline
loads here (ids may be numbers or strings; coordinates a list ``[x, y, z]`` or a mapping with x, y,
z) and ours is written in that shape with nothing added. Every edge naming a node that does not
exist is dropped (the paper's rule — "Do NOT create edges to missing entities" — enforced here, not
asked for).

Our graphs are *computed*: :meth:`SceneGraph.build` assembles the semantic map's instances, the rooms
and the spatial relations of :mod:`missiontree.semantics.relations`; no language model is needed.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple, Protocol

from missiontree.errors import ConfigError
from missiontree.file_limits import MAX_SCENE_GRAPH_BYTES, read_input_text
from missiontree.files import write_whole

#: The building node's id and label, as the NAIS prompt fixes them.
BUILDING_ID = 0
BUILDING_LABEL = "Building"
NODE_TYPES = ("building", "room", "object")
CONTAINS = "contains"

_NODE_KEYS = ("id", "type", "label", "description", "coordinates")
_EDGE_KEYS = ("source_id", "source_label", "target_id", "target_label", "relation")
#: Encoders without indent (only those use the C encoder); text as it is, not \u-escaped.
_COMPACT = json.JSONEncoder(ensure_ascii=False)
_MARKED = json.JSONEncoder(ensure_ascii=False, separators=(",\x1e", ": "))


class SceneGraphError(ConfigError):
    """A scene-graph document is not in the NAIS shape (the message says where and how)."""


class RoomLike(Protocol):
    """What the graph needs of a room: an id, a label (its type) and a description."""

    id: str

    @property
    def label(self) -> str:
        """The room's name in the graph (its type, e.g. ``kitchen``)."""
        ...

    def describe(self) -> str:
        """One sentence."""
        ...


class ObjectLike(Protocol):
    """What the graph needs of an object (a :class:`~missiontree.semantics.semantic_map.Instance`)."""

    id: str
    label: str
    position: tuple[float, float, float]
    description: str
    room: str | None


class RelationEdge(NamedTuple):
    """A spatial or semantic relation between two objects: ``source`` is ``relation`` ``target``.

    A named tuple, not a dataclass: a rebuild makes hundreds of them and a tuple is made several
    times faster than a frozen dataclass.
    """

    source_id: Any
    target_id: Any
    relation: str


def _key(node_id: Any) -> str:
    """Ids compare as text: the paper's pipeline writes numbers, ours strings."""
    return str(node_id)


@dataclass
class SceneGraph:
    """Nodes and edges in the NAIS shape (see module docstring).

    Attributes:
        nodes: Node dicts with the NAIS keys.
        edges: Edge dicts with the NAIS keys.
        dropped: Edges dropped because they named a missing node (for reporting).
    """

    nodes: list[dict[str, Any]] = field(default_factory=list)
    edges: list[dict[str, Any]] = field(default_factory=list)
    dropped: list[dict[str, Any]] = field(default_factory=list)

    # -- reading ---------------------------------------------------------------------------------

    @classmethod
    def from_json(cls, source: str | bytes | Mapping[str, Any]) -> SceneGraph:
        """Read a graph from JSON text or an already parsed dict; drop edges to missing nodes.

        Raises:
            SceneGraphError: Not JSON, or not the NAIS shape (says which node or edge and why).
        """
        if isinstance(source, str | bytes):
            try:
                data = json.loads(source)
            except (json.JSONDecodeError, UnicodeDecodeError) as exc:  # bytes may not even be text
                raise SceneGraphError(
                    f"scene graph: not JSON ({exc}); expected an object with 'nodes' and 'edges'"
                ) from None
        else:
            data = source
        if not isinstance(data, Mapping) or not isinstance(data.get("nodes"), list):
            keys = sorted(data) if isinstance(data, Mapping) else "-"
            raise SceneGraphError(
                "scene graph: expected an object with a 'nodes' list and an 'edges' list, "
                f"found {type(data).__name__} with keys {keys}"
            )
        nodes = [_read_node(i, raw) for i, raw in enumerate(data["nodes"])]
        raw_edges = data.get("edges", [])
        if not isinstance(raw_edges, list):
            raise SceneGraphError(f"scene graph: 'edges' must be a list, found {type(raw_edges).__name__}")
        graph = cls(nodes=nodes, edges=[_read_edge(i, raw) for i, raw in enumerate(raw_edges)])
        seen: set[str] = set()
        for node in nodes:
            if _key(node["id"]) in seen:
                raise SceneGraphError(
                    f"scene graph: two nodes have the id {node['id']!r}; ids must be unique"
                )
            seen.add(_key(node["id"]))
        graph.drop_dangling()
        return graph

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> SceneGraph:
        """Read a graph from a JSON file (``scene_graph.json`` or the paper's ``Scene_Graph.json``)."""
        text = read_input_text(path, MAX_SCENE_GRAPH_BYTES, "scene graph file", "a scene graph file is JSON",
                               SceneGraphError)
        try:
            return cls.from_json(text)
        except SceneGraphError as exc:
            raise SceneGraphError(f"{path}: {exc}") from None

    # -- writing ---------------------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        """The NAIS-shaped dict (only the NAIS keys, in their order)."""
        return {
            "nodes": [{k: n[k] for k in _NODE_KEYS if k in n} for n in self.nodes],
            "edges": [{k: e[k] for k in _EDGE_KEYS} for e in self.edges],
        }

    def to_json(self, indent: int | None = 2) -> str:
        """The graph as JSON text: one node or edge a line, indented by ``indent``; one line if None.

        One item a line reads as well as a fully indented dump and is written by the C encoder:
        ``json.dumps(..., indent=2)`` falls back to the pure-Python encoder, several times slower
        (about 5 ms for a 300-object graph, on every change of ``scene_graph.json``).
        """
        data = self.to_dict()
        if indent is None:
            return _COMPACT.encode(data)
        pad = " " * indent
        lines = []
        for key in ("nodes", "edges"):
            items = data[key]
            if items:
                # each list in one call of the C encoder; its separators carry a control character,
                # which never stands unescaped inside a JSON string, and become a line break between
                # the list's items and a space everywhere else
                body = _MARKED.encode(items)[1:-1]
                body = body.replace("},\x1e{", "},\n" + pad + pad + "{").replace("\x1e", " ")
                lines.append(f'{pad}"{key}": [\n{pad}{pad}{body}\n{pad}]')
            else:
                lines.append(f'{pad}"{key}": []')
        return "{\n" + ",\n".join(lines) + "\n}"

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the graph atomically (a reader never sees half a file); return the path."""
        return write_whole(path, (self.to_json() + "\n").encode("utf-8"))

    # -- queries ---------------------------------------------------------------------------------

    def node(self, node_id: Any) -> dict[str, Any] | None:
        """The node with this id (numbers and strings compare as text), or None."""
        wanted = _key(node_id)
        for node in self.nodes:
            if _key(node["id"]) == wanted:
                return node
        return None

    def building(self) -> dict[str, Any] | None:
        """The building node."""
        return next((n for n in self.nodes if n["type"] == "building"), None)

    def rooms(self) -> list[dict[str, Any]]:
        """Every room node."""
        return [n for n in self.nodes if n["type"] == "room"]

    def objects(self) -> list[dict[str, Any]]:
        """Every object node."""
        return [n for n in self.nodes if n["type"] == "object"]

    def relations_of(self, node_id: Any, include_contains: bool = False) -> list[dict[str, Any]]:
        """Edges that have the node as source or target (``contains`` only when asked)."""
        wanted = _key(node_id)
        return [
            e
            for e in self.edges
            if wanted in (_key(e["source_id"]), _key(e["target_id"]))
            and (include_contains or e["relation"] != CONTAINS)
        ]

    def room_of(self, node_id: Any) -> dict[str, Any] | None:
        """The room that (directly, or through a containing object) contains the node, or None."""
        parents = {_key(e["target_id"]): e["source_id"] for e in self.edges if e["relation"] == CONTAINS}
        current, visited = _key(node_id), set()
        while current in parents and current not in visited:
            visited.add(current)
            parent = self.node(parents[current])
            if parent is None:
                return None
            if parent["type"] == "room":
                return parent
            current = _key(parent["id"])
        return None

    def drop_dangling(self) -> list[dict[str, Any]]:
        """Drop every edge whose source or target is not a node; return the dropped edges."""
        ids = {_key(n["id"]) for n in self.nodes}
        kept: list[dict[str, Any]] = []
        dropped: list[dict[str, Any]] = []
        for edge in self.edges:
            whole = _key(edge["source_id"]) in ids and _key(edge["target_id"]) in ids
            (kept if whole else dropped).append(edge)
        self.edges = kept
        self.dropped.extend(dropped)
        return dropped

    def add_relations(self, relations: Iterable[RelationEdge | Mapping[str, Any]]) -> int:
        """Add relation edges (e.g. from a language model); edges naming a missing node are dropped.

        An edge equal to one already in the graph (same source, target and relation) is not added
        twice.

        Returns:
            How many edges were dropped.
        """
        before = len(self.dropped)
        # ids compare as text (see _key); str() inline: this loop runs for every edge of a rebuild
        index = {str(n["id"]): n for n in self.nodes}
        existing = {(str(e["source_id"]), str(e["target_id"]), e["relation"]) for e in self.edges}
        edges, dropped = self.edges, self.dropped
        for rel in relations:
            raw: Any
            if isinstance(rel, RelationEdge):
                source_id, target_id, raw = rel
            else:
                source_id, target_id, raw = rel.get("source_id"), rel.get("target_id"), rel.get("relation")
            relation = str(raw or "")
            source_key, target_key = str(source_id), str(target_id)
            source, target = index.get(source_key), index.get(target_key)
            if source is None or target is None or not relation:
                dropped.append(
                    {
                        "source_id": source_id,
                        "source_label": source["label"] if source else "",
                        "target_id": target_id,
                        "target_label": target["label"] if target else "",
                        "relation": relation,
                    }
                )
                continue
            key = (source_key, target_key, relation)
            if key not in existing:
                existing.add(key)
                edges.append(
                    {
                        "source_id": source_id,
                        "source_label": source["label"],
                        "target_id": target_id,
                        "target_label": target["label"],
                        "relation": relation,
                    }
                )
        return len(self.dropped) - before

    # -- building --------------------------------------------------------------------------------

    @classmethod
    def build(
        cls,
        objects: Sequence[ObjectLike],
        rooms: Sequence[RoomLike],
        relations: Iterable[RelationEdge] = (),
        building_label: str = BUILDING_LABEL,
    ) -> SceneGraph:
        """Assemble building → rooms → objects with ``contains`` edges and the given relations.

        An object whose ``room`` names no room in ``rooms`` hangs directly under the building.
        """
        nodes: list[dict[str, Any]] = [
            {"id": BUILDING_ID, "type": "building", "label": building_label, "description": ""}
        ]
        edges: list[dict[str, Any]] = []
        room_labels: dict[str, str] = {}
        for room in rooms:
            nodes.append({"id": room.id, "type": "room", "label": room.label, "description": room.describe()})
            edges.append(
                {
                    "source_id": BUILDING_ID,
                    "source_label": building_label,
                    "target_id": room.id,
                    "target_label": room.label,
                    "relation": CONTAINS,
                }
            )
            room_labels[room.id] = room.label
        nodes_append, edges_append = nodes.append, edges.append
        for obj in objects:
            x, y, z = obj.position
            obj_id, label, obj_room = obj.id, obj.label, obj.room
            nodes_append(
                {
                    "id": obj_id,
                    "type": "object",
                    "label": label,
                    "description": obj.description or f"a {label}",
                    "coordinates": [round(x, 3), round(y, 3), round(z, 3)],
                }
            )
            room_label = room_labels.get(obj_room) if obj_room is not None else None
            edges_append(
                {
                    "source_id": obj_room if room_label is not None else BUILDING_ID,
                    "source_label": room_label if room_label is not None else building_label,
                    "target_id": obj_id,
                    "target_label": label,
                    "relation": CONTAINS,
                }
            )
        graph = cls(nodes=nodes, edges=edges)
        graph.add_relations(relations)
        return graph

    def object_coordinates(self) -> dict[str, tuple[float, float, float]]:
        """Object id (as text) → (x, y, z)."""
        return {
            _key(n["id"]): tuple(n["coordinates"])
            for n in self.objects()  # type: ignore[misc]
            if n.get("coordinates") is not None
        }


def _read_node(index: int, raw: Any) -> dict[str, Any]:
    where = f"scene graph: nodes[{index}]"
    if not isinstance(raw, Mapping):
        raise SceneGraphError(f"{where}: expected an object with id, type, label, found {type(raw).__name__}")
    missing = [k for k in ("id", "type", "label") if k not in raw]
    if missing:
        raise SceneGraphError(
            f"{where}: missing {', '.join(missing)} (a node has id, type, label, "
            "description and, for objects, coordinates)"
        )
    node_type = str(raw["type"]).strip().lower()
    if node_type not in NODE_TYPES:
        raise SceneGraphError(f"{where}: type {_brief(raw['type'])} is not one of {', '.join(NODE_TYPES)}")
    node_id = raw["id"]
    if isinstance(node_id, float) and math.isfinite(node_id) and node_id.is_integer():
        node_id = int(node_id)  # 3.0 written by a JSON tool is the paper's id 3
    if isinstance(node_id, bool) or not isinstance(node_id, str | int) or node_id == "":
        raise SceneGraphError(f"{where}: id {_brief(node_id)}: expected a text or integer id")
    node: dict[str, Any] = {
        "id": node_id,
        "type": node_type,
        "label": str(raw["label"]),
        "description": str(raw.get("description") or ""),
    }
    if node_type == "object" and raw.get("coordinates") is not None:
        node["coordinates"] = _read_coordinates(where, raw["coordinates"])
    return node


def _brief(raw: Any) -> str:
    """A short form of an untrusted value for a message (never the whole of it)."""
    text = repr(raw)
    return text if len(text) <= 60 else text[:57] + "..."


def _read_coordinates(where: str, raw: Any) -> list[float]:
    if isinstance(raw, Mapping):
        try:
            values = [float(raw["x"]), float(raw["y"]), float(raw.get("z", 0.0))]
        except (KeyError, TypeError, ValueError, OverflowError):
            raise SceneGraphError(f"{where}: coordinates {_brief(raw)}: expected x, y (and z)") from None
    elif isinstance(raw, list | tuple) and len(raw) in (2, 3):
        try:
            values = [float(v) for v in raw] + [0.0] * (3 - len(raw))
        except (TypeError, ValueError, OverflowError):
            raise SceneGraphError(f"{where}: coordinates {_brief(raw)}: expected numbers") from None
    else:
        raise SceneGraphError(f"{where}: coordinates {_brief(raw)}: expected [x, y, z] or {{x, y, z}}")
    if not all(math.isfinite(v) for v in values):  # a NaN place would reach the planner as a goal
        raise SceneGraphError(f"{where}: coordinates {_brief(raw)}: expected finite numbers")
    return values


def _read_edge(index: int, raw: Any) -> dict[str, Any]:
    where = f"scene graph: edges[{index}]"
    if not isinstance(raw, Mapping):
        raise SceneGraphError(f"{where}: expected an object, found {type(raw).__name__}")
    missing = [k for k in ("source_id", "target_id", "relation") if k not in raw]
    if missing:
        raise SceneGraphError(
            f"{where}: missing {', '.join(missing)} (an edge has source_id, source_label, "
            "target_id, target_label and relation)"
        )
    return {
        "source_id": raw["source_id"],
        "source_label": str(raw.get("source_label") or ""),
        "target_id": raw["target_id"],
        "target_label": str(raw.get("target_label") or ""),
        "relation": str(raw["relation"]),
    }
