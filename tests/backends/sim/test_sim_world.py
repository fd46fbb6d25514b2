"""World files: the shipped worlds load, waypoints are reachable, broken files give file:line errors."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from conftest import ROOM

from missiontree.backends.sim import create_robot, load_robot_profile, load_world
from missiontree.backends.sim.navigation import INSCRIBED, Costmap, plan
from missiontree.errors import ConfigError, WorldFileError
from missiontree.paths import REPO_ROOT
from missiontree.types import Pose2D

SHIPPED = ["office", "corridor", "entrance_hall", "combined", "conformance", "map_example"]


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_worlds_load(name):
    """Every shipped world loads and its robot starts in free space."""
    world = load_world(name)
    assert world.name == name
    assert world.clearance(world.start.x, world.start.y) > 0.17


def test_office_holds_what_nais_used():
    """The office world has the NAIS objects: chairs, sofas, umbrellas, bottles, cups, backpacks, laptop."""
    world = load_world("office")
    labels = {o.label for o in world.objects}
    assert {"chair", "sofa", "umbrella", "bottle", "cup", "backpack", "laptop", "sink", "refrigerator",
            "dining table"} <= labels
    colours = {(o.label, o.color) for o in world.objects}
    assert {("backpack", "grey"), ("backpack", "red"), ("chair", "blue"), ("bottle", "pink")} <= colours
    assert {r.type for r in world.rooms} == {"kitchen", "office"}


@pytest.mark.parametrize("scenario", ["a", "b", "c", "d"])
def test_seed001_waypoints_are_reachable(scenario):
    """Each waypoint of seed 001's tables is free of the inscribed zone and the loop has paths."""
    data = yaml.safe_load((REPO_ROOT / "config" / "waypoints" / f"scenario_{scenario}.yaml").read_text())
    world = load_world(data["world"])
    profile = load_robot_profile(world.profile_name)
    costmap = Costmap(world.grid, profile.body.radius, profile.navigation)
    points = {w["name"]: Pose2D(w["pose"][0], w["pose"][1]) for w in data["waypoints"]}
    order = data.get("order") or list(points)
    for name in order:
        assert costmap.cell_cost(costmap.cost, points[name].x, points[name].y) < INSCRIBED, name
    for a, b in zip(order, order[1:] + order[:1], strict=True):
        assert plan(costmap, costmap.cost, points[a], points[b]) is not None, (a, b)


def _problems(path: Path) -> list[str]:
    with pytest.raises(WorldFileError) as info:
        load_world(path)
    return [str(p) for p in info.value.problems]


def test_unknown_key_names_its_line_and_the_known_keys(write_world):
    """A misspelt key is reported at its line with the keys that exist."""
    cup = "  - {label: cup, size: [0.1, 0.1, 0.1], pose: {x: 1, y: 1}, colour: red}\n"
    path = write_world(ROOM + "objects:\n" + cup)
    (problem,) = _problems(path)
    assert problem.startswith(f"{path}:10:")
    assert "unknown key 'colour'" in problem and "color" in problem


def test_missing_fields_are_all_reported(write_world):
    """Every missing required field is reported, each with a line."""
    path = write_world(ROOM + "objects:\n  - {label: cup, pose: {x: 1}}\n")
    problems = _problems(path)
    assert any("missing required key 'size'" in p and ":10:" in p for p in problems)
    assert any("missing required key 'y'" in p for p in problems)


def test_walls_or_map_required(write_world):
    """A world with neither walls nor a map is refused."""
    path = write_world("name: x\nrobot: {start: {x: 0, y: 0}}\n")
    assert any("expected `walls:` or `map:`" in p for p in _problems(path))


def test_object_inside_a_wall(write_world):
    """An object that overlaps a wall is reported at its pose's line."""
    shelf = "  - {id: shelf, label: shelf, size: [1, 0.5, 1], pose: {x: 6.0, y: 2}}\n"
    path = write_world(ROOM + "objects:\n" + shelf)
    (problem,) = _problems(path)
    assert ":10:" in problem and "'shelf'" in problem and "overlaps a wall" in problem


def test_object_against_a_wall_is_fine(write_world):
    """An object touching a wall (not crossing it) is accepted."""
    path = write_world(ROOM + "objects:\n  - {label: shelf, size: [1, 0.5, 1], pose: {x: 3.0, y: 3.75}}\n")
    assert load_world(path).objects[0].label == "shelf"


def test_robot_starting_inside_a_wall(write_world):
    """A start pose closer to a wall than the body radius is reported at the start's line."""
    path = write_world(ROOM.replace("{x: 2.0, y: 1.5, yaw: 0.0}", "{x: 0.05, y: 1.5, yaw: 0.0}"))
    (problem,) = _problems(path)
    assert ":4:" in problem and "robot start" in problem and "inside the wall" in problem


def test_unknown_robot_profile(write_world):
    """An unknown robot profile is reported with the known profiles."""
    path = write_world(ROOM.replace("profile: turtlebot4", "profile: turtlebot9"))
    (problem,) = _problems(path)
    assert ":3:" in problem and "turtlebot9" in problem and "turtlebot4" in problem


def test_missing_map_image(write_world, tmp_path):
    """A map yaml naming an image that does not exist is reported at the map yaml's image line."""
    (tmp_path / "m.yaml").write_text("image: nowhere.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n")
    path = write_world("name: m\nrobot: {start: {x: 1, y: 1}}\nmap: {yaml: m.yaml}\n")
    (problem,) = _problems(path)
    assert "m.yaml:1:" in problem and "nowhere.pgm" in problem and "does not exist" in problem


def test_missing_map_yaml(write_world):
    """A world naming a map yaml that does not exist is reported at its line."""
    path = write_world("name: m\nrobot: {start: {x: 1, y: 1}}\nmap: {yaml: gone.yaml}\n")
    (problem,) = _problems(path)
    assert ":3:" in problem and "gone.yaml" in problem


def test_unknown_world_name_lists_the_known_ones():
    """An unknown world name is an error listing the shipped worlds."""
    with pytest.raises(WorldFileError) as info:
        load_world("atlantis")
    assert "office" in str(info.value) and "combined" in str(info.value)


def test_bad_config_override_and_option():
    """A broken profile override and an unknown option are clear errors (ConfigError, exit 2)."""
    with pytest.raises(WorldFileError) as info:
        create_robot({"world": "conformance", "config": {"lidar": {"beems": 10}}})
    assert "lidar.beems" in str(info.value) and "unknown key" in str(info.value)
    with pytest.raises(ConfigError, match="unknown simulator option"):
        create_robot({"wrld": "office"})


def test_broken_world_through_the_cli_exits_2(write_world, tmp_path, capsys):
    """`missiontree run --world broken.yaml` prints file:line problems and exits with code 2."""
    from missiontree.cli.main import main

    cup = "objects:\n  - {label: cup, size: [0.1, 0.1, 0.1], pose: {x: 1, y: 1}, colour: red}\n"
    path = write_world(ROOM.replace("profile: turtlebot4", "profile: turtlebot9") + cup)
    code = main(["run", str(REPO_ROOT / "trees" / "patrol.yaml"), "--world", str(path),
                 "--out", str(tmp_path / "run"), "--max-duration", "1"])
    err = capsys.readouterr().err
    assert code == 2
    assert f"{path}:10:" in err and "colour" in err and f"{path}:3:" in err and "turtlebot9" in err


def test_person_walking_through_a_wall(write_world):
    """A route leg that crosses a wall is reported at the route point it leads to."""
    path = write_world(ROOM + "people:\n  - {id: ghost, route: [[1, 1], [7, 1]], loop: false}\n")
    (problem,) = _problems(path)
    assert ":10:" in problem and "'ghost' walks through a wall" in problem


def test_map_server_world_reads_occupied_free_and_unknown():
    """A map_server map: black cells are walls (the lidar sees their edges), grey ones unknown (-1)."""
    import math

    import numpy as np

    robot = create_robot({"world": "map_example", "config": {"lidar": {"noise": 0.0}}})
    grid = robot.occupancy()
    assert set(np.unique(grid.data).tolist()) == {-1, 0, 100}
    assert grid.data[grid.world_to_cell(0.1, 0.1)] == -1       # the unknown border of the image
    assert grid.data[grid.world_to_cell(0.3, 3.0)] == 100      # the west wall cells (x 0.25-0.40)
    scan = robot.scan()
    angles = np.angle(np.exp(1j * scan.angles()))
    ahead = int(np.argmin(np.abs(angles)))
    right = int(np.argmin(np.abs(angles + math.pi / 2)))
    assert scan.ranges[ahead] == pytest.approx(2.0, abs=0.02)  # inner wall face at x = 4.0, start x = 2.0
    assert scan.ranges[right] == pytest.approx(1.6, abs=0.02)  # south wall face at y = 0.4, start y = 2.0


def test_wall_overlap_checks_agree_with_whole_map_checks_on_a_real_map():
    """The windowed and pre-filtered overlap checks give the whole-map answers for objects anywhere."""
    import dataclasses

    import cv2
    import numpy as np

    from missiontree.backends.sim import world as world_module

    world = load_world(REPO_ROOT / "config" / "worlds" / "map_example.yaml")
    grid = world.grid
    walls = grid.data >= 50
    segs = np.asarray(world.wall_segments, float).reshape(-1, 4)
    rng = np.random.default_rng(3)
    template = world.objects[0]
    hits = 0
    for _ in range(300):
        obj = dataclasses.replace(
            template, shape=str(rng.choice(["box", "cylinder"])),
            size=(float(rng.uniform(0.1, 1.5)), float(rng.uniform(0.1, 1.5)), 0.5),
            pose=Pose2D(float(rng.uniform(-0.5, 8.5)), float(rng.uniform(-0.5, 6.5)),
                        float(rng.uniform(-3, 3))))
        mask = np.zeros(walls.shape, np.uint8)  # the whole-map reference
        poly = ((obj.footprint() - [grid.origin.x, grid.origin.y]) / grid.resolution * 16).astype(np.int32)
        cv2.fillPoly(mask, [poly], 1, cv2.LINE_8, shift=4)
        expected_grid = bool((cv2.erode(mask, np.ones((3, 3), np.uint8)).astype(bool) & walls).any())
        assert world_module._footprint_hits_grid(obj, walls, grid) == expected_grid, obj.pose
        assert world_module._footprint_hits_walls(obj, segs) == _box_hits_any_segment(obj, segs), obj.pose
        hits += expected_grid
    assert 0 < hits < 300  # both answers occur


def _box_hits_any_segment(obj, segs):  # noqa: ANN001, ANN202
    """The reference: every segment clipped against the (shrunk) outline, none filtered out first."""
    import math

    from missiontree.backends.sim import world as world_module

    slack = world_module._CONTACT_SLACK
    if obj.shape == "cylinder":
        r = obj.size[0] / 2 - slack
        return bool((world_module._point_segment_distance(obj.pose.x, obj.pose.y, segs) < r).any())
    c, s = math.cos(obj.pose.yaw), math.sin(obj.pose.yaw)
    hx, hy = obj.size[0] / 2 - slack, obj.size[1] / 2 - slack
    for x1, y1, x2, y2 in segs:
        ax, ay = c * (x1 - obj.pose.x) + s * (y1 - obj.pose.y), -s * (x1 - obj.pose.x) + c * (y1 - obj.pose.y)
        bx, by = c * (x2 - obj.pose.x) + s * (y2 - obj.pose.y), -s * (x2 - obj.pose.x) + c * (y2 - obj.pose.y)
        for k in range(201):  # dense points along the segment, inside the box?
            t = k / 200
            if abs(ax + t * (bx - ax)) < hx and abs(ay + t * (by - ay)) < hy:
                return True
    return False


def test_floor_colours_paint_each_room_over_the_ones_before():
    """Rooms are painted in the order listed, a later room over an earlier one, as room masks would."""
    import cv2
    import numpy as np

    from missiontree.backends.sim import world as world_module

    world = load_world(REPO_ROOT / "config" / "worlds" / "map_example.yaml")
    grid, rooms = world.grid, world.rooms
    expected = np.empty(grid.data.shape + (3,), np.float64)
    expected[:] = (170, 160, 145)
    for room in rooms:
        mask = np.zeros(grid.data.shape, np.uint8)
        poly = ((room.polygon - [grid.origin.x, grid.origin.y]) / grid.resolution * 16).astype(np.int32)
        cv2.fillPoly(mask, [poly], 1, cv2.LINE_8, shift=4)
        expected[mask > 0] = room.floor_rgb or world_module._ROOM_FLOORS.get(room.type, (170, 160, 145))
    assert len(rooms) == 2
    assert np.array_equal(world_module._floor_colours(grid, rooms), expected)
