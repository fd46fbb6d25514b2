"""The room-type classifier: priors over what rooms hold, noisy absence, and the corridor shape."""

from __future__ import annotations

import numpy as np

from missiontree.semantics.room_types import classify_room, corridor_shaped

KNOWN = ["chair", "sofa", "table", "bottle", "cup", "backpack", "laptop", "umbrella", "potted plant", "tv",
         "refrigerator", "trash can", "bookshelf"]


def test_a_refrigerator_says_kitchen() -> None:
    """A room with a refrigerator and cups is a kitchen, with high confidence."""
    answer = classify_room(["refrigerator", "cup", "table"], known=KNOWN)
    assert answer.room_type == "kitchen" and answer.confidence > 0.9
    assert "refrigerator" in answer.evidence


def test_a_missing_large_object_counts_against_its_room() -> None:
    """A trash can and a bottle with no refrigerator or table seen say bathroom, not kitchen."""
    assert classify_room(["trash can", "bottle"], known=KNOWN).room_type == "bathroom"
    assert classify_room(["trash can", "bottle"], known=None).room_type == "kitchen"  # absence unused


def test_a_long_narrow_room_is_a_corridor() -> None:
    """A 10 x 1.5 m outline with nothing in it is typed a corridor; a 5 x 4 m empty room stays unknown."""
    corridor = np.array([[0, 0], [10, 0], [10, 1.5], [0, 1.5]])
    square = np.array([[0, 0], [5, 0], [5, 4], [0, 4]])
    assert corridor_shaped(corridor) and not corridor_shaped(square)
    assert classify_room([], corridor, KNOWN).room_type == "corridor"
    assert classify_room([], square, KNOWN).room_type == "unknown"


def test_an_unknown_label_alone_says_nothing() -> None:
    """Labels the priors do not cover leave a shapeless room unknown."""
    assert classify_room(["spaceship"], known=KNOWN).room_type == "unknown"
