"""A batch plan: one mission expanded over seeds, worlds, fixed ``--set`` values and ``--sweep`` grids.

The grammar the ``batch`` command takes::

    --seeds 0-999            seeds 0 to 999 (inclusive); lists and ranges mix: 0-9,20,30-32
    --worlds office,generated:0-49
                             the office world, then generated:0 ... generated:49 (a name ending
                             in ``:A-B`` is a range of that world source); default: the mission's own
    --set laps=3             a fixed value of the mission's ``params:`` for every run
    --sweep laps=1,2,3       one run per value; several sweeps make a grid (their product)

Runs are ordered world, then parameter combination, then seed — the order of ``results.jsonl``
whatever order the engine finished them in. Each run's seed is the batch seed it came from, the
same across worlds and parameter values (common random numbers: two parameter values are compared
on the same draws); with ``base_seed`` it is derived from both instead (:func:`derive_seed`), for a
batch that must not share draws with another. Both are recorded.
"""

from __future__ import annotations

import hashlib
import itertools
import math
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from missiontree.errors import ConfigError

__all__ = ["BatchPlan", "RunSpec", "derive_seed", "expand_plan", "parse_assignments", "parse_seeds",
           "parse_sweeps", "parse_worlds"]

#: More runs than this in one batch is almost surely a typo (``0-9999999``).
MAX_RUNS = 1_000_000
_RANGE = re.compile(r"^(\d+)-(\d+)$")
_WORLD_RANGE = re.compile(r"^(.+:)(\d+)-(\d+)$")
_UNSAFE = re.compile(r"[^A-Za-z0-9._=+-]+")


def parse_seeds(text: str) -> list[int]:
    """``"0-9,20"`` → ``[0, 1, ..., 9, 20]``, in the order written.

    Raises:
        ConfigError: Not a list of whole numbers and ranges, a range backwards, a seed twice.
    """
    seeds: list[int] = []
    for part in _split(text, "--seeds"):
        match = _RANGE.match(part)
        if match:
            low, high = int(match[1]), int(match[2])
            if high < low:
                raise ConfigError(f"--seeds: range {part!r} runs backwards; write {high}-{low}")
            if high - low + 1 > MAX_RUNS:
                raise ConfigError(f"--seeds: range {part!r} has more than {MAX_RUNS} seeds")
            if len(seeds) + high - low + 1 > MAX_RUNS:  # counted before the range is built
                raise ConfigError(f"--seeds: more than {MAX_RUNS} seeds in all (at {part!r})")
            seeds.extend(range(low, high + 1))
        elif part.isdigit():
            seeds.append(int(part))
        else:
            raise ConfigError(f"--seeds: expected whole numbers >= 0 and ranges like 0-999, found {part!r}")
    _no_repeats(seeds, "--seeds", "seed")
    return seeds


def parse_worlds(text: str) -> list[str]:
    """``"office,generated:0-2"`` → ``["office", "generated:0", "generated:1", "generated:2"]``.

    Raises:
        ConfigError: Empty, a range backwards, a world twice.
    """
    worlds: list[str] = []
    for part in _split(text, "--worlds"):
        match = _WORLD_RANGE.match(part)
        if match:
            low, high = int(match[2]), int(match[3])
            if high < low:
                raise ConfigError(f"--worlds: range {part!r} runs backwards; write {match[1]}{high}-{low}")
            if high - low + 1 > MAX_RUNS:
                raise ConfigError(f"--worlds: range {part!r} has more than {MAX_RUNS} worlds")
            if len(worlds) + high - low + 1 > MAX_RUNS:  # counted before the range is built
                raise ConfigError(f"--worlds: more than {MAX_RUNS} worlds in all (at {part!r})")
            worlds.extend(f"{match[1]}{n}" for n in range(low, high + 1))
        else:
            worlds.append(part)
    _no_repeats(worlds, "--worlds", "world")
    return worlds


def parse_assignments(items: Iterable[str], flag: str = "--set") -> dict[str, str]:
    """``["laps=3"]`` → ``{"laps": "3"}`` (values stay text; the session reads them as YAML).

    Raises:
        ConfigError: An item without ``=`` or a key given twice.
    """
    found: dict[str, str] = {}
    for item in items:
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ConfigError(f"{flag}: expected KEY=VALUE, found {item!r}")
        if key in found:
            raise ConfigError(f"{flag}: {key!r} given twice")
        found[key] = value
    return found


def parse_sweeps(items: Iterable[str]) -> dict[str, list[str]]:
    """``["laps=1,2", "route=a,b"]`` → ``{"laps": ["1", "2"], "route": ["a", "b"]}``.

    Commas inside brackets or quotes do not split (``--sweep goal=[1,2],[3,4]`` is two values).

    Raises:
        ConfigError: An item without ``=``, no values, a value twice, a key twice.
    """
    sweeps: dict[str, list[str]] = {}
    for key, text in parse_assignments(items, "--sweep").items():
        values = _split(text, f"--sweep {key}")
        _no_repeats(values, f"--sweep {key}", "value")
        sweeps[key] = values
    return sweeps


def derive_seed(base_seed: int, seed: int) -> int:
    """A run seed from the batch's base seed and the run's batch seed (stable across machines)."""
    digest = hashlib.blake2b(f"missiontree-batch:{base_seed}:{seed}".encode(), digest_size=4).digest()
    return int.from_bytes(digest, "big") & 0x7FFFFFFF


@dataclass(frozen=True)
class RunSpec:
    """One run of a batch.

    Attributes:
        world: The world (None: the mission's own).
        seed: The batch seed this run came from.
        run_seed: The seed the mission runs with (the batch seed, or derived from the base seed).
        params: Values for the mission's ``params:`` (``--set`` and this run's sweep values), as text.
    """

    world: str | None
    seed: int
    run_seed: int
    params: tuple[tuple[str, str], ...] = ()

    @property
    def params_dict(self) -> dict[str, str]:
        """The parameters as a mapping."""
        return dict(self.params)

    @property
    def run_id(self) -> str:
        """The run's directory name: readable, unique within a plan, the same in every batch."""
        parts = [self.world or "default", *(f"{k}={v}" for k, v in self.params), f"s{self.seed}"]
        exact = "_".join(parts)
        safe = "_".join(_UNSAFE.sub("-", p).strip("-") or "x" for p in parts)
        if safe == exact and len(safe) <= 120:
            return safe
        exact_key = repr((self.world, self.params, self.seed)).encode()
        digest = hashlib.blake2b(exact_key, digest_size=4).hexdigest()
        return f"{safe[:110]}_{digest}"


@dataclass
class BatchPlan:
    """A mission and the runs to make of it.

    Attributes:
        mission: The mission file.
        runs: The runs, in report order.
        sweep_keys: The swept parameters (the summary groups by each).
        request: Options every run shares, as :class:`~missiontree.session.MissionRequest` fields
            (backend, robot, models, config, max_duration, tick_hz, unknown_map, allow_outside).
        base_seed: The base seed when run seeds are derived.
    """

    mission: Path
    runs: list[RunSpec]
    sweep_keys: list[str] = field(default_factory=list)
    request: dict[str, Any] = field(default_factory=dict)
    base_seed: int | None = None

    def describe(self) -> dict[str, Any]:
        """The plan as JSON data (written to ``batch.json``)."""
        return {
            "mission": str(self.mission), "runs": len(self.runs), "sweep_keys": self.sweep_keys,
            "request": {k: v for k, v in self.request.items() if _plain(v)}, "base_seed": self.base_seed,
            "worlds": sorted({r.world or "default" for r in self.runs}),
            "seeds": sorted({r.seed for r in self.runs}),
        }


def expand_plan(
    mission: Path,
    seeds: Sequence[int],
    worlds: Sequence[str] | None = None,
    fixed: Mapping[str, str] | None = None,
    sweeps: Mapping[str, Sequence[str]] | None = None,
    base_seed: int | None = None,
    request: Mapping[str, Any] | None = None,
) -> BatchPlan:
    """Every run of a batch: worlds × sweep grid × seeds.

    Raises:
        ConfigError: No seeds, a key both fixed and swept, or more than :data:`MAX_RUNS` runs.
    """
    fixed = dict(fixed or {})
    sweeps = {k: list(v) for k, v in (sweeps or {}).items()}
    if not seeds:
        raise ConfigError("--seeds: no seeds given; write e.g. --seeds 0-99")
    both = sorted(set(fixed) & set(sweeps))
    if both:
        raise ConfigError(f"{', '.join(both)}: given to both --set and --sweep; keep one")
    world_list: list[str | None] = list(worlds) if worlds else [None]
    total = len(world_list) * math.prod(len(values) for values in sweeps.values()) * len(seeds)
    if total > MAX_RUNS:  # counted before the grid is built (a large sweep grid would fill memory)
        raise ConfigError(f"the batch would make {total} runs (more than {MAX_RUNS}); narrow --seeds, "
                          "--worlds or --sweep")
    combos = list(itertools.product(*sweeps.values())) if sweeps else [()]
    runs = []
    for world in world_list:
        for combo in combos:
            params = {**fixed, **dict(zip(sweeps, combo, strict=True))}
            ordered = tuple(sorted(params.items()))
            for seed in seeds:
                run_seed = seed if base_seed is None else derive_seed(base_seed, seed)
                runs.append(RunSpec(world=world, seed=seed, run_seed=run_seed, params=ordered))
    return BatchPlan(mission=Path(mission), runs=runs, sweep_keys=list(sweeps), request=dict(request or {}),
                     base_seed=base_seed)


def _split(text: str, flag: str) -> list[str]:
    """Split on commas outside brackets and quotes; strip; refuse empty items."""
    parts: list[str] = []
    depth, quote = 0, ""
    current: list[str] = []
    for char in text:
        if quote:
            quote = "" if char == quote else quote
        elif char in "\"'":
            quote = char
        elif char in "[{(":
            depth += 1
        elif char in "]})":
            depth = max(0, depth - 1)
        elif char == "," and depth == 0:
            parts.append("".join(current).strip())
            current = []
            continue
        current.append(char)
    parts.append("".join(current).strip())
    if any(not p for p in parts):
        raise ConfigError(f"{flag}: empty item in {text!r}")
    return parts


def _no_repeats(items: Sequence[Any], flag: str, what: str) -> None:
    seen: set[Any] = set()
    for item in items:
        if item in seen:
            raise ConfigError(f"{flag}: {what} {item!r} listed twice")
        seen.add(item)


def _plain(value: Any) -> bool:
    return value is None or isinstance(value, str | int | float | bool | dict | list)
