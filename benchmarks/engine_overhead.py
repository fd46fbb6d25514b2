"""Engine overhead: the runner with its JSON-lines tick log against raw py_trees, in one run.

Three ways of ticking identical 100-node trees (mixed composites, ten leaves RUNNING, two of
them writing the blackboard every tick, a few status changes every tick), alternating in rounds:

- ``runner``: :class:`missiontree.engine.runner.Runner` on a clock-only robot, writing
  ``ticks.jsonl`` (one line a tick: changed nodes, blackboard changes) to a temporary run directory,
  without the run profile (the engine alone);
- ``runner_profiled``: the same with the run profile on, as every mission runs
  (:mod:`missiontree.engine.profile`): ``ratio_profiled_vs_runner`` is the profile's cost on a tree
  that does nothing else (an upper bound: in a mission the leaves' and the simulator's work dwarf it);
- ``raw``: ``root.tick_once()`` with no logging at all (the floor);
- ``pytrees_logging``: ``BehaviourTree.tick()`` with a SnapshotVisitor and the whole tree serialised
  to JSON every tick, as py_trees' own logging demo does (file opened once, no indentation — the
  cheapest form of that reference).

Each round ticks every variant ``--ticks`` times from a fresh (INVALID) tree, rotating which goes
first; the ratios are taken per round, so machine load affects both sides alike. Times are the
process's CPU time (``time.process_time``): on a shared machine wall time also counts the time spent
waiting for a core, which has nothing to do with the engine. The last line is one JSON object.

Then, per tree *shape* and *size* (10 to 10,000 nodes), the runner against raw ``tick_once()``:

- ``selector``: a memoryless Selector over failing leaves and one leaf that keeps RUNNING: every
  tick walks every child (the whole tree is the active part);
- ``memseq``: a memory Sequence of leaves that each run for one tick and succeed on the next: the
  active part is two leaves, while the finished children pile up behind it (the tick log's cost
  must not grow with them). Ticked at least once through (small ones several times over).

Here the runner side is the runner's own tick (``Runner.tick()``: the tree's tick, the recorder, the
tick-log line written to ``ticks.jsonl``) after its setup, so that a run's fixed costs (summary,
files) do not swamp small trees; raw is ``tick_once()`` on a set-up tree. Each shape/size alternates
the two (A B B A, rotating) for ``--shape-rounds`` rounds; the ratio per round gives min/median/max.
``setup_ms`` is the runner's setup (guards, paths, stop watching, node setup);
``overhead_us_per_tick`` the runner's time per tick beyond raw's (py_trees' own memory Sequence
finds its current child with ``list.index``, so raw's tick there grows with the finished children;
this figure shows the tick log's own cost staying flat).
``ratio_memseq_10k_vs_selector_10k`` is the memory Sequence's median runner/raw ratio over the
Selector's, both at 10,000 nodes (target <= 2).

Run: ``.venv/bin/python benchmarks/engine_overhead.py [--rounds N] [--ticks N] [--shape-rounds N]``.
"""

from __future__ import annotations

import argparse
import gc
import io
import json
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any

import py_trees
from pydantic import BaseModel

from missiontree.engine.context import MissionContext
from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.ports import Output
from missiontree.engine.runner import Runner
from missiontree.testing import ClockRobot, clean_state

TICK_HZ = 10.0
#: Periods (in ticks) of the ten running leaves: primes, so the tree as a whole never finishes.
PERIODS = (23, 29, 31, 37, 41, 43, 47, 53, 59, 61)


class Periodic(Leaf):
    """RUNNING, but SUCCESS every ``period`` ticks; optionally writes its tick count each tick."""

    class Params(BaseModel):
        period: int = 10
        out: Annotated[str, Output("tick count")] = ""

    def initialise(self) -> None:
        """Start counting."""
        self.count = 0

    def update(self) -> Status:
        """Count; write the count when asked to; succeed every ``period`` ticks."""
        self.count += 1
        if self.params.out:
            self.write("out", self.count * 0.1)
        return Status.SUCCESS if self.count % self.params.period == 0 else Status.RUNNING


def branch(index: int) -> py_trees.behaviour.Behaviour:
    """One branch of ten nodes: a reactive check that fails, then a plan with a running step."""
    # branch(1) + check(1 + 2) + plan(1 + 4) + idle(1) = 10 nodes
    s = py_trees.behaviours
    check = py_trees.composites.Sequence(f"check{index}", memory=False, children=[
        s.Success(f"ready{index}"), s.Failure(f"alarm{index}"),
    ])
    out = f"odometer{index}" if index < 2 else ""
    plan = py_trees.composites.Sequence(f"plan{index}", memory=True, children=[
        s.Success(f"prepare{index}"),
        Periodic(f"work{index}", Periodic.Params(period=PERIODS[index], out=out)),
        s.Success(f"report{index}"),
        s.Success(f"rest{index}"),
    ])
    return py_trees.composites.Selector(f"branch{index}", memory=False, children=[
        check, plan, s.Success(f"idle{index}"),
    ])


def build_tree() -> py_trees.behaviour.Behaviour:
    """The 100-node tree: a Parallel over ten branches, the last without its idle leaf (10 × 10 - 1 + 1)."""
    branches = [branch(i) for i in range(10)]
    branches[-1].remove_child(branches[-1].children[-1])  # 101 → 100 nodes
    policy = py_trees.common.ParallelPolicy.SuccessOnAll(synchronise=False)
    return py_trees.composites.Parallel("root", policy=policy, children=branches)


def count_nodes(root: py_trees.behaviour.Behaviour) -> int:
    """Number of nodes in the tree."""
    return sum(1 for _ in root.iterate())


def time_runner(root: py_trees.behaviour.Behaviour, ticks: int, run_dir: Path,
                profile: bool = False) -> float:
    """Seconds for the runner to do ``ticks`` ticks with its tick log written to ``run_dir``."""
    runner = Runner(root, MissionContext(robot=ClockRobot()), tick_hz=TICK_HZ, max_duration=ticks / TICK_HZ,
                    run_dir=run_dir, mission="bench", handle_signals=False, profile=profile)
    start = time.process_time()
    result = runner.run()
    elapsed = time.process_time() - start
    assert result.ticks == ticks, (result.ticks, result.stopped_by)
    return elapsed


def time_raw(root: py_trees.behaviour.Behaviour, ticks: int) -> float:
    """Seconds for ``ticks`` bare ``tick_once()`` calls, then a halt like the runner's."""
    start = time.process_time()
    for _ in range(ticks):
        root.tick_once()
    root.stop(Status.INVALID)
    return time.process_time() - start


def _serialise(tree: py_trees.trees.BehaviourTree, snapshot: py_trees.visitors.SnapshotVisitor) -> dict:
    """The whole tree as py_trees' logging demo serialises it."""
    nodes = []
    for node in tree.root.iterate():
        tip = node.tip()
        nodes.append({
            "name": node.name, "id": str(node.id),
            "parent_id": str(node.parent.id) if node.parent else "none",
            "child_ids": [str(child.id) for child in node.children],
            "tip_id": str(tip.id) if tip is not None else "none",
            "class_name": f"{node.__module__}.{type(node).__name__}",
            "status": node.status.value, "message": node.feedback_message,
            "is_active": node.id in snapshot.visited,
        })
    return {"tick": tree.count, "nodes": nodes}


def time_pytrees_logging(root: py_trees.behaviour.Behaviour, ticks: int, out: io.TextIOBase) -> float:
    """Seconds for ``ticks`` of ``BehaviourTree.tick()`` with a snapshot and a JSON dump each tick."""
    tree = py_trees.trees.BehaviourTree(root)
    snapshot = py_trees.visitors.SnapshotVisitor()
    tree.add_visitor(snapshot)
    tree.add_post_tick_handler(lambda t: out.write(json.dumps(_serialise(t, snapshot)) + "\n"))
    start = time.process_time()
    for _ in range(ticks):
        tree.tick()
    root.stop(Status.INVALID)
    out.flush()
    return time.process_time() - start


class Blink(Leaf):
    """RUNNING on its first tick, SUCCESS on the next."""

    def initialise(self) -> None:
        """Start."""
        self.ticked = False

    def update(self) -> Status:
        """Run once, then succeed."""
        if self.ticked:
            return Status.SUCCESS
        self.ticked = True
        return Status.RUNNING


def selector_tree(nodes: int) -> tuple[py_trees.behaviour.Behaviour, int | None]:
    """A memoryless Selector: ``nodes - 2`` failing leaves, then one leaf RUNNING forever."""
    children: list[py_trees.behaviour.Behaviour] = [py_trees.behaviours.Failure(f"check{i}")
                                                    for i in range(nodes - 2)]
    children.append(Periodic("work", Periodic.Params(period=10**9)))
    return py_trees.composites.Selector("root", memory=False, children=children), None


def memseq_tree(nodes: int) -> tuple[py_trees.behaviour.Behaviour, int | None]:
    """A memory Sequence of ``nodes - 1`` leaves RUNNING for one tick each; ticks until it succeeds.

    A leaf's success hands over to the next leaf in the same tick, so it takes ``nodes`` ticks.
    """
    children = [Blink(f"step{i}") for i in range(nodes - 1)]
    return py_trees.composites.Sequence("root", memory=True, children=children), nodes


SHAPES: dict[str, Callable[[int], tuple[py_trees.behaviour.Behaviour, int | None]]] = {
    "selector": selector_tree, "memseq": memseq_tree,
}
SIZES = (10, 100, 1000, 10000)
#: Node-ticks per measured run of the Selector (its every tick walks the whole tree).
SELECTOR_WORK = 200_000


#: Fewest ticks of a memory Sequence measurement (small ones go through several times).
MEMSEQ_MIN_TICKS = 2000


def shape_ticks(shape: str, nodes: int, finish: int | None) -> int:
    """Ticks per measured run: once through the memory Sequence at least, fixed work otherwise."""
    return max(finish, MEMSEQ_MIN_TICKS) if finish is not None else max(20, SELECTOR_WORK // nodes)


def time_shape_runner(shape: str, nodes: int, ticks: int, run_dir: Path) -> tuple[float, float]:
    """(seconds ticking, seconds in setup) for the runner on a fresh tree of ``shape``."""
    clean_state()
    root, _ = SHAPES[shape](nodes)
    runner = Runner(root, MissionContext(robot=ClockRobot()), tick_hz=TICK_HZ, max_duration=ticks / TICK_HZ,
                    run_dir=run_dir, mission="bench", handle_signals=False, profile=False)
    start = time.process_time()
    runner.setup()
    setup = time.process_time() - start
    robot = runner.robot
    start = time.process_time()
    for index in range(ticks):
        runner.tick()
        robot.spin_until((index + 1) / TICK_HZ)
    elapsed = time.process_time() - start
    runner.max_duration = 1e-9  # run() now ends at once: it halts, writes the summary, closes the log
    result = runner.run()
    assert runner.recorder is not None and runner.recorder.ticks >= ticks, (shape, nodes, result.ticks)
    return elapsed, setup


def time_shape_raw(shape: str, nodes: int, ticks: int) -> float:
    """Seconds for ``ticks`` bare ``tick_once()`` calls on a fresh, set-up tree of ``shape``."""
    clean_state()
    root, _ = SHAPES[shape](nodes)
    root.setup_with_descendants()
    start = time.process_time()
    for _ in range(ticks):
        root.tick_once()
    root.stop(Status.INVALID)
    return time.process_time() - start


def measure_shapes(rounds: int, sizes: tuple[int, ...], tmp: Path) -> dict[str, dict[str, Any]]:
    """Runner/raw ratio (min/median/max over rounds) and setup time per shape and size."""
    found: dict[str, dict[str, Any]] = {}
    for shape in SHAPES:
        for nodes in sizes:
            _, finish = SHAPES[shape](nodes)
            ticks = shape_ticks(shape, nodes, finish)
            ratios: list[float] = []
            overheads: list[float] = []
            setups: list[float] = []
            run_dir = tmp / f"{shape}_{nodes}"
            for index in range(rounds + 1):  # the first round warms up and is not counted
                gc.collect()
                runner_t = raw_t = 0.0
                order = ["runner", "raw"] if index % 2 == 0 else ["raw", "runner"]
                for name in order + order[::-1]:  # A B B A
                    if name == "runner":
                        elapsed, setup = time_shape_runner(shape, nodes, ticks, run_dir)
                        runner_t += elapsed
                        setups.append(setup)
                    else:
                        raw_t += time_shape_raw(shape, nodes, ticks)
                if index:
                    ratios.append(runner_t / raw_t)
                    overheads.append((runner_t - raw_t) / (2 * ticks) * 1e6)
            s = spread(ratios)
            key = f"{shape}_{nodes}"
            found[key] = {"ratio_median": s["median"], "ratio_min": s["min"], "ratio_max": s["max"],
                          "ticks": ticks, "setup_ms": round(1000 * statistics.median(setups), 2),
                          "overhead_us_per_tick": round(statistics.median(overheads), 2)}
            print(f"  {key:15s} runner/raw  min {s['min']:6.3f}  median {s['median']:6.3f}  "
                  f"max {s['max']:6.3f}   runner - raw {found[key]['overhead_us_per_tick']:7.1f} µs/tick   "
                  f"({ticks} ticks, setup {found[key]['setup_ms']:.1f} ms)", flush=True)
    return found


def spread(values: list[float]) -> dict[str, float]:
    """Min / median / max, rounded."""
    return {"min": round(min(values), 3), "median": round(statistics.median(values), 3),
            "max": round(max(values), 3)}


def main() -> None:
    """Run the rounds and print the ratios; the last line is JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=11)
    parser.add_argument("--ticks", type=int, default=600, help="ticks per variant per round (60 s at 10 Hz)")
    parser.add_argument("--shape-rounds", type=int, default=3, help="rounds per shape and size")
    parser.add_argument("--sizes", type=int, nargs="+", default=list(SIZES), help="tree sizes (nodes)")
    args = parser.parse_args()

    clean_state()
    trees = {"runner": build_tree(), "runner_profiled": build_tree(), "raw": build_tree(),
             "pytrees_logging": build_tree()}
    nodes = count_nodes(trees["raw"])
    for root in trees.values():
        root.setup_with_descendants()
    visited_per_tick = _visited_per_tick()
    times: dict[str, list[float]] = {name: [] for name in trees}
    half = args.ticks // 2  # each round runs every variant twice, palindromically
    with tempfile.TemporaryDirectory() as tmp:
        run_dir = Path(tmp) / "run"
        with (Path(tmp) / "dump.jsonl").open("w") as dump:
            variants: dict[str, Callable[[], float]] = {
                "runner": lambda: time_runner(trees["runner"], half, run_dir),
                "runner_profiled": lambda: time_runner(trees["runner_profiled"], half, run_dir, profile=True),
                "raw": lambda: time_raw(trees["raw"], half),
                "pytrees_logging": lambda: time_pytrees_logging(trees["pytrees_logging"], half, dump),
            }
            for variant in variants.values():  # warm-up, not counted
                variant()
            order = list(variants)
            for round_index in range(args.rounds):
                # A B C C B A (rotating who starts): a load that drifts within the round hits all alike.
                turn = round_index % len(order)
                rotated = order[turn:] + order[:turn]
                spent = dict.fromkeys(order, 0.0)
                for name in rotated + rotated[::-1]:
                    gc.collect()
                    spent[name] += variants[name]()
                for name in order:
                    times[name].append(spent[name])
            log_lines = sum(1 for _ in (run_dir / "ticks.jsonl").open())
    vs_raw = [r / w for r, w in zip(times["runner"], times["raw"], strict=True)]
    vs_logging = [r / p for r, p in zip(times["runner"], times["pytrees_logging"], strict=True)]
    profiled = [p / r for p, r in zip(times["runner_profiled"], times["runner"], strict=True)]
    per_tick = {name: spread([t / (2 * half) * 1e6 for t in values]) for name, values in times.items()}
    print(f"tree: {nodes} nodes, {visited_per_tick} ticked per tick, {len(PERIODS)} leaves running; "
          f"{args.rounds} rounds x {2 * half} ticks per variant (two runs of {half}, A B C C B A); "
          f"last runner log: {log_lines} lines")
    for name, s in per_tick.items():
        print(f"  {name:16s} µs/tick  min {s['min']:8.1f}  median {s['median']:8.1f}  max {s['max']:8.1f}")
    print("runner / raw per round: " + " ".join(f"{v:.2f}" for v in vs_raw))
    r, p = spread(vs_raw), spread(vs_logging)
    for label, v, target in (("runner / raw tick_once:            ", r, "median <= 1.3"),
                             ("runner / BehaviourTree.tick + JSON:", p, "well below 1")):
        print(f"{label} min {v['min']:.3f}  median {v['median']:.3f}  max {v['max']:.3f}  (target {target})")
    result: dict[str, Any] = {
        "benchmark": "engine_overhead", "nodes": nodes, "visited_per_tick": visited_per_tick,
        "running_leaves": len(PERIODS), "rounds": args.rounds, "ticks_per_round": 2 * half,
        "ratio_vs_raw_median": r["median"], "ratio_vs_raw_min": r["min"], "ratio_vs_raw_max": r["max"],
        "ratio_vs_pytrees_logging_median": p["median"], "ratio_vs_pytrees_logging_min": p["min"],
        "ratio_vs_pytrees_logging_max": p["max"],
        "us_per_tick_median": {name: s["median"] for name, s in per_tick.items()},
        "ratio_profiled_vs_runner": spread(profiled),
    }
    q = spread(profiled)
    print(f"runner with profile / without (the profile's cost, engine-only tree): min {q['min']:.3f}  "
          f"median {q['median']:.3f}  max {q['max']:.3f}")
    print(f"shapes: runner / raw tick_once per shape and size ({args.shape_rounds} rounds, A B B A):")
    with tempfile.TemporaryDirectory() as tmp:
        shapes = measure_shapes(args.shape_rounds, tuple(args.sizes), Path(tmp))
    result["shapes"] = shapes
    result.update({f"ratio_{key}_median": entry["ratio_median"] for key, entry in shapes.items()})
    if "memseq_10000" in shapes and "selector_10000" in shapes:
        ratio = shapes["memseq_10000"]["ratio_median"] / shapes["selector_10000"]["ratio_median"]
        result["ratio_memseq_10k_vs_selector_10k"] = round(ratio, 3)
        print(f"memory Sequence / Selector runner-raw ratio at 10,000 nodes: {ratio:.3f} (target <= 2)")
    print(json.dumps(result, sort_keys=True))


def _visited_per_tick() -> int:
    """Nodes ticked in a steady-state tick of a fresh tree (after the first tick)."""
    root = build_tree()
    root.setup_with_descendants()
    root.tick_once()
    visited = sum(1 for _ in root.tick())
    root.stop(Status.INVALID)
    return visited


if __name__ == "__main__":
    main()
