"""The bag recorder's parts that need no ROS: .msg dependencies, header stamps, the stamp throttle."""

from __future__ import annotations

import struct
from types import SimpleNamespace

import pytest

from missiontree.backends.ros2.bag_record import StampThrottle, header_stamp, msg_dependencies, type_hash


def _cdr(sec: int, nanosec: int) -> bytes:
    """A little-endian CDR message starting with a header stamp."""
    return b"\x00\x01\x00\x00" + struct.pack("<iI", sec, nanosec) + b"\x00" * 8


def test_dependencies_name_non_primitive_fields_with_their_package() -> None:
    """Fields of other packages keep theirs, bare names are the message's own package, Header is std_msgs."""
    text = ("# a comment: Pose pose\nstd_msgs/Header header\nMapMetaData info\nint8[] data\n"
            "uint8 KIND=3\nuint8 OTHER = 4\ngeometry_msgs/Point[<=4] corners\nstring<=10 name\n"
            "Header other\n")
    assert msg_dependencies(text, "nav_msgs") == [
        "std_msgs/msg/Header", "nav_msgs/msg/MapMetaData", "geometry_msgs/msg/Point"]


def test_header_stamp_reads_the_stamp_after_the_encapsulation() -> None:
    """Seconds and nanoseconds of a serialized header; NaN for a message too short to hold one."""
    assert header_stamp(_cdr(1_700_000_000, 500_000_000)) == pytest.approx(1_700_000_000.5)
    assert header_stamp(b"\x00\x01\x00\x00") != header_stamp(b"\x00\x01\x00\x00")  # NaN


def test_throttle_keeps_one_message_per_slot_the_same_for_every_topic() -> None:
    """At 1 Hz, stamps 10.0, 10.4, 10.9, 11.1, 12.5 keep 10.0, 11.1 and 12.5, whichever topic they are on."""
    stamps = [(10, 0), (10, 400_000_000), (10, 900_000_000), (11, 100_000_000), (12, 500_000_000)]
    for _ in range(2):  # colour and depth with the same stamps: the same choice
        throttle = StampThrottle(1.0)
        assert [throttle.keep(_cdr(*s)) for s in stamps] == [True, False, False, True, True]


def test_type_hash_is_written_as_ros_writes_it() -> None:
    """Version 1 and 32 bytes give RIHS01_ and 64 hex digits; a publisher without a hash gives nothing."""
    info = SimpleNamespace(topic_type_hash=SimpleNamespace(version=1, value=bytes(range(32))))
    assert type_hash(info) == "RIHS01_" + bytes(range(32)).hex()
    assert type_hash(SimpleNamespace(topic_type_hash=SimpleNamespace(version=-1, value=b""))) == ""
