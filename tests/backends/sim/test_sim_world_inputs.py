"""World files as an attacker writes them: files outside the folder, NaN, huge sizes, bad seeds."""

from __future__ import annotations

import ast
import struct
import zlib
from pathlib import Path

import pytest
from conftest import ROOM

from missiontree.backends.sim import create_robot, load_world
from missiontree.backends.sim.mapimage import MAX_MAP_CELLS
from missiontree.errors import ConfigError, WorldFileError
from missiontree.paths import REPO_ROOT

SIM = REPO_ROOT / "src" / "missiontree" / "backends" / "sim"


def _problems(path: Path | str) -> list[str]:
    with pytest.raises(WorldFileError) as info:
        load_world(path)
    return [str(p) for p in info.value.problems]


def _imports(module: Path) -> set[str]:
    """Every module a file imports, at any depth of the file (function-level imports included)."""
    found: set[str] = set()
    for node in ast.walk(ast.parse(module.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module:
            found.add(node.module)
            found.update(f"{node.module}.{a.name}" for a in node.names)
        elif isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
    return found


def test_world_loader_and_generator_form_no_circle():
    """The world loader does not import the generator; the generator uses only public world names."""
    assert not any("generator" in m for m in _imports(SIM / "world.py"))
    generator_source = (SIM / "generator.py").read_text()
    assert "_load_doc" not in generator_source
    assert "missiontree.backends.sim.world" in _imports(SIM / "generator.py")


def test_a_map_outside_the_world_folder_is_refused_and_never_echoed(write_world, tmp_path):
    """`map: {yaml: ../../etc/passwd}` is refused without opening the file or showing its content."""
    secret = tmp_path.parent / "secret.yaml"
    secret.write_text("password: hunter2-very-secret\n")
    world_dir = tmp_path / "w"
    world_dir.mkdir()
    path = world_dir / "world.yaml"
    path.write_text("name: m\nrobot: {start: {x: 1, y: 1}}\nmap: {yaml: ../../secret.yaml}\n")
    (problem,) = _problems(path)
    assert ":3:" in problem and "outside" in problem and "MISSIONTREE_MAP_PATH" in problem
    assert "hunter2" not in problem
    for target in ("/etc/passwd", "../../../etc/passwd"):
        path.write_text(f"name: m\nrobot: {{start: {{x: 1, y: 1}}}}\nmap: {{yaml: {target}}}\n")
        (problem,) = _problems(path)
        assert "outside" in problem and "root:" not in problem


@pytest.mark.parametrize("broken_valid", [False, True])
def test_a_map_path_with_a_nul_byte_is_a_problem_not_a_crash(write_world, broken_valid):
    """A NUL byte in `map: {yaml: ...}` is reported as an invalid path, also beside other mistakes.

    Found by the world-loader fuzz: the path reached ``Path.resolve``, whose ValueError escaped.
    """
    broken = "objects: [{id: a, label: chair, size: [1, 1, 1], pose: {x: nan, y: 1}}]\n"
    other = broken if broken_valid else ""
    path = write_world('name: m\nrobot: {start: {x: 1, y: 1}}\nmap: {yaml: "maps/a\\0b.yaml"}\n' + other)
    problems = " ".join(_problems(path))
    assert "not a valid path" in problems


def test_a_map_yaml_that_is_not_one_is_not_echoed(write_world, tmp_path):
    """A text file named as the map yaml is reported by its line count, not its content."""
    (tmp_path / "notes.yaml").write_text("root:x:0:0:root:/root:/bin/bash secret-token-123\n")
    path = write_world("name: m\nrobot: {start: {x: 1, y: 1}}\nmap: {yaml: notes.yaml}\n")
    problems = " ".join(_problems(path))
    assert "secret-token-123" not in problems and "not a Nav2 map yaml" in problems


def test_an_allowed_map_folder_is_accepted(write_world, tmp_path, monkeypatch):
    """A map in a folder named by $MISSIONTREE_MAP_PATH loads although it lies outside the world's folder."""
    maps = tmp_path / "maps"
    maps.mkdir()
    (maps / "m.yaml").write_text((REPO_ROOT / "config/worlds/maps/small_office.yaml").read_text())
    (maps / "small_office.pgm").write_bytes((REPO_ROOT / "config/worlds/maps/small_office.pgm").read_bytes())
    world_dir = tmp_path / "w"
    world_dir.mkdir()
    path = world_dir / "world.yaml"
    path.write_text(f"name: m\nrobot: {{start: {{x: 2, y: 2}}}}\nmap: {{yaml: {maps / 'm.yaml'}}}\n")
    assert any("outside" in p for p in _problems(path))
    monkeypatch.setenv("MISSIONTREE_MAP_PATH", str(maps))
    assert load_world(path).grid.data.shape == (120, 160)


def _png_header(width: int, height: int) -> bytes:
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    chunk = b"IHDR" + ihdr
    return (b"\x89PNG\r\n\x1a\n" + struct.pack(">I", len(ihdr)) + chunk
            + struct.pack(">I", zlib.crc32(chunk)) + b"\x00" * 16)


@pytest.mark.parametrize("image", ["P5\n100000 100000\n255\n", "png"])
def test_a_huge_map_header_is_refused_before_decoding(write_world, tmp_path, image):
    """A map image whose header promises 100,000 x 100,000 pixels is refused from the header alone."""
    name = "big.png" if image == "png" else "big.pgm"
    (tmp_path / name).write_bytes(_png_header(100_000, 100_000) if image == "png" else image.encode())
    (tmp_path / "m.yaml").write_text(f"image: {name}\nresolution: 0.05\norigin: [0, 0, 0]\n")
    path = write_world("name: m\nrobot: {start: {x: 1, y: 1}}\nmap: {yaml: m.yaml}\n")
    (problem,) = _problems(path)
    assert "m.yaml:1:" in problem and f"{MAX_MAP_CELLS:,}" in problem and "100,000" in problem


@pytest.mark.parametrize("where, value", [
    ("walls", "segments: [[[0, 0], [1e300, 0]]]"),
    ("walls", "segments: [[[0, 0], [.nan, 0]]]"),
    ("walls", "polygons: [[[0, 0], [.inf, 0], [1, 1]]]"),
])
def test_walls_must_be_finite_and_near(write_world, where, value):
    """Walls at 1e300, NaN or infinity are problems at their line, not tracebacks or huge grids."""
    path = write_world(f"name: x\nrobot: {{start: {{x: 0.5, y: 0.5}}}}\n{where}:\n  {value}\n")
    (problem,) = _problems(path)
    assert ":4:" in problem and ("finite" in problem or "less than or equal" in problem)


def test_a_two_kilometre_world_is_refused_before_allocating(write_world):
    """A world of 2 km a side needs more grid cells than allowed: refused with its size."""
    path = write_world("name: x\nrobot: {start: {x: 1, y: 1}}\nwalls:\n"
                       "  polygons: [[[0, 0], [2000, 0], [2000, 2000], [0, 2000]]]\n")
    (problem,) = _problems(path)
    assert "grid cells" in problem and "2,001" in problem


@pytest.mark.parametrize("field, value", [
    ("pose: {x: .nan, y: 1}", "x"), ("pose: {x: 1, y: 1, yaw: .inf}", "yaw"),
    ("pose: {x: 1, y: 1, yaw_deg: .nan}", "yaw_deg"),
])
def test_object_poses_must_be_finite(write_world, field, value):
    """NaN or infinite object poses are reported at the number's line."""
    path = write_world(ROOM + f"objects:\n  - {{label: cup, size: [0.1, 0.1, 0.1], {field}}}\n")
    problems = _problems(path)
    assert any(":10:" in p and "finite" in p for p in problems), problems


@pytest.mark.parametrize("size", ["[.nan, 0.1, 0.1]", "[0.1, .inf, 0.1]", "[1e9, 0.1, 0.1]"])
def test_object_sizes_must_be_finite_and_bounded(write_world, size):
    """Sizes that are NaN, infinite or absurd are problems."""
    path = write_world(ROOM + f"objects:\n  - {{label: cup, size: {size}, pose: {{x: 1, y: 1}}}}\n")
    assert any(":10:" in p for p in _problems(path))


@pytest.mark.parametrize("person", [
    "{id: p, route: [[1, 1], [.nan, 2]]}", "{id: p, route: [[1, 1], [2, 2]], speed: .inf}",
    "{id: p, route: [[1, 1], [2, 2]], speed: 1e6}", "{id: p, route: [[1, 1]], start_time: .nan}",
])
def test_person_routes_and_speeds_must_be_finite(write_world, person):
    """A person route with NaN or an infinite or absurd speed is refused at its line."""
    path = write_world(ROOM + f"people:\n  - {person}\n")
    assert any(":10:" in p for p in _problems(path))


def test_every_problem_of_a_world_is_reported_at_once(write_world):
    """Schema mistakes, an unknown profile and a missing map are reported together."""
    path = write_world("name: x\nrobot: {profile: turtlebot9, start: {x: 1, y: .nan}}\n"
                       "map: {yaml: gone.yaml, heigth: 2}\nobjects:\n  - {label: cup, pose: {x: 1, y: 1}}\n")
    problems = _problems(path)
    text = "\n".join(problems)
    assert "turtlebot9" in text and "gone.yaml" in text and "heigth" in text and "size" in text, text
    assert "finite" in text


@pytest.mark.parametrize("seed", [-1, -(2**70), 2**64, 1.5, True, "3"])
def test_bad_seeds_are_refused_clearly(seed):
    """Negative, huge or non-integer seeds are a ConfigError naming the range, not a numpy traceback."""
    with pytest.raises(ConfigError, match="seed"):
        create_robot({"world": "conformance", "seed": seed})


def test_generated_world_rejects_a_negative_seed():
    """`generated:-1` is refused with the accepted form."""
    assert "whole number" in _problems("generated:-1")[0]


@pytest.mark.parametrize("option", [{"world": 3}, {"config": [1, 2]}, {"robot": ["x"]}])
def test_factory_options_are_type_checked(option):
    """A factory option of the wrong type is a ConfigError, not an AttributeError."""
    with pytest.raises(ConfigError):
        create_robot(option)


def test_four_mistakes_are_reported_in_one_run(write_world):
    """A misspelt key, an object in a wall, a route through a wall and a blocked start: one report."""
    path = write_world(ROOM.replace("{x: 2.0, y: 1.5, yaw: 0.0}", "{x: 0.05, y: 1.5}") + (
        "objects:\n"
        "  - {label: cup, size: [0.1, 0.1, 0.1], pose: {x: 1, y: 1}, colour: red}\n"
        "  - {id: shelf, label: shelf, size: [1, 0.5, 1], pose: {x: 6.0, y: 2}}\n"
        "people:\n  - {id: p, route: [[1, 1], [8, 1]], loop: false}\n"))
    problems = _problems(path)
    assert len(problems) == 4, problems
    assert any(":10:" in p and "'colour'" in p for p in problems)
    assert any(":11:" in p and "'shelf'" in p and "overlaps a wall" in p for p in problems)
    assert any(":13:" in p and "walks through a wall" in p for p in problems)
    assert any(":4:" in p and "robot start" in p for p in problems)
