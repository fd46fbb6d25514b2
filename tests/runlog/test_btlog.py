"""Groot2 .btlog export: the FileLogger2 layout, read back with a reader written from its format."""

from __future__ import annotations

import struct
import xml.etree.ElementTree as ElementTree
from pathlib import Path

import pytest
from runlog_helpers import read_lines

from missiontree.errors import ConfigError
from missiontree.runlog.btlog import MAGIC, read_btlog, to_btlog, write_btlog
from missiontree.runlog.replay import open_run


def test_header_xml_and_timestamp_are_laid_out_as_filelogger2_writes_them(patrol_run: Path):
    """18-byte magic, protocol 1, int32 XML size, the XML, int64 first timestamp, then 9-byte records."""
    data = to_btlog(open_run(patrol_run))
    assert data[:18] == b"BTCPP4-FileLogger2" == MAGIC and data[18] == 1
    (size,) = struct.unpack_from("<i", data, 19)
    xml = data[23 : 23 + size].decode()
    root = ElementTree.fromstring(xml)
    assert root.tag == "root" and root.attrib == {"BTCPP_format": "4"}
    assert (len(data) - (23 + size + 8)) % 9 == 0
    models = {m.attrib["ID"]: m.tag for m in root.find("TreeNodesModel")}
    assert (
        models["Patrol"] == "Action"
        and models["Selector"] == "Control"
        and models["ForceFailure"] == "Decorator"
    )
    patrol = next(e for e in root.iter("Patrol"))
    assert patrol.attrib["name"] == "patrol" and patrol.attrib["laps"] == "1"


def test_round_trip_gives_back_every_transition_in_order(patrol_run: Path):
    """Each status change of the log (and the final halt) is one record with the node's uid and status."""
    replay = open_run(patrol_run)
    log = read_btlog(to_btlog(replay))
    by_uid = log.nodes()
    uid_of_path = {}
    for uid, (_tag, name) in by_uid.items():
        uid_of_path.setdefault(name, uid)
    expected = []
    codes = {"INVALID": 0, "RUNNING": 1, "SUCCESS": 2, "FAILURE": 3}
    lines = read_lines(patrol_run)
    t0 = next(line["t"] for line in lines if line["event"] == "tick")
    for line in lines:
        if line["event"] in ("tick", "halted"):
            t = line["t"]
            for change in line.get("changed", []):
                expected.append(
                    (round((t - t0) * 1e6), change["node"].rsplit("/", 1)[-1], codes[change["status"]])
                )
    got = [(tr.offset_us, by_uid[tr.uid][1], tr.status) for tr in log.transitions]
    assert got == expected
    assert log.protocol == 1 and log.first_timestamp_us == round(t0 * 1e6)


def test_uids_number_nodes_depth_first_from_one(patrol_run: Path):
    """Parents before children, as BehaviorTree.CPP numbers the nodes it creates."""
    log = read_btlog(to_btlog(open_run(patrol_run)))
    names = [log.nodes()[uid][1] for uid in sorted(log.nodes())]
    assert names == [
        "respond_or_patrol",
        "servo_then_resume",
        "servo",
        "patrol_and_watch",
        "patrol",
        "surveillance",
    ]


def test_the_same_run_gives_the_same_bytes(patrol_run: Path, tmp_path: Path):
    """Exporting twice writes identical files."""
    first = write_btlog(open_run(patrol_run), tmp_path / "a.btlog").read_bytes()
    second = write_btlog(open_run(patrol_run), tmp_path / "b.btlog").read_bytes()
    assert first == second


def test_reader_rejects_other_and_truncated_files():
    """A file that is not FileLogger2, or cut short, is refused with the reason."""
    with pytest.raises(ValueError, match="not a Groot2"):
        read_btlog(b"hello")
    data = to_btlog_minimal()
    with pytest.raises(ValueError, match="multiple of 9"):
        read_btlog(data[:-3])


def test_output_needs_the_btlog_extension(patrol_run: Path, tmp_path: Path):
    """Groot2 only opens .btlog files, so another name is refused."""
    with pytest.raises(ConfigError, match=".btlog"):
        write_btlog(open_run(patrol_run), tmp_path / "run.log")


def to_btlog_minimal() -> bytes:
    from missiontree.runlog.replay import Replay

    replay = Replay(None).feed_all(
        [
            {
                "event": "tick",
                "tick": 1,
                "t": 0.0,
                "status": "RUNNING",
                "changed": [{"node": "a", "status": "RUNNING", "was": "INVALID"}],
            },
            {
                "event": "tick",
                "tick": 2,
                "t": 0.1,
                "status": "SUCCESS",
                "changed": [{"node": "a", "status": "SUCCESS", "was": "RUNNING"}],
            },
        ]
    )
    return to_btlog(replay)
