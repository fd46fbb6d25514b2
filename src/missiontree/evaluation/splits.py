"""The worlds every evaluation benchmark runs on: a ``dev`` split to tune on, a ``test`` split to report.

- **dev**: the apartment generator's worlds, ``generated:<seed>`` for seeds ``first_seed`` on.
- **test**: different in kind, not only in seed. It cycles through :data:`TEST_CYCLE`: the seven
  floorplan kinds of :mod:`missiontree.backends.sim.floorplans` (long corridors with many 0.8-0.9 m
  doors, L- and T-shaped corridors, open plan, suites of rooms off rooms, clutter beside doors,
  warehouse floors up to 30 x 50 m) interleaved with the real SLAM maps under config/worlds/maps
  (TurtleBot 4's maze, depot and warehouse, Nav2's tb3_sandbox), whose rooms are found by room
  segmentation and typed, and whose objects (with same-class and same-colour decoys) come from
  :func:`missiontree.backends.sim.placement.place_objects`.

Test world ``i`` (seed ``s = first_seed + i``) is place ``s % n`` of the ``n`` places of
:func:`current_test_cycle`: a floorplan named ``floorplan:<7 s + kind>``, a map world named
``map:<map>:<s>`` or an MRPT world ``mrpt:<map>:<s>``.

MRPT's two real grids from Debian's ``mrpt-common`` (:mod:`missiontree.backends.sim.mrpt_worlds`:
``uwb`` and a 40 x 40 m crop of the Malaga campus) are appended to the cycle, at its places 11 and
12, only when that package is installed (``make setup-mrpt``); otherwise the cycle is the 11 places
of :data:`TEST_CYCLE` and one line on stderr says so. Seeds 0 to 10 give the same worlds either way;
from seed 11 on the worlds depend on whether the package is installed, so the split is
deterministic for a given machine setup, and a report should say whether the MRPT maps were in it.

Every world is checked by the code that makes it (valid, every room reachable by a TurtleBot 4)
before it is handed out; the names load by themselves too (``load_world("map:depot:4")``), with
two walkers and without ``min_objects``: run the file :func:`write_split_world` writes to get the
split's world.

Nobody tunes on ``test``: run it once at the end of a change and report it beside ``dev``.
"""

from __future__ import annotations

import copy
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from missiontree.backends.sim.floorplans import FLOORPLAN_PREFIX, KINDS, floorplan_world
from missiontree.backends.sim.generator import GENERATED_PREFIX, generate_world
from missiontree.backends.sim.mrpt_worlds import INSTALL_HINT, MRPT_PREFIX, map_yaml, mrpt_available
from missiontree.backends.sim.placement import MAP_PREFIX, map_world, place_objects, shipped_map, small_kinds
from missiontree.errors import WorldFileError
from missiontree.files import write_whole
from missiontree.yamlio import load_yaml

#: The split names.
SPLITS = ("dev", "test")
#: Family of each split's worlds.
DEV_FAMILY, FLOORPLAN_FAMILY, MAP_FAMILY = "generated", "floorplan", "real map"
#: Real maps of the test split: names of Nav2 map yamls in config/worlds/maps.
TEST_MAPS = ("tb3_sandbox", "depot", "maze", "warehouse")
#: What the test split cycles through: ("floorplan", kind) and ("map", map name).
TEST_CYCLE: tuple[tuple[str, str], ...] = (
    ("floorplan", "corridor"),
    ("map", "tb3_sandbox"),
    ("floorplan", "l_corridor"),
    ("floorplan", "open_plan"),
    ("map", "depot"),
    ("floorplan", "t_corridor"),
    ("floorplan", "suites"),
    ("map", "maze"),
    ("floorplan", "clutter"),
    ("floorplan", "warehouse"),
    ("map", "warehouse"),
)

#: Appended to :data:`TEST_CYCLE` when Debian's mrpt-common is installed: ("mrpt", MRPT map name).
MRPT_CYCLE: tuple[tuple[str, str], ...] = (("mrpt", "uwb"), ("mrpt", "malaga"))
_noted: list[bool] = []


def current_test_cycle() -> tuple[tuple[str, str], ...]:
    """The test split's cycle on this machine: :data:`TEST_CYCLE`, then :data:`MRPT_CYCLE` if installed.

    Without the MRPT maps a one-line note goes to stderr (once per process), so a report can say why.
    """
    if mrpt_available():
        return TEST_CYCLE + MRPT_CYCLE
    if not _noted:
        _noted.append(True)
        print(f"note: the test split leaves out MRPT's maps: {INSTALL_HINT}", file=sys.stderr)
    return TEST_CYCLE


@dataclass(frozen=True)
class SplitWorld:
    """One world of a split.

    Attributes:
        name: ``generated:12``, ``floorplan:1003`` or ``map:tb3_sandbox:2``.
        family: ``generated`` (dev), ``floorplan`` or ``real map``.
        data: World-file data (as ``generate_world`` returns); map paths absolute.
    """

    name: str
    family: str
    data: dict[str, Any]


def split_worlds(
    split: str, count: int, *, first_seed: int = 0, people: bool = False, min_objects: int = 0
) -> list[SplitWorld]:
    """``count`` worlds of ``split`` from seed ``first_seed`` on (see the module docstring).

    Args:
        split: ``dev`` or ``test``.
        count: How many worlds.
        first_seed: Seed of the first world.
        people: Keep (dev, floorplans) or add (real maps) people walking; without, no one walks.
        min_objects: At least this many small (findable) objects in every world.

    Raises:
        ValueError: An unknown split, a negative count or seed; or a world with no room for
            ``min_objects`` small objects.
    """
    if split not in SPLITS:
        raise ValueError(f"expected a split in {', '.join(SPLITS)}, found {split!r}")
    if count < 0 or first_seed < 0:
        raise ValueError(f"expected a count and first seed from 0, found {count} and {first_seed}")
    seeds = range(first_seed, first_seed + count)
    worlds = [
        _dev(s, people, min_objects) if split == "dev" else _test(s, people, min_objects) for s in seeds
    ]
    for world in worlds:
        found = len(small_objects(world.data))
        if found < min_objects:
            raise ValueError(
                f"{world.name}: expected at least {min_objects} small objects, could place {found}"
            )
    return worlds


def _dev(seed: int, people: bool, min_objects: int) -> SplitWorld:
    data = generate_world(seed, people=2 if people else 0)
    return SplitWorld(f"{GENERATED_PREFIX}{seed}", DEV_FAMILY, _top_up(data, seed, min_objects))


def _test(seed: int, people: bool, min_objects: int) -> SplitWorld:
    cycle = current_test_cycle()
    family, what = cycle[seed % len(cycle)]
    if family == "floorplan":
        fseed = 7 * seed + KINDS.index(what)
        data = floorplan_world(fseed, people=2 if people else 0)
        return SplitWorld(f"{FLOORPLAN_PREFIX}{fseed}", FLOORPLAN_FAMILY, _top_up(data, seed, min_objects))
    if family == "mrpt":
        data = map_world(
            map_yaml(what), seed, name=f"mrpt_{what}_{seed}", small=min_objects, people=2 if people else 0
        )
        return SplitWorld(f"{MRPT_PREFIX}{what}:{seed}", MAP_FAMILY, data)
    data = map_world(
        shipped_map(what), seed, name=f"map_{what}_{seed}", small=min_objects, people=2 if people else 0
    )
    return SplitWorld(f"{MAP_PREFIX}{what}:{seed}", MAP_FAMILY, data)


def small_objects(data: dict[str, Any]) -> list[dict[str, Any]]:
    """The small (findable) objects of world data: the generator's small classes, not fixed furniture."""
    kinds = small_kinds()
    return [o for o in data.get("objects", []) if o.get("label") in kinds and o.get("movable", True)]


def _top_up(data: dict[str, Any], seed: int, min_objects: int) -> dict[str, Any]:
    have = len(small_objects(data))
    if have >= min_objects:
        return data
    return place_objects(data, seed, furniture=False, small=min_objects - have, decoys=False, per_room=False)


def write_split_world(world: SplitWorld, directory: Path) -> Path:
    """Write the world as ``<directory>/<name>.yaml`` (loadable by ``--world PATH``); returns the path.

    A map world's map yaml and image are copied into ``<directory>/maps/`` and named by absolute
    path, since the world loader reads maps only beside the world file (or on $MISSIONTREE_MAP_PATH).
    Files are replaced whole, so processes writing one folder at once never read half a file.

    Raises:
        ValueError: A map yaml names an image outside its own folder.
    """
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    data = copy.deepcopy(world.data)
    section = data.get("map")
    if isinstance(section, dict) and isinstance(section.get("yaml"), str):
        source = Path(section["yaml"])
        target_dir = (directory / "maps").resolve()
        target_dir.mkdir(exist_ok=True)
        image = Path(str(load_yaml(source, error=WorldFileError).data["image"]))
        if image.is_absolute() or ".." in image.parts:
            raise ValueError(f"{source}: expected an image path inside the map's folder, found {image}")
        _copy(source, target_dir / source.name)
        _copy(source.parent / image, target_dir / image)
        section["yaml"] = str(target_dir / source.name)
    path = directory / f"{world.name.replace(':', '_')}.yaml"
    text = (
        f"# {world.family} world {world.name} of the evaluation splits (missiontree.evaluation.splits)\n"
        + yaml.safe_dump(data, sort_keys=False)
    )
    write_whole(path, text.encode("utf-8"))
    return path


def _copy(source: Path, target: Path) -> None:
    """Copy a file unless the same bytes are there already (workers may write one folder at once)."""
    content = source.read_bytes()
    if target.is_file() and target.read_bytes() == content:
        return
    write_whole(target, content)



