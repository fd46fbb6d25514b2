"""Groot2 log files: a run's status transitions as BehaviorTree.CPP 4.x's ``FileLogger2`` writes them.

The layout (``bt_file_logger_v2.cpp``; every number little-endian)::

    "BTCPP4-FileLogger2"            18 bytes
    protocol                        uint8, 1
    xml_size                        int32
    xml                             WriteTreeToXML(tree, add_metadata=true, add_builtin_models=true)
    first_timestamp                 int64, microseconds
    transitions                     9 bytes each, until the end of the file:
        timestamp                   6 bytes: microseconds since first_timestamp
        uid                         uint16: the node's _uid in the XML
        status                      uint8: IDLE 0, RUNNING 1, SUCCESS 2, FAILURE 3, SKIPPED 4

The XML is printed as tinyxml2's ``XMLPrinter`` prints it (four spaces a level, empty elements
closed with ``/>``): ``<root BTCPP_format="4">``, one ``<BehaviorTree ID="MainTree">`` with every
node as an element named by its type, carrying ``name``, ``_uid`` (1, 2, ... in depth-first order,
as BehaviorTree.CPP numbers nodes it creates) and the node's parameters as attributes; then a
``<TreeNodesModel>`` declaring each type (``Action``, ``Decorator`` or ``Control``) with its
parameters as input ports, sorted by type name. A node's conditions (the tick log's ``conditions``
events) are written as BT.CPP 4's attributes (``skip_if`` as ``_skipIf``, ``on_success`` as
``_onSuccess``, ...), with missiontree's expression text as written (BT.CPP spells ``and`` as
``&&``: Groot2 shows them, it does not evaluate them), and are not ports. Times are the robot
clock's (simulated seconds in the simulator, so the same run gives the same bytes). py_trees'
INVALID is Groot's IDLE; the halt at the end of a run is written too, as BehaviorTree.CPP logs
transitions to IDLE.
"""

from __future__ import annotations

import json
import re
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from missiontree.errors import ConfigError
from missiontree.runlog.replay import Replay

MAGIC = b"BTCPP4-FileLogger2"
PROTOCOL = 1
#: Groot's status codes (py_trees INVALID is IDLE); the replay's codes are the same numbers.
GROOT_STATUS = ("IDLE", "RUNNING", "SUCCESS", "FAILURE", "SKIPPED")
_MODEL_ELEMENT = {"leaf": "Action", "decorator": "Decorator", "composite": "Control"}
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_.\-]*$")
_MAX_OFFSET = (1 << 48) - 1
#: missiontree's condition keys and BehaviorTree.CPP 4's attribute names for them.
BTCPP_CONDITIONS = {"fail_if": "_failureIf", "succeed_if": "_successIf", "skip_if": "_skipIf",
                    "while": "_while", "on_success": "_onSuccess", "on_failure": "_onFailure",
                    "on_halted": "_onHalted", "post": "_post"}


def node_conditions(replay: Replay) -> dict[str, dict[str, str]]:
    """Each conditioned node's conditions by path (``{"skip_if": "at_dock"}``), from the log's events."""
    found: dict[str, dict[str, str]] = {}
    for event in replay.events:
        if event.kind != "conditions":
            continue
        node, written = event.fields.get("node"), event.fields.get("conditions")
        if isinstance(node, str) and isinstance(written, dict):
            found[node] = {k: str(v) for k, v in written.items() if k in BTCPP_CONDITIONS}
    return found


def _escape(text: str) -> str:
    """tinyxml2's attribute escaping."""
    return (
        text.replace("&", "&amp;")
        .replace("<", "&lt;")
        .replace(">", "&gt;")
        .replace('"', "&quot;")
        .replace("'", "&apos;")
    )


def _attr_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | float | str):
        return str(value)
    return json.dumps(value, sort_keys=True, separators=(",", ":"))


def _element_name(node_type: str) -> str:
    return node_type if _NAME.match(node_type) else "Unknown"


def preorder(replay: Replay) -> list[int]:
    """Node indices in depth-first order (parents before children), roots in the order met."""
    order: list[int] = []
    stack = [i for i, n in enumerate(replay.nodes) if n.parent < 0][::-1]
    while stack:
        index = stack.pop()
        order.append(index)
        stack.extend(reversed(replay.nodes[index].children))
    return order


def tree_xml(replay: Replay, tree_id: str = "MainTree") -> tuple[str, dict[int, int]]:
    """The tree as ``WriteTreeToXML`` prints it, and node index -> ``_uid``."""
    order = preorder(replay)
    if len(order) > 0xFFFF:
        raise ConfigError(
            f"the tree has {len(order)} nodes; a .btlog numbers nodes with 16 bits (at most 65535)"
        )
    uids = {index: uid for uid, index in enumerate(order, start=1)}
    lines = ['<root BTCPP_format="4">', f'    <BehaviorTree ID="{_escape(tree_id)}" _fullpath="">']
    conditions = node_conditions(replay)

    def write(index: int, depth: int) -> None:
        node = replay.nodes[index]
        element = _element_name(node.type)
        attrs = [f'name="{_escape(node.name)}"', f'_uid="{uids[index]}"']
        attrs += [
            f'{key}="{_escape(_attr_value(value))}"' for key, value in node.params.items()
            if _NAME.match(key) and key not in BTCPP_CONDITIONS
        ]
        written = {**{k: v for k, v in node.params.items() if k in BTCPP_CONDITIONS},
                   **conditions.get(node.path, {})}
        attrs += [f'{BTCPP_CONDITIONS[key]}="{_escape(str(written[key]))}"'
                  for key in BTCPP_CONDITIONS if key in written]
        pad = "    " * depth
        if node.children:
            lines.append(f"{pad}<{element} {' '.join(attrs)}>")
            for child in node.children:
                write(child, depth + 1)
            lines.append(f"{pad}</{element}>")
        else:
            lines.append(f"{pad}<{element} {' '.join(attrs)}/>")

    for root in (i for i, n in enumerate(replay.nodes) if n.parent < 0):
        write(root, 2)
    lines.append("    </BehaviorTree>")
    models: dict[str, tuple[str, set[str]]] = {}
    for node in replay.nodes:
        element = _element_name(node.type)
        category = node.category or (
            "composite" if len(node.children) > 1 else "decorator" if node.children else "leaf"
        )
        kind, ports = models.setdefault(element, (_MODEL_ELEMENT.get(category, "Action"), set()))
        ports.update(k for k in node.params if _NAME.match(k) and k not in BTCPP_CONDITIONS)
    lines.append("    <TreeNodesModel>")
    for element in sorted(models):
        kind, ports = models[element]
        if ports:
            lines.append(f'        <{kind} ID="{_escape(element)}">')
            lines += [f'            <input_port name="{_escape(p)}"/>' for p in sorted(ports)]
            lines.append(f"        </{kind}>")
        else:
            lines.append(f'        <{kind} ID="{_escape(element)}"/>')
    lines.append("    </TreeNodesModel>")
    lines.append("</root>")
    return "\n".join(lines) + "\n", uids


def to_btlog(replay: Replay) -> bytes:
    """The whole ``.btlog`` file of a replayed run."""
    xml, uids = tree_xml(replay)
    encoded = xml.encode("utf-8")
    t0 = replay.times[0] if replay.times else 0.0
    first_us = round(t0 * 1e6)
    out = bytearray(MAGIC)
    out += struct.pack("<B", PROTOCOL)
    out += struct.pack("<i", len(encoded))
    out += encoded
    out += struct.pack("<q", first_us)
    timed = [(replay.times[c.tick], c) for c in replay.changes] + [
        (replay.halted_t, c) for c in replay.halted
    ]
    for t, change in timed:
        offset = min(max(round(t * 1e6) - first_us, 0), _MAX_OFFSET)
        out += offset.to_bytes(6, "little") + struct.pack("<HB", uids[change.node], change.status)
    return bytes(out)


def write_btlog(replay: Replay, path: Path) -> Path:
    """Write the ``.btlog`` of ``replay`` to ``path``."""
    path = Path(path)
    if path.suffix != ".btlog":
        raise ConfigError(
            f"{path}: Groot2 opens FileLogger2 files only with the .btlog extension; "
            f"name the output like run.btlog"
        )
    path.write_bytes(to_btlog(replay))
    return path


@dataclass(frozen=True)
class Transition:
    """One transition read back: microseconds since the first timestamp, node uid, Groot status code."""

    offset_us: int
    uid: int
    status: int


@dataclass
class BtLog:
    """A ``.btlog`` read back."""

    protocol: int
    xml: str
    first_timestamp_us: int
    transitions: list[Transition]

    def nodes(self) -> dict[int, tuple[str, str]]:
        """Uid -> (element name, name) of every node in the XML's BehaviorTree."""
        import xml.etree.ElementTree as ElementTree

        found: dict[int, tuple[str, str]] = {}
        for tree in ElementTree.fromstring(self.xml).iter("BehaviorTree"):
            for element in tree.iter():
                if "_uid" in element.attrib:
                    found[int(element.attrib["_uid"])] = (element.tag, element.attrib.get("name", ""))
        return found


def read_btlog(data: bytes) -> BtLog:
    """Parse a FileLogger2 file (as BehaviorTree.CPP 4.x writes it, or :func:`to_btlog`).

    Raises:
        ValueError: Not a FileLogger2 file, or truncated (says where).
    """
    if not data.startswith(MAGIC):
        raise ValueError(f"not a Groot2 .btlog: the file does not start with {MAGIC.decode()!r}")
    at = len(MAGIC)
    if len(data) < at + 5:
        raise ValueError("truncated .btlog: no protocol byte and XML size")
    protocol = data[at]
    (size,) = struct.unpack_from("<i", data, at + 1)
    at += 5
    if size < 0 or len(data) < at + size + 8:
        raise ValueError(f"truncated .btlog: the XML of {size} bytes and the first timestamp do not fit")
    xml = data[at : at + size].decode("utf-8")
    at += size
    (first,) = struct.unpack_from("<q", data, at)
    at += 8
    rest = len(data) - at
    if rest % 9:
        raise ValueError(f"truncated .btlog: {rest} bytes of transitions is not a multiple of 9")
    transitions = []
    for start in range(at, len(data), 9):
        offset = int.from_bytes(data[start : start + 6], "little")
        uid, status = struct.unpack_from("<HB", data, start + 6)
        transitions.append(Transition(offset, uid, status))
    return BtLog(protocol, xml, first, transitions)
