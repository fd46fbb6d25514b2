"""Labelled views of the simulator for training and scoring the shipped detector.

Each world is generated from a seed: a rectangular room (sometimes split by a wall with a door),
a random floor and wall tint, 8-16 objects drawn from :data:`CATALOGUE` (sizes, shapes, colours
and heights like the shipped worlds' objects, small things sometimes standing on tables) and 0-3
people walking routes, dressed in the usual colours or, half the time, in any colour. The world is
written as an ordinary world file and loaded with the simulator's own loader, and views are
rendered with its camera (TurtleBot 4 profile: 320x240, 70 degrees, 0.4 m high) from free
positions, mostly aimed at an object or person, as close to people as :data:`CLOSEST` (a robot
meets people passing right beside it) and sometimes with a person at the edge of the view.

Labels come from the instance mask: an object's box is the extent of its visible pixels.
Objects showing fewer than :data:`MIN_PIXELS` pixels (far away, hidden or cut off) are marked
*ignored*: training does not punish a detection there and scoring counts it neither way.

Training uses world seeds from 0; scoring (benchmarks/detector_quality.py) uses seeds from
:data:`EVAL_FIRST_WORLD`, which training never touches.
"""

from __future__ import annotations

import math
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from missiontree.backends.sim.camera import Camera, Floor
from missiontree.backends.sim.raycast import Primitives
from missiontree.backends.sim.schema import COLOR_NAMES, CameraSpec
from missiontree.backends.sim.world import World, load_world
from missiontree.errors import WorldFileError
from missiontree.types import Pose2D

#: Classes the detector learns, in output order. Person first, as in COCO.
CLASSES: list[str] = [
    "person", "chair", "sofa", "table", "bottle", "cup", "backpack", "laptop", "umbrella",
    "potted plant", "tv", "refrigerator", "trash can", "bookshelf",
]
#: Camera image size (height, width) of the TurtleBot 4 profile.
IMAGE_HW = (240, 320)
#: Objects with fewer visible pixels (of the 320x240 frame) are ignored in training and scoring:
#: about a 10x10 patch, e.g. a cup farther than about 2.5 m.
MIN_PIXELS = 100
#: First world seed used for scoring; training uses seeds below it.
EVAL_FIRST_WORLD = 10_000
CAMERA_HEIGHT = 0.4
#: Closest a view stands to a person (m): the robot's body (0.17) and a torso (0.19) touching, as
#: a patrol robot meets people who pass right beside it.
CLOSEST = 0.36


@dataclass(frozen=True)
class Kind:
    """How one class of object is drawn: shape, size ranges (x, y, z in m), colours, heights."""

    shape: str
    low: tuple[float, float, float]
    high: tuple[float, float, float]
    colours: tuple[str, ...]
    weight: float = 1.0
    on_table: float = 0.0      # probability of standing on a table when one exists
    square: bool = False       # x and y sizes equal (cylinders always are)
    raised: float = 0.0        # probability of hanging or standing raised (a tv on the wall or a stand)
    raised_to: tuple[float, float] = (0.0, 0.0)  # range of the raised object's bottom height (m)


_ANY = ("black", "white", "grey", "red", "green", "blue", "yellow", "orange", "pink", "purple", "brown",
        "beige", "cyan", "navy", "dark grey", "light grey", "wood")

#: Object classes as the shipped worlds draw them (config/worlds/*.yaml).
CATALOGUE: dict[str, Kind] = {
    "chair": Kind("box", (0.4, 0.4, 0.8), (0.55, 0.55, 1.05), _ANY, 2.0, square=True),
    "sofa": Kind("box", (1.5, 0.8, 0.7), (2.2, 1.0, 0.9), ("grey", "brown", "navy", "beige", "dark grey",
                                                          "green", "red", "blue"), 1.0),
    "table": Kind("box", (0.8, 0.5, 0.4), (1.6, 1.0, 0.8), ("wood", "white", "brown", "black", "grey",
                                                           "beige"), 1.5),
    "bottle": Kind("cylinder", (0.06, 0.06, 0.2), (0.09, 0.09, 0.32), _ANY, 1.5, on_table=0.4),
    "cup": Kind("cylinder", (0.08, 0.08, 0.09), (0.1, 0.1, 0.12), _ANY, 1.5, on_table=0.5),
    "backpack": Kind("box", (0.28, 0.18, 0.4), (0.36, 0.26, 0.5), _ANY, 1.2),
    "laptop": Kind("box", (0.3, 0.22, 0.18), (0.36, 0.27, 0.24), ("silver", "black", "grey", "dark grey",
                                                                 "white"), 1.0, on_table=0.5),
    "umbrella": Kind("cylinder", (0.08, 0.08, 0.7), (0.25, 0.25, 1.0), _ANY, 1.0),  # furled, or a stand
    "potted plant": Kind("cylinder", (0.35, 0.35, 0.6), (0.5, 0.5, 1.0), ("green",), 1.0),
    "tv": Kind("box", (0.9, 0.08, 0.55), (1.3, 0.12, 0.75), ("black", "dark grey"), 0.8, raised=0.6,
               raised_to=(0.4, 1.1)),
    "refrigerator": Kind("box", (0.6, 0.6, 1.7), (0.8, 0.8, 1.9), ("white", "silver", "light grey"), 0.8),
    "trash can": Kind("cylinder", (0.3, 0.3, 0.5), (0.4, 0.4, 0.7), ("grey", "black", "dark grey",
                                                                     "silver"), 1.0),
    "bookshelf": Kind("box", (0.8, 0.3, 1.7), (1.2, 0.4, 2.0), ("brown", "wood", "black", "white"), 0.8),
}

_FLOORS = ((200, 190, 170), (150, 130, 110), (180, 180, 185), (120, 95, 70), (210, 205, 195), (140, 150, 160))
_SHIRTS = ((60, 90, 160), (180, 40, 40), (40, 130, 70), (230, 230, 230), (30, 30, 30), (200, 170, 40),
           (120, 60, 150), (240, 130, 40))
_TROUSERS = ((40, 40, 50), (30, 50, 100), (90, 80, 70), (20, 20, 20), (120, 110, 90))
_SKINS = ((205, 160, 130), (150, 105, 75), (90, 60, 45), (235, 200, 175))


# -- worlds ---------------------------------------------------------------------------------------


def _dress(rng: np.random.Generator, usual: list[int], low: int, high: int) -> list[int]:
    """A garment's colour: one of the usual ones, or (half the time) any colour, as people dress."""
    return [int(v) for v in rng.integers(low, high, 3)] if rng.random() < 0.5 else usual


def _free(x: float, y: float, r: float, placed: list[tuple[float, float, float]]) -> bool:
    return all(math.hypot(x - px, y - py) > r + pr + 0.1 for px, py, pr in placed)


def world_spec(seed: int) -> dict[str, Any]:
    """A world file (as a dict) generated from ``seed``."""
    rng = np.random.default_rng(seed)
    width, depth = float(rng.uniform(5.0, 9.0)), float(rng.uniform(4.0, 7.0))
    wall_rgb = [int(v) for v in np.clip(np.array([214, 210, 200]) + rng.integers(-30, 20, 3), 0, 255)]
    walls: dict[str, Any] = {"height": 2.5, "rgb": wall_rgb, "polygons": [[[0, 0], [width, 0], [width, depth],
                                                                            [0, depth]]]}
    placed: list[tuple[float, float, float]] = []
    if rng.random() < 0.5:  # a dividing wall with a 1.2 m door
        split, door = width * float(rng.uniform(0.4, 0.6)), float(rng.uniform(0.5, depth - 1.7))
        walls["segments"] = [[[split, 0], [split, door]], [[split, door + 1.2], [split, depth]]]
        placed += [(split, y, 0.05) for y in np.arange(0.0, depth, 0.2) if not door < y < door + 1.2]
    labels = list(CATALOGUE)
    weights = np.array([CATALOGUE[k].weight for k in labels])
    objects: list[dict[str, Any]] = []
    tables: list[dict[str, Any]] = []
    lift = np.random.default_rng([seed, 2])  # its own stream, as ``dress`` below
    for _ in range(int(rng.integers(8, 17))):
        label = labels[int(rng.choice(len(labels), p=weights / weights.sum()))]
        kind = CATALOGUE[label]
        size = [float(v) for v in rng.uniform(kind.low, kind.high)]
        if kind.shape == "cylinder" or kind.square:
            size[1] = size[0]
        colour = kind.colours[int(rng.integers(len(kind.colours)))]
        rgb = np.clip(np.array(COLOR_NAMES[colour]) + rng.integers(-15, 16, 3), 0, 255)
        entry: dict[str, Any] = {"label": label, "shape": kind.shape, "size": size,
                                 "rgb": [int(v) for v in rgb], "color": colour}
        if tables and rng.random() < kind.on_table:
            table = tables[int(rng.integers(len(tables)))]
            tx, ty = table["pose"]["x"], table["pose"]["y"]
            dx, dy = rng.uniform(-0.3, 0.3, 2) * np.array(table["size"][:2])
            c, s = math.cos(table["pose"]["yaw"]), math.sin(table["pose"]["yaw"])
            entry["pose"] = {"x": float(tx + c * dx - s * dy), "y": float(ty + s * dx + c * dy),
                             "yaw": float(rng.uniform(-math.pi, math.pi))}
            entry["elevation"] = table["size"][2]
            entry["obstacle"] = False
            objects.append(entry)
            continue
        radius = math.hypot(size[0], size[1]) / 2
        for _attempt in range(30):
            x = float(rng.uniform(radius + 0.1, width - radius - 0.1))
            y = float(rng.uniform(radius + 0.1, depth - radius - 0.1))
            if _free(x, y, radius, placed):
                break
        else:
            continue
        placed.append((x, y, radius))
        # big furniture mostly stands square to the walls, as in real rooms
        square_yaw = rng.choice([0.0, math.pi / 2, math.pi, -math.pi / 2])
        yaw = float(square_yaw if size[0] > 0.7 else rng.uniform(-math.pi, math.pi))
        entry["pose"] = {"x": x, "y": y, "yaw": yaw}
        if kind.raised and lift.random() < kind.raised:
            entry["elevation"] = float(lift.uniform(*kind.raised_to))
        objects.append(entry)
        if label == "table":
            tables.append(entry)
    people = []
    dress = np.random.default_rng([seed, 1])  # its own stream: the rest of the world stays as it was
    for j in range(int(rng.integers(0, 4))):
        route = [[float(rng.uniform(0.5, width - 0.5)), float(rng.uniform(0.5, depth - 0.5))]
                 for _ in range(3)]
        people.append({
            "id": f"person_{j}", "route": route, "speed": float(rng.uniform(0.4, 1.2)), "loop": True,
            "shirt_rgb": _dress(dress, list(_SHIRTS[int(rng.integers(len(_SHIRTS)))]), 30, 226),
            "trousers_rgb": _dress(dress, list(_TROUSERS[int(rng.integers(len(_TROUSERS)))]), 20, 120),
            "skin_rgb": list(_SKINS[int(rng.integers(len(_SKINS)))]),
        })
    for _attempt in range(200):
        sx, sy = float(rng.uniform(0.5, width - 0.5)), float(rng.uniform(0.5, depth - 0.5))
        if _free(sx, sy, 0.25, placed):
            break
    floor = list(_FLOORS[int(rng.integers(len(_FLOORS)))])
    return {
        "name": f"generated_{seed}",
        "robot": {"profile": "turtlebot4", "start": {"x": sx, "y": sy, "yaw": 0.0}},
        "walls": walls,
        "rooms": [{"name": "room", "type": "room", "floor_rgb": floor,
                   "polygon": [[0, 0], [width, 0], [width, depth], [0, depth]]}],
        "objects": objects,
        "people": people,
    }


def generated_world(seed: int, empty: bool = False) -> World:
    """Load the world of ``seed``; a seed whose world the loader refuses moves on to the next seed.

    ``empty`` leaves out its objects and people: bare rooms, whose floors and walls a detector must
    learn to leave alone.
    """
    for attempt in range(20):
        spec = world_spec(seed * 100 + attempt)
        if empty:
            spec["objects"], spec["people"] = [], []
        with tempfile.TemporaryDirectory() as folder:
            path = Path(folder) / f"generated_{seed}.yaml"
            path.write_text(yaml.safe_dump(spec, sort_keys=False))
            try:
                return load_world(path)
            except WorldFileError:
                continue
    raise RuntimeError(f"no loadable world for seed {seed} in 20 attempts")


# -- views ----------------------------------------------------------------------------------------


def labels_of(instances: np.ndarray, world: World) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Boxes of the visible detector classes.

    Returns:
        (kept K x 5 [class, x1, y1, x2, y2], ignored M x 5, instance id of each kept row (K,)).
    """
    kept, ignored, ids_kept = [], [], []
    ids, counts = np.unique(instances, return_counts=True)
    for inst, count in zip(ids.tolist(), counts.tolist(), strict=True):
        info = world.instances.get(inst)
        if info is None or info.label not in CLASSES:
            continue
        pixels = instances == inst
        rows = np.flatnonzero(pixels.any(axis=1))
        cols = np.flatnonzero(pixels.any(axis=0))
        row = [CLASSES.index(info.label), cols[0], rows[0], cols[-1] + 1, rows[-1] + 1]
        if count >= MIN_PIXELS:
            kept.append(row)
            ids_kept.append(inst)
        else:
            ignored.append(row)
    as_array = lambda rows: np.array(rows, np.float32).reshape(-1, 5)  # noqa: E731
    return as_array(kept), as_array(ignored), np.array(ids_kept, np.int64)


@dataclass
class View:
    """One labelled view: the image, its instance mask and labels, and where it was taken from."""

    color: np.ndarray        # (240, 320, 3) uint8 RGB
    instances: np.ndarray    # (240, 320) instance id per pixel
    kept: np.ndarray         # K x 5 [class, x1, y1, x2, y2] of objects showing MIN_PIXELS or more
    ignored: np.ndarray      # M x 5, objects showing fewer
    kept_ids: np.ndarray     # (K,) instance id of each kept row
    pose: Pose2D             # camera pose
    prims: Primitives        # the scene as rendered (walls, objects and people at that moment)


def floor_of(world: World) -> Floor:
    """The floor and ceiling the camera renders in ``world``."""
    return Floor(world.floor_rgb, world.grid.origin.x, world.grid.origin.y, world.grid.resolution,
                 world.ceiling)


def render_views(world: World, count: int, rng: np.random.Generator) -> list[View]:
    """``count`` labelled views of ``world`` from free positions."""
    camera = Camera(CameraSpec(), rng)
    floor = floor_of(world)
    xmin, ymin, xmax, ymax = world.bounds()
    targets = [(o.pose.x, o.pose.y) for o in world.objects]
    views = []
    while len(views) < count:
        t = float(rng.uniform(0.0, 120.0))
        people = world.crowd.positions(t)
        x, y = float(rng.uniform(xmin, xmax)), float(rng.uniform(ymin, ymax))
        if world.clearance(x, y) < 0.3 or any(math.hypot(x - px, y - py) < CLOSEST for _, px, py in people):
            continue
        aims = targets + [(px, py) for _, px, py in people] * 3
        if aims and rng.random() < 0.8:
            pick = int(rng.integers(len(aims)))
            ax, ay = aims[pick]
            spread = 0.5 if pick < len(targets) else 0.8  # people also at the edge, half out of view
            yaw = math.atan2(ay - y, ax - x) + float(rng.uniform(-1.0, 1.0)) * spread
        else:
            yaw = float(rng.uniform(-math.pi, math.pi))
        prims = world.static.concat(world.crowd.primitives(t))
        pose = Pose2D(x, y, yaw)
        rendering = camera.render(pose, CAMERA_HEIGHT, prims, floor)
        kept, ignored, kept_ids = labels_of(rendering.instances, world)
        views.append(View(rendering.color, rendering.instances, kept, ignored, kept_ids, pose, prims))
    return views


def unoccluded_share(world: World, view: View) -> np.ndarray:
    """For each kept object of ``view``, the share of its in-frame pixels that nothing else hides.

    Renders each object alone from the same pose (noise-free, no random draws) and compares its
    pixel count with the view's. 1.0: in full view; 0.3: 70 % hidden behind other things. (Being
    cut off by the frame's edge is not counted here: the object alone is cut off the same way.)
    """
    camera = Camera(CameraSpec(), np.random.default_rng(0))
    floor = floor_of(world)
    shares = np.ones(len(view.kept_ids))
    for k, inst in enumerate(view.kept_ids.tolist()):
        itself = view.prims.select(view.prims.inst == inst)
        alone = camera.render_exact(view.pose, CAMERA_HEIGHT, itself, floor)
        shown = int((view.instances == inst).sum())
        shares[k] = shown / max(int((alone.instances == inst).sum()), shown, 1)
    return shares


def dataset_views(
    images: int, seed: int = 0, first_world: int = 0, views_per_world: int = 25, empty_share: float = 0.0
) -> Iterator[View]:
    """``images`` labelled views from worlds ``first_world``, ``first_world + 1``, ..., one at a time.

    A share ``empty_share`` of the worlds (drawn per world from ``seed``) are bare rooms.
    """
    rng = np.random.default_rng(seed)
    made = 0
    world_seed = first_world
    bare = np.random.default_rng([seed, 3])  # its own stream: without empty rooms nothing changes
    while made < images:
        world = generated_world(world_seed, empty=empty_share > 0 and bare.random() < empty_share)
        world_seed += 1
        for view in render_views(world, min(views_per_world, images - made), rng):
            made += 1
            yield view


def render_dataset(
    images: int, seed: int = 0, first_world: int = 0, views_per_world: int = 25, empty_share: float = 0.0
) -> tuple[np.ndarray, list[np.ndarray], list[np.ndarray]]:
    """``images`` labelled views from worlds ``first_world``, ``first_world + 1``, ...

    A share ``empty_share`` of the worlds (drawn per world from ``seed``) are bare rooms.

    Returns:
        (N x 240 x 320 x 3 uint8 images, kept labels per image, ignored labels per image).
    """
    colours = np.zeros((images, *IMAGE_HW, 3), np.uint8)
    kept: list[np.ndarray] = []
    ignored: list[np.ndarray] = []
    for k, view in enumerate(dataset_views(images, seed, first_world, views_per_world, empty_share)):
        colours[k] = view.color
        kept.append(view.kept)
        ignored.append(view.ignored)
    return colours, kept, ignored
