"""Fuzzing two more doors untrusted input comes in by: scene-graph files and the command stream.

- A scene graph file (``scene_graph.json``, a graph a user or a model hands over) is read by
  :meth:`SceneGraph.from_json`: a graph in the NAIS shape or a :class:`SceneGraphError` naming what is
  wrong, for mutated graphs, any JSON and arbitrary bytes.
- The command channel (stdin in the simulator) reads any bytes: every line becomes a command of
  printable text at most :data:`MAX_COMMAND_CHARS` long or a refused command with its reason; nothing
  is lost (one delivered entry a line), nothing raises, and the channel closes at the end.

Budget: the ``ci`` profile in CI, ``MISSIONTREE_FUZZ=nightly`` for 10,000 cases a test.
"""

from __future__ import annotations

import io
import json
import time

from hypothesis import given
from hypothesis import strategies as st
from strategies import mutations, values

from missiontree.robot.commands import MAX_COMMAND_CHARS, LineCommands, clean_command
from missiontree.semantics.scene_graph import SceneGraph, SceneGraphError

GRAPH = {
    "nodes": [
        {"id": 0, "type": "building", "label": "Building", "description": ""},
        {"id": "room_1", "type": "room", "label": "kitchen", "description": "kitchen, 12 m2"},
        {"id": "cup_1", "type": "object", "label": "cup", "description": "a red cup",
         "coordinates": [1.0, 2.0, 0.8]},
        {"id": "table_1", "type": "object", "label": "table", "description": "a brown table",
         "coordinates": [1.2, 2.1, 0.4]},
    ],
    "edges": [
        {"source_id": 0, "source_label": "Building", "target_id": "room_1", "target_label": "kitchen",
         "relation": "contains"},
        {"source_id": "room_1", "source_label": "kitchen", "target_id": "cup_1", "target_label": "cup",
         "relation": "contains"},
        {"source_id": "cup_1", "source_label": "cup", "target_id": "table_1", "target_label": "table",
         "relation": "on"},
    ],
}


def _read(source: object) -> None:
    try:
        graph = SceneGraph.from_json(source)  # type: ignore[arg-type]
    except SceneGraphError:
        return
    json.dumps(graph.nodes, allow_nan=False)  # what was read is plain, finite JSON again
    ids = {str(n.get("id")) for n in graph.nodes}
    assert all(str(e.get("source_id")) in ids and str(e.get("target_id")) in ids for e in graph.edges)


@given(mutations([GRAPH]))
def test_mutated_scene_graphs_are_read_or_refused(graph: object) -> None:
    """A NAIS graph with values replaced, dropped or added is read (finite, known edges) or refused."""
    _read(graph)
    try:
        text = json.dumps(graph, allow_nan=True)
    except (TypeError, ValueError):
        return
    _read(text)


@given(st.one_of(values(), st.binary(max_size=200)))
def test_any_json_or_bytes_as_a_scene_graph_is_read_or_refused(data: object) -> None:
    """Any JSON value, or bytes, given as a scene graph is read or refused with SceneGraphError."""
    _read(data if isinstance(data, bytes) else json.dumps(data, allow_nan=True))


class _Stdin(io.TextIOWrapper):
    """A text stream over bytes, as ``sys.stdin`` is (it has a ``buffer``)."""


def _says_something(line: bytes) -> bool:
    """A line that must arrive: text with something printable in it, or bytes that are not text."""
    try:
        return bool(clean_command(line.decode("utf-8")))
    except UnicodeDecodeError:
        return True


def _commands(raw: bytes) -> list[object]:
    channel = LineCommands(_Stdin(io.BytesIO(raw), encoding="utf-8"))
    got: list[object] = []
    deadline = time.process_time() + 5.0
    while not channel.closed:
        got += channel.poll(0.0)
        assert time.process_time() < deadline, "the channel never closed"
        time.sleep(0.001)
    return got + channel.poll(0.0)


_HOSTILE_LINES = st.sampled_from([b"\xff\xfe", b"\x1b[31mred\x1b[0m", b"\r", b"\x00" * 5, b"a" * 600])


@given(st.lists(st.one_of(st.binary(max_size=80), st.text(max_size=80).map(str.encode), _HOSTILE_LINES),
                max_size=8))
def test_any_bytes_on_the_command_stream_become_commands_or_refusals(lines: list[bytes]) -> None:
    """Every line of any bytes arrives as a printable command or a refusal; none is lost, none raises."""
    raw = b"\n".join(line.replace(b"\n", b" ") for line in lines)
    got = _commands(raw)
    assert len(got) == sum(1 for part in raw.split(b"\n") if _says_something(part)) if raw else not got
    for command in got:
        text, error = command.text, command.error  # type: ignore[attr-defined]
        assert bool(text) != bool(error) or (not text and not error)
        assert len(text) <= MAX_COMMAND_CHARS and text.isprintable()
