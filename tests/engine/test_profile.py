"""Tests of the run profile: per-node ticks, rate and CPU, model calls by role, the run's figures."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import py_trees
import pytest

from missiontree.engine.context import MissionContext
from missiontree.engine.leaf import Leaf, Status
from missiontree.engine.profile import RunProfile, cost_centres, percentile
from missiontree.engine.runner import Runner
from missiontree.testing import ClockRobot, ScriptedLeaf, clean_state


@pytest.fixture(autouse=True)
def _clean() -> None:
    clean_state()


def _burn(seconds: float) -> None:
    """Use ``seconds`` of this thread's CPU (CPU time, not wall time: load cannot change it)."""
    end = time.thread_time() + seconds
    while time.thread_time() < end:
        pass


class _Busy(Leaf):
    """Burns 2 ms of CPU in each update and runs forever."""

    def update(self) -> Status:
        _burn(0.002)
        return Status.RUNNING


class _Detector:
    """A model provider that burns 1 ms of CPU a call."""

    name = "fake"

    def detect(self, image: Any) -> list[Any]:
        _burn(0.001)
        return []


class _AsksDetector(Leaf):
    """Calls the context's detector once a tick."""

    def update(self) -> Status:
        self.context.model("detector").detect(None)
        return Status.RUNNING


def _run(root: py_trees.behaviour.Behaviour, *, models: dict[str, Any] | None = None,
         run_dir: Path | None = None, **options: Any) -> dict[str, Any]:
    context = MissionContext(robot=ClockRobot(), models=models or {})
    options.setdefault("handle_signals", False)
    return Runner(root, context, run_dir=run_dir, **options).run().summary


def test_summary_has_a_profile_with_each_nodes_ticks_and_rate() -> None:
    """Every ticked node's ticks are counted; a node ticked every tick runs at the tick rate."""
    root = py_trees.composites.Sequence("seq", memory=False, children=[ScriptedLeaf("a", script="R")])
    profile = _run(root, tick_hz=10, max_duration=2.0)["profile"]
    assert profile["nodes"]["seq"]["ticks"] == 20
    assert profile["nodes"]["seq/a"]["ticks"] == 20
    assert profile["nodes"]["seq/a"]["rate_hz"] == pytest.approx(10.0)


def test_node_cpu_is_the_cpu_spent_in_its_own_methods() -> None:
    """A leaf burning 2 ms a tick is charged at least that; its idle sibling far less."""
    busy = _Busy("busy")
    idle = ScriptedLeaf("idle", script="R")
    root = py_trees.composites.Parallel("par", policy=py_trees.common.ParallelPolicy.SuccessOnAll(),
                                        children=[busy, idle])
    nodes = _run(root, tick_hz=10, max_duration=1.0)["profile"]["nodes"]
    assert nodes["par/busy"]["cpu_s"] >= 10 * 0.002
    assert nodes["par/idle"]["cpu_s"] < nodes["par/busy"]["cpu_s"] / 4


def test_rate_of_a_node_ticked_every_other_tick_is_half_the_tick_rate() -> None:
    """A child left RUNNING while its parent skips it is active but not ticked: its rate drops."""

    class _EveryOther(py_trees.decorators.Decorator):
        """Ticks its child on odd ticks only, and is RUNNING either way."""

        n = 0

        def tick(self) -> Any:
            self.n += 1
            if self.n % 2:
                yield from self.decorated.tick()
            self.status = Status.RUNNING
            yield self

        def update(self) -> Status:
            return Status.RUNNING

    root = _EveryOther(name="half", child=ScriptedLeaf("child", script="R"))
    nodes = _run(root, tick_hz=10, max_duration=2.0)["profile"]["nodes"]
    assert nodes["half/child"]["ticks"] == 10
    assert nodes["half/child"]["rate_hz"] == pytest.approx(5.0, abs=0.3)


def test_model_calls_are_counted_by_role_and_the_wrappers_removed_after() -> None:
    """Each call to the role's provider is counted with its latency; the provider is left unwrapped."""
    detector = _Detector()
    profile = _run(_AsksDetector("ask"), models={"detector": detector}, tick_hz=10,
                   max_duration=0.5)["profile"]
    role = profile["models"]["detector"]
    assert role["calls"] == 5
    assert role["cpu_s"] >= 5 * 0.001
    assert role["latency_ms_p95"] >= role["latency_ms_p50"] >= 1.0
    assert "detect" not in vars(detector)


def test_run_figures_and_the_written_summary(tmp_path: Path) -> None:
    """The run's CPU, wall, robot time, real-time factor and RSS peak reach summary.json."""
    _run(ScriptedLeaf("a", script="RRS"), run_dir=tmp_path, tick_hz=10)
    run = json.loads((tmp_path / "summary.json").read_text())["profile"]["run"]
    assert run["robot_s"] == pytest.approx(0.2)
    assert run["cpu_s"] >= 0 and run["wall_s"] > 0 and run["rss_peak_mb"] > 10
    assert run["realtime_factor"] == pytest.approx(run["robot_s"] / run["wall_s"], rel=0.01)
    assert "sim_cpu_s" in run


def test_profile_off_leaves_no_section_and_no_wrappers() -> None:
    """With profile=False the summary has no profile and no node method is wrapped."""
    leaf = ScriptedLeaf("a", script="RS")
    summary = _run(leaf, profile=False)
    assert "profile" not in summary
    assert "update" not in vars(leaf)


def test_node_wrappers_are_removed_after_the_run() -> None:
    """After the run a node's lifecycle methods are its class's again."""
    leaf = ScriptedLeaf("a", script="RS")
    _run(leaf)
    assert not {"initialise", "update", "terminate"} & set(vars(leaf))


def test_nested_model_calls_count_once_in_the_workers_cpu() -> None:
    """A provider calling another role's provider: both roles count it, the outer CPU counts once."""
    inner = _Detector()

    class _Vlm:
        name = "vlm"

        def ask(self, images: Any, prompt: str, schema: Any = None) -> str:
            inner.detect(None)
            return "ok"

    vlm = _Vlm()
    profile = RunProfile(ScriptedLeaf("a", script="R"), lambda n: n.name,
                         {"detector": inner, "vlm": vlm})
    profile.attach()
    profile.worker.tick_thread = -1  # as if called from a worker
    vlm.ask([], "?")
    profile.detach()
    summary = profile.summary(1.0)
    assert summary["models"]["detector"]["calls"] == 1 and summary["models"]["vlm"]["calls"] == 1
    assert summary["run"]["worker_models_cpu_s"] == pytest.approx(summary["models"]["vlm"]["cpu_s"], abs=1e-3)


def test_cost_centres_lead_with_the_largest_and_share_the_run() -> None:
    """Cost centres are sorted by CPU and carry their share of the run's CPU."""
    profile = {"run": {"cpu_s": 10.0, "tick_cpu_s": 3.0, "sim_cpu_s": 2.0, "engine_cpu_s": 1.0,
                       "worker_models_cpu_s": 4.0},
               "nodes": {"root/leaf": {"cpu_s": 2.0}}, "models": {"detector": {"cpu_s": 4.0}}}
    centres = cost_centres(profile)
    assert [c[0] for c in centres] == ["model:detector", "root/leaf", "sim stepping", "engine", "other"]
    assert centres[0][2] == pytest.approx(0.4)


def test_percentile_interpolates() -> None:
    """The median of 1..4 is 2.5; an empty list gives 0."""
    assert percentile([4.0, 1.0, 3.0, 2.0], 50) == pytest.approx(2.5)
    assert percentile([], 95) == 0.0


def test_the_environment_switches_the_profile_off(monkeypatch: pytest.MonkeyPatch) -> None:
    """MISSIONTREE_PROFILE=0 turns the profile off for runs that do not say (to time without it)."""
    monkeypatch.setenv("MISSIONTREE_PROFILE", "0")
    assert "profile" not in _run(ScriptedLeaf("a", script="RS"))
    assert "profile" in _run(ScriptedLeaf("b", script="RS"), profile=True)


def test_a_run_without_cpu_has_no_cost_centres() -> None:
    """A run that ended before using any CPU lists no cost centre (no share of nothing)."""
    assert cost_centres({"run": {"cpu_s": 0.0, "engine_cpu_s": 0.001}, "nodes": {}, "models": {}}) == []


def test_a_pending_model_is_built_on_first_use_and_timed_from_then() -> None:
    """The profile builds no pending role; a role first used mid-run is timed, one never used is not built."""
    from missiontree.reasoning.models import Models, PendingProvider

    built: list[str] = []

    def make(role: str) -> Any:
        def build() -> _Detector:
            built.append(role)
            return _Detector()
        return PendingProvider(role, "fake", build)

    models = Models({"detector": make("detector"), "llm": make("llm")})
    profile = _run(_AsksDetector("ask"), models=models, tick_hz=10, max_duration=0.5)["profile"]
    assert built == ["detector"]
    assert profile["models"]["detector"]["calls"] == 5
    assert "detect" not in vars(models["detector"])
