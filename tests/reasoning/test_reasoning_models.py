"""Tests of the typed model services (reasoning.models.Models) and the protocols a context carries."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from missiontree.engine.context import MissionContext
from missiontree.errors import ConfigError, ModelConfigError
from missiontree.events import ForwardEvents, NullEvents
from missiontree.reasoning.calls import CALLER_KEY, BrokenProvider, CallSettings, LatencyModel, model_caller
from missiontree.reasoning.models import Models
from missiontree.semantics.live import LiveScene
from missiontree.services import Scene
from missiontree.testing import ClockRobot


class NeedsRobot:
    """A provider that must be bound to the robot; may refuse it (the oracle detector on a real robot)."""

    name = "needy"
    needs_robot = True

    def __init__(self, refuse: bool = False) -> None:
        self.refuse = refuse
        self.bound: list[object] = []

    def bind(self, robot: object) -> None:
        if self.refuse:
            raise ModelConfigError("detector 'needy' is simulation-only; configure a real detector")
        self.bound.append(robot)

    def embed(self, texts: list[str]) -> np.ndarray:
        return np.ones((len(texts), 2), np.float32)


class Events:
    """Keeps every event."""

    def __init__(self) -> None:
        self.seen: list[tuple[str, dict[str, Any]]] = []

    def emit(self, event: str, /, **fields: Any) -> None:
        self.seen.append((event, fields))


def test_bind_makes_one_caller_and_binds_providers_before_any_leaf() -> None:
    """bind() makes the caller once, puts it on the context and binds (or breaks) robot-bound providers."""
    robot = ClockRobot()
    good, bad = NeedsRobot(), NeedsRobot(refuse=True)
    models = Models({"embedder": good, "detector": bad}, CallSettings(workers=1))
    context = MissionContext(robot=robot, models=models)
    caller = models.bind(context)
    assert models.bind(context) is caller and context.calls is caller and models.caller is caller
    assert model_caller(context) is caller  # a leaf finds the bound caller, nothing more is wired
    assert good.bound == [robot]
    assert isinstance(models["detector"], BrokenProvider) and "simulation-only" in models["detector"].reason
    models.close()


def test_the_bound_caller_reports_to_the_sink_installed_later() -> None:
    """A caller bound before the run reports its model_call events to the sink the runner puts in later."""
    robot = ClockRobot()
    models = Models({"embedder": NeedsRobot()})
    context = MissionContext(robot=robot, models=models)
    caller = models.bind(context)
    events = Events()
    context.events = events  # as the runner does at setup
    call = caller.call("embedder", "embed", ["cup"], node="leaf")
    while not call.status().done:
        pass
    assert [kind for kind, _ in events.seen] == ["model_call"]
    assert events.seen[0][1]["outcome"] == "succeeded" and events.seen[0][1]["node"] == "leaf"
    models.close()


def test_settings_and_roles_leave_out_the_reserved_entries() -> None:
    """The settings property reads the call settings; roles() and provider() see providers only."""
    settings = CallSettings(latency={"vlm": LatencyModel(1.0, 1.0)})
    models = Models({"vlm": "a provider"}, settings)
    assert models.settings is settings
    assert models.roles() == {"vlm": "a provider"}
    assert Models().settings == CallSettings()
    with pytest.raises(ConfigError, match=r"no model configured for role '_calls' \(configured: vlm\)"):
        models.provider("_calls")


def test_a_hand_made_context_still_gets_a_caller_on_first_use() -> None:
    """A context made without a session gets its caller (and bound providers) from model_caller, once."""
    robot = ClockRobot()
    good, bad = NeedsRobot(), NeedsRobot(refuse=True)
    context = MissionContext(robot=robot, models={"embedder": good, "other": bad})
    caller = model_caller(context)
    assert model_caller(context) is caller
    assert context.calls is caller and context.models[CALLER_KEY] is caller
    assert good.bound == [robot]
    broken = context.models["other"]
    assert isinstance(broken, BrokenProvider) and "simulation-only" in broken.reason
    caller.close()


def test_the_live_scene_is_a_scene() -> None:
    """The semantic layer's LiveScene provides the Scene protocol the context is typed with."""
    assert isinstance(LiveScene(), Scene)


def test_forward_events_follows_the_holders_sink() -> None:
    """ForwardEvents writes to whatever sink its holder has at the time of the event."""
    context = MissionContext(robot=ClockRobot())
    forward = ForwardEvents(context)
    forward.emit("dropped")
    assert isinstance(context.events, NullEvents)
    events = Events()
    context.events = events
    forward.emit("kept", x=1)
    assert events.seen == [("kept", {"x": 1})]
