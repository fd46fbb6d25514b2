"""Generated apartments: seeded, valid, furnished, every room reachable."""

from __future__ import annotations

import pytest

from missiontree.backends.sim import create_robot, load_world
from missiontree.backends.sim.generator import _all_rooms_reachable, generate_world, write_world_file
from missiontree.errors import WorldFileError


def test_same_seed_same_world_other_seed_other_world():
    """The world depends on the seed alone."""
    assert generate_world(11) == generate_world(11)
    assert generate_world(11) != generate_world(12)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_generated_worlds_are_valid_and_connected(seed):
    """A generated world passes the world-file checks; rooms, doors and objects exist; all reachable."""
    data = generate_world(seed)
    assert _all_rooms_reachable(data)
    world = load_world(f"generated:{seed}")
    assert len(world.rooms) >= 3 and len(world.objects) >= 10
    assert {"kitchen", "living room", "office"} <= {r.type for r in world.rooms}
    assert world.clearance(world.start.x, world.start.y) > 0.3


def test_written_world_file_loads(tmp_path):
    """write_world_file writes a world file that loads like any other."""
    path = write_world_file(4, tmp_path / "apartment.yaml")
    world = load_world(path)
    assert world.name == "generated_4" and len(world.crowd) == 2


def test_generated_world_drives_a_robot():
    """create_robot accepts generated:<seed> as a world."""
    robot = create_robot({"world": "generated:6", "seed": 1})
    robot.spin_until(1.0)
    assert robot.scan() is not None and robot.rgbd() is not None


def test_bad_generated_name():
    """generated: needs an integer seed."""
    with pytest.raises(WorldFileError, match="whole number"):
        load_world("generated:many")
