"""SemanticMap: instances with ids, and a change recorded for every add, move, remove and update."""

from __future__ import annotations

import pytest

from missiontree.semantics.semantic_map import Instance, SemanticMap


def test_add_move_remove_record_their_changes_in_order() -> None:
    """Each operation leaves one change with what it did; drain_changes hands them over once."""
    smap = SemanticMap()
    seen = []
    smap.subscribe(seen.append)
    cup = smap.add("cup", (1.0, 2.0, 0.05), 3.0, colour="red", reason="seen in 10 frames")
    smap.move(cup.id, (2.0, 2.0, 0.05), 5.0, reason="moved")
    smap.update(cup.id, 6.0, announce=True, room="room_1")
    smap.remove(cup.id, 7.0, reason="gone")
    changes = smap.drain_changes()
    assert [c.kind for c in changes] == ["added", "moved", "updated", "removed"]
    assert changes[1].previous == (1.0, 2.0, 0.05) and changes[1].position == (2.0, 2.0, 0.05)
    assert seen == changes
    assert smap.drain_changes() == []
    assert len(smap) == 0


def test_ids_are_per_label_and_never_reused_while_present() -> None:
    """Ids are label_n with spaces joined; a second potted plant is potted_plant_2."""
    smap = SemanticMap()
    assert smap.add("potted plant", (0, 0), 0.0).id == "potted_plant_1"
    assert smap.add("potted plant", (1, 0), 0.0).id == "potted_plant_2"
    with pytest.raises(ValueError, match="exists already"):
        smap.add("chair", (0, 0), 0.0, id="potted_plant_1")


def test_queries_and_round_trip() -> None:
    """near() sorts by distance within the radius; to_dict/from_dict keep every field."""
    smap = SemanticMap()
    smap.add("chair", (0.0, 0.0, 0.4), 0.0, size=(0.5, 0.5, 0.9), colour="blue")
    smap.add("chair", (3.0, 0.0, 0.4), 0.0)
    smap.add("cup", (0.2, 0.0, 0.05), 0.0)
    assert [i.id for i in smap.near(0.15, 0.0, 1.0)] == ["cup_1", "chair_1"]
    assert [i.id for i in smap.near(0.1, 0.0, 5.0, label="chair")] == ["chair_1", "chair_2"]
    copy = SemanticMap.from_dict(smap.to_dict())
    assert copy.get("chair_1") == Instance.from_dict(smap.get("chair_1").to_dict())
    assert copy.get("chair_1").colour == "blue"


def test_bad_positions_and_unknown_ids_are_clear_errors() -> None:
    """A non-finite position and a missing id raise errors that say what was expected."""
    smap = SemanticMap()
    with pytest.raises(ValueError, match="finite"):
        smap.add("cup", (float("nan"), 0.0, 0.0), 0.0)
    with pytest.raises(KeyError, match="no instance 'cup_9'"):
        smap.remove("cup_9", 0.0)
