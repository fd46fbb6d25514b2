"""Node conditions reach the viewer and the Groot2 export (from the tick log's `conditions` events)."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ElementTree
from pathlib import Path

import pytest

from missiontree.paths import REPO_ROOT
from missiontree.runlog.btlog import tree_xml
from missiontree.runlog.html import page_data
from missiontree.runlog.replay import open_run


@pytest.fixture(scope="module")
def timer_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The timer example on the simulator: its second Wait sets the phase by an on_success assignment."""
    from missiontree.session import MissionRequest, run_mission
    from missiontree.testing import clean_state

    clean_state()
    out = tmp_path_factory.mktemp("timer") / "run"
    run_mission(MissionRequest(mission=REPO_ROOT / "trees" / "examples" / "timer_and_blackboard.yaml",
                               out=out, quiet=True, handle_signals=False))
    clean_state()
    return out


def test_btlog_writes_conditions_as_btcpp_attributes_not_ports(timer_run: Path) -> None:
    """The Wait carries `_onSuccess="phase = 'done'"`; no model declares it as a port."""
    xml, _ = tree_xml(open_run(timer_run))
    root = ElementTree.fromstring(xml)
    conditioned = [e for e in root.iter("Wait") if "_onSuccess" in e.attrib]
    assert [e.attrib["_onSuccess"] for e in conditioned] == ["phase = 'done'"]
    models = root.find("TreeNodesModel")
    assert models is not None
    ports = {p.attrib["name"] for model in models for p in model}
    assert "on_success" not in ports and "_onSuccess" not in ports


def test_the_viewer_shows_conditions_with_the_nodes_parameters(timer_run: Path) -> None:
    """The page's node table gives the Wait's on_success beside its seconds."""
    data = page_data(open_run(timer_run), timer_run)
    params = [json.loads(data["s"][node[4]]) for node in data["nodes"]]
    assert {"seconds": 5, "on_success": "phase = 'done'"} in params
