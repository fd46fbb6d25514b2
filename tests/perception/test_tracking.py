"""The NAIS paper's detection filters, each alone, and chained as the paper chains them."""

from __future__ import annotations

from missiontree.perception.projection import Projection
from missiontree.perception.tracking import (
    Confirmed,
    DedupBuffer,
    NaisFilterParams,
    NaisTracker,
    TemporalVoting,
    confident,
    is_dynamic,
    replaces,
    within_range,
)
from missiontree.types import Detection, Pose2D


def proj(
    label: str = "chair",
    x: float = 1.0,
    y: float = 0.0,
    score: float = 0.9,
    rng: float = 2.0,
    stamp: float = 0.0,
) -> Projection:
    det = Detection(label, score, (10, 10, 20, 20))
    return Projection(label, score, det.box, (x, y, 0.3), rng, rng, (0.5, 0.5, 0.9), stamp, Pose2D(0, 0), det)


def test_defaults_are_the_papers_values() -> None:
    """0.7, 4.5 m, 10 frames, 0.5 m over 100 entries, room-change replacement on."""
    p = NaisFilterParams()
    assert (p.min_confidence, p.max_range, p.min_frames, p.dedup_radius, p.dedup_buffer) == (
        0.7,
        4.5,
        10,
        0.5,
        100,
    )
    assert p.room_change_replacement and "person" in p.dynamic_classes


def test_confidence_filter() -> None:
    """At least 0.7 passes; below it is dropped; the threshold is a parameter."""
    assert confident(0.7) and not confident(0.69)
    assert confident(0.5, min_confidence=0.5)


def test_dynamic_class_filter() -> None:
    """People, vehicles and animals are dropped, whatever the case; furniture is not."""
    assert is_dynamic("person") and is_dynamic("Dog") and is_dynamic("car")
    assert not is_dynamic("chair")
    assert is_dynamic("robot", dynamic_classes={"robot"})


def test_range_filter() -> None:
    """4.5 m passes, farther is rejected; an unknown range is rejected."""
    assert within_range(proj(rng=4.5)) and not within_range(proj(rng=4.51))
    assert not within_range(proj(rng=float("inf")))


def test_temporal_voting_accepts_on_the_tenth_frame() -> None:
    """Nine frames do not confirm, the tenth does; one vote per frame; far sightings are another candidate."""
    voting = TemporalVoting(min_frames=10)
    results = [voting.vote(proj(x=1.0 + 0.01 * k, stamp=k * 0.2)) for k in range(10)]
    assert results[:9] == [None] * 9 and results[9] is not None and results[9].frames == 10
    voting = TemporalVoting(min_frames=3)
    voting.vote(proj(stamp=0.0))
    voting.vote(proj(stamp=0.0))  # the same frame again: a new candidate, not a second vote
    assert max(c.frames for c in voting.candidates) == 1
    voting.vote(proj(x=3.0, stamp=0.2))
    assert len(voting.candidates) == 3


def test_dedup_buffer_rejects_within_half_a_metre_of_the_last_hundred() -> None:
    """A position within 0.5 m of a buffered one is a duplicate; the 101st entry pushes out the first."""
    buffer = DedupBuffer(radius=0.5, size=100)
    for k in range(101):
        buffer.push(Confirmed("cup", 10.0 * k, 0.0, None, 1.0, f"cup_{k}"))
    assert buffer.duplicate_of("cup", 10.3, 0.0).key == "cup_1"
    assert buffer.duplicate_of("cup", 0.3, 0.0) is None  # cup_0 fell out of the buffer
    assert buffer.duplicate_of("cup", 10.6, 0.0) is None
    assert buffer.duplicate_of("chair", 10.3, 0.0) is not None  # the paper's buffer holds positions only
    assert DedupBuffer(any_label=False).duplicate_of("chair", 0.0, 0.0) is None


def test_room_change_replacement() -> None:
    """A duplicate seen closer from another room replaces the record; same room or farther does not."""
    old = Confirmed("chair", 0.0, 0.0, "kitchen", 3.0, "chair_1")
    assert replaces(old, "chair", 1.5, "office")
    assert not replaces(old, "chair", 1.5, "kitchen")
    assert not replaces(old, "chair", 3.5, "office")
    assert not replaces(old, "sofa", 1.5, "office")


def test_the_chain_confirms_once_and_never_updates() -> None:
    """Ten frames confirm a chair; sightings after that are duplicates; a room change closer replaces it."""
    tracker = NaisTracker()
    events = []
    for k in range(25):
        events += tracker.process(
            [
                proj(stamp=k * 0.2, rng=3.0),
                proj("person", stamp=k * 0.2),
                proj(score=0.5, x=2.0, stamp=k * 0.2),
            ],
            room="kitchen",
        )
    assert [e.kind for e in events] == ["confirmed", "duplicate"]
    assert tracker.dropped["dynamic"] == 25 and tracker.dropped["confidence"] == 25
    assert len(tracker.objects) == 1
    events = []
    for k in range(10):
        events += tracker.process([proj(x=1.2, stamp=10 + k * 0.2, rng=1.0)], room="office")
    assert [e.kind for e in events] == ["replaced"]
    assert len(tracker.objects) == 1 and next(iter(tracker.objects.values())).room == "office"


def test_voting_reach_keeps_two_close_small_objects_apart() -> None:
    """Two bottles 0.4 m apart: one candidate by the 0.5 m radius, two with a 0.3 m reach for them."""
    for reach, expected in ((None, 1), (0.3, 2)):
        voting = TemporalVoting(min_frames=10, reach=(lambda p, r=reach: r))
        for k in range(4):
            voting.vote(proj(label="bottle", x=1.0, stamp=0.2 * k))
            voting.vote(proj(label="bottle", x=1.4, stamp=0.2 * k + 0.1))
        assert len(voting.candidates) == expected
