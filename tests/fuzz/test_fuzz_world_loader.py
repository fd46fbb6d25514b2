"""Fuzzing the world loader and robot profiles: every case loads or ends in a WorldFileError."""

from __future__ import annotations

import pytest
import yaml
from hypothesis import given
from hypothesis import strategies as st
from strategies import SCALARS, mutations, values

from missiontree.backends.sim import create_robot, load_robot_profile
from missiontree.backends.sim.world import build_world
from missiontree.errors import ConfigError, ProblemsError, WorldFileError
from missiontree.paths import REPO_ROOT
from missiontree.yamlio import parse_yaml

BASES = [yaml.safe_load((REPO_ROOT / "config" / "worlds" / f"{name}.yaml").read_text())
         for name in ("conformance", "corridor", "map_example")]
PROFILE = yaml.safe_load((REPO_ROOT / "config" / "robots" / "turtlebot4.yaml").read_text())
WORLD_DIR = REPO_ROOT / "config" / "worlds"


def _load(data: object) -> None:
    try:
        text = yaml.safe_dump(data, sort_keys=False)
    except yaml.YAMLError:
        return
    try:
        doc = parse_yaml(text, "<fuzz world>", error=WorldFileError)
        build_world(doc, WORLD_DIR / "fuzz.yaml")
    except WorldFileError:
        pass


@given(mutations(BASES))
def test_mutated_worlds_never_crash(world: object) -> None:
    """A shipped world with values replaced, dropped or added loads or reports problems, nothing else."""
    _load(world)


@given(values(keys=st.sampled_from(["name", "robot", "walls", "map", "rooms", "objects", "people",
                                    "resolution", "start", "x", "y", "yaml", "segments", "polygons"]),
              depth=4))
def test_random_world_documents_never_crash(doc: object) -> None:
    """Random documents made of the world format's keys load or report problems."""
    _load(doc)


@given(mutations([PROFILE]), st.one_of(st.none(), mutations([PROFILE])))
def test_mutated_robot_profiles_never_crash(tmp_path_factory: pytest.TempPathFactory, profile: object,
                                            overrides: object) -> None:
    """A robot profile with values replaced loads or reports problems (also as config overrides)."""
    overrides = overrides if isinstance(overrides, dict) else None
    path = tmp_path_factory.getbasetemp() / "fuzz_robot.yaml"
    try:
        path.write_text(yaml.safe_dump(profile))
    except yaml.YAMLError:
        return
    try:
        load_robot_profile(path, overrides)
    except ProblemsError:
        pass


_OPTION_VALUES = st.one_of(SCALARS, st.sampled_from(["conformance", "generated:3", "office", "nowhere",
                                                     "turtlebot4", "../../etc/passwd"]),
                           st.dictionaries(st.sampled_from(["lidar", "camera", "odometry", "body", "beams"]),
                                           values(), max_size=2))


@given(st.dictionaries(st.sampled_from(["world", "robot", "seed", "config", "name", "unknown_map", "wrld"]),
                       _OPTION_VALUES, max_size=4))
def test_simulator_factory_options_never_crash(options: dict) -> None:
    """Any options to the simulator's factory build a robot or raise a ConfigError, nothing else.

    The full budget: most options are refused before a robot is built (1,000 cases took 8 s).
    """
    try:
        robot = create_robot(options)
    except ConfigError:
        return
    robot.close()
