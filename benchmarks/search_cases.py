"""The search benchmark's cases: worlds edited for one search each (search_eval's; both splits).

A target (class and colour) is chosen per world among the small objects (those the generator
describes, or any object under 0.6 m across and 1 m high); when no small object is of a target
class, one is made into one. Decoys of both kinds are made sure of, any second object matching the
target is recoloured, and in the ``absent`` cases the target itself is recoloured (see
:func:`edit_world`). :func:`make_case` writes a dev apartment, :func:`held_out_cases` the test
split's worlds in whole rounds of its cycle, real maps first (:func:`held_out_seeds`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

#: Targets drawn from the generator's small objects: (class, colour).
TARGETS = [
    ("backpack", "red"),
    ("backpack", "blue"),
    ("bottle", "green"),
    ("backpack", "green"),
    ("umbrella", "red"),
    ("bottle", "blue"),
]
#: Colours a decoy may be painted in.
PALETTE = ["red", "blue", "green", "grey", "white", "pink", "black", "yellow"]

#: Size and shape of a target class, for a small object made into one (the generator's).
CLASS_SHAPES = {
    "backpack": ([0.32, 0.22, 0.45], "box"),
    "bottle": ([0.08, 0.08, 0.3], "cylinder"),
    "umbrella": ([0.1, 0.1, 0.9], "cylinder"),
}
#: An object this small across (m) and this low (m) may be a target or a decoy.
SMALL_ACROSS, SMALL_HEIGHT = 0.6, 1.0


@dataclass
class Case:
    """One world and what is searched in it."""

    index: int
    seed: int
    label: str
    colour: str
    absent: bool
    target_id: str = ""
    split: str = "dev"
    world: str = ""

    @property
    def target(self) -> str:
        """The phrase searched for ("red backpack")."""
        return f"{self.colour} {self.label}"



def small_objects(objects: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The objects a target or decoy may be: described by the generator, or small and movable."""
    out = []
    for o in objects:
        size = [float(v) for v in o.get("size", [1.0, 1.0, 1.0])]
        small = max(size[:2]) <= SMALL_ACROSS and size[2] <= SMALL_HEIGHT and o.get("movable", True)
        if "description" in o or small:
            out.append(o)
    return out


def edit_world(data: dict[str, Any], seed: int, absent: bool) -> tuple[str, str, str]:
    """Edit a world's objects for one search (in place); return (label, colour, target id).

    Works on any world of the generator's format (dev apartments, the test split's placed objects).

    Raises:
        ValueError: The world has no small object to search for.
    """
    objects = data.setdefault("objects", [])
    small = small_objects(objects)
    if not small:
        raise ValueError(f"{data.get('name', '?')}: no small object to search for")
    rng = np.random.default_rng(seed + 7919)
    options = [t for t in TARGETS if any(o["label"] == t[0] for o in small)]
    if not options:  # no object of a target class: one small object becomes one
        label, colour = TARGETS[int(rng.integers(len(TARGETS)))]
        _relabel(small[int(rng.integers(len(small)))], label, colour)
        options = [(label, colour)]
    label, colour = options[int(rng.integers(len(options)))]
    same_class = [o for o in small if o["label"] == label]
    target = next((o for o in same_class if o.get("color") == colour), same_class[0])
    target["color"] = colour
    for o in same_class:  # exactly one right object
        if o is not target and o.get("color") == colour:
            o["color"] = next(c for c in PALETTE if c != colour)
    others = [o for o in small if o["label"] != label]
    if len(same_class) < 2 and others:  # a same-class decoy: another small object becomes one
        decoy = others.pop(int(rng.integers(len(others))))
        _relabel(decoy, label, next(c for c in PALETTE if c != colour), like=target)
    if not any(o.get("color") == colour for o in others) and others:  # same colour, another class
        others[int(rng.integers(len(others)))]["color"] = colour
    # any object outside the small ones that matches the target is recoloured too
    for o in objects:
        if o is not target and o["label"] == label and o.get("color") == colour:
            o["color"] = next(c for c in PALETTE if c != colour)
    if absent:  # another colour, one no object of the class has when there is one
        unused = [c for c in PALETTE if c != colour and not any(o.get("color") == c for o in same_class)]
        target["color"] = unused[0] if unused else next(c for c in PALETTE if c != colour)
    for o in small:
        o["description"] = f"a {o.get('color', '')} {o['label']}".replace("  ", " ")
    return label, colour, str(target["id"])


def _relabel(obj: dict[str, Any], label: str, colour: str, like: dict[str, Any] | None = None) -> None:
    """Make ``obj`` an object of ``label`` in ``colour``, sized like ``like`` or the class's usual size."""
    size, shape = CLASS_SHAPES.get(label, ([0.3, 0.3, 0.4], "box"))
    if like is not None:
        size, shape = list(like["size"]), like.get("shape", shape)
    obj.update(label=label, color=colour, size=list(size), shape=shape)


def make_case(
    index: int, seed: int, absent: bool, folder: Path, rooms: int = 4, size: tuple[float, float] | None = None
) -> tuple[Case, Path]:
    """A dev case: generate, edit and write the apartment of ``seed``; return the case and its file.

    ``rooms`` and ``size`` (m) give larger apartments of the same generator (``--dev-rooms``,
    ``--dev-size``): tuning for large floors without looking at the test split's.
    """
    from missiontree.backends.sim.generator import generate_world

    data = generate_world(seed, rooms=rooms, people=0, size=size)
    label, colour, target_id = edit_world(data, seed, absent)
    case = Case(index, seed, label, colour, absent, target_id, "dev", f"generated:{seed}")
    path = folder / f"dev_{index:03d}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return case, path


def held_out_seeds(count: int, first_seed: int, order: str = "maps-first") -> list[int]:
    """The test split's seeds of a sample of ``count``: whole rounds of the cycle, real maps first.

    Round ``r`` holds each of the cycle's ``n`` places once (seeds ``first_seed + r n`` to
    ``first_seed + r n + n - 1``). With ``maps-first`` each round gives its real maps (the SLAM maps,
    MRPT's grids) before its generated floorplans, so a sample smaller than the cycle still holds
    the large real maps (TurtleBot 4's warehouse and depot); ``cycle``: the seeds in order.
    """
    from missiontree.evaluation.splits import current_test_cycle

    cycle = current_test_cycle()
    n = len(cycle)
    if order == "cycle":
        return list(range(first_seed, first_seed + count))
    places = [p for p in range(n) if cycle[p][0] != "floorplan"] + [
        p for p in range(n) if cycle[p][0] == "floorplan"
    ]
    seeds: list[int] = []
    r = 0
    while len(seeds) < count:
        seeds += [first_seed + r * n + (p - first_seed) % n for p in places]
        r += 1
    return seeds[:count]


def held_out_cases(
    n_present: int, n_absent: int, first_seed: int, folder: Path, order: str = "maps-first"
) -> tuple[list[tuple[Case, Path]], list[str]]:
    """The test split's cases (the splits API's held-out worlds, edited) and the worlds skipped.

    The seeds come from :func:`held_out_seeds`: the cases with the target first, then the absent
    ones (the next places of the same order, so they too start with the real maps).
    """
    import copy
    from dataclasses import replace

    from missiontree.evaluation.splits import split_worlds, write_split_world

    n = n_present + n_absent
    seeds = held_out_seeds(n + 4, first_seed, order)
    cases: list[tuple[Case, Path]] = []
    skipped: list[str] = []
    for seed in seeds:
        if len(cases) >= n:
            break
        world = split_worlds("test", 1, first_seed=seed, people=False, min_objects=3)[0]
        index = len(cases)
        absent = index >= n_present
        data = copy.deepcopy(world.data)
        try:
            label, colour, target_id = edit_world(data, seed, absent)
        except ValueError as error:
            skipped.append(f"{world.name}: {error}")
            continue
        sub = folder / f"test_{index:03d}"
        sub.mkdir(parents=True, exist_ok=True)
        path = write_split_world(replace(world, data=data), sub)
        cases.append((Case(index, seed, label, colour, absent, target_id, "test", world.name), path))
    return cases, skipped
