"""Tests of non-blocking model calls: polling, timeouts, cancellation, simulated latency."""

from __future__ import annotations

import threading
import time
from typing import Any

import pytest

from missiontree.errors import ModelConfigError, ModelError
from missiontree.reasoning.calls import CallStatus, LatencyModel, ModelCaller


class Clock:
    """A settable clock standing in for the simulated robot clock."""

    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


class Events:
    def __init__(self) -> None:
        self.events: list[tuple[str, dict[str, Any]]] = []

    def emit(self, event: str, **fields: Any) -> None:
        self.events.append((event, fields))


def test_submit_returns_before_the_provider_finishes() -> None:
    """submit() returns at once while the provider is still blocked on the worker."""
    gate = threading.Event()
    caller = ModelCaller(time.monotonic, Events())
    start = time.monotonic()
    call = caller.submit("vlm", gate.wait, 5.0, provider="blocked")
    assert time.monotonic() - start < 2.5  # the provider blocks until the gate opens (5 s at most)
    assert not call.status().done
    gate.set()
    deadline = time.monotonic() + 5.0
    while not call.status().done and time.monotonic() < deadline:
        time.sleep(0.01)
    assert call.status() is CallStatus.SUCCEEDED
    assert call.result() is True
    caller.close()


def test_real_timeout_ends_timed_out_with_reason() -> None:
    """On a real clock a call that outlives its timeout ends TIMED_OUT naming provider and role."""
    gate = threading.Event()
    events = Events()
    caller = ModelCaller(time.monotonic, events)
    call = caller.submit("llm", gate.wait, 5.0, provider="slowpoke", timeout=0.05)
    time.sleep(0.1)
    assert call.status() is CallStatus.TIMED_OUT
    assert "slowpoke" in call.error() and "'llm'" in call.error()
    gate.set()
    assert events.events[-1][0] == "model_call"
    assert events.events[-1][1]["outcome"] == "timed_out"
    caller.close()


def test_cancel_ends_cancelled_and_drops_the_result() -> None:
    """Cancelling a running call ends it CANCELLED, emits one event, and ignores the later result."""
    gate = threading.Event()
    events = Events()
    caller = ModelCaller(time.monotonic, events)
    call = caller.submit("vlm", gate.wait, 5.0, provider="p")
    call.cancel()
    call.cancel()
    gate.set()
    time.sleep(0.05)
    assert call.status() is CallStatus.CANCELLED
    assert call.result() is None
    assert [e for e, _ in events.events] == ["model_call"]
    assert events.events[0][1]["outcome"] == "cancelled"
    caller.close()


def test_provider_exception_becomes_failed_with_provider_named() -> None:
    """An exception in the provider ends the call FAILED with a reason naming the provider."""
    def broken() -> None:
        raise ModelError("server unreachable at http://127.0.0.1:9; start the server")

    clock = Clock()
    caller = ModelCaller(clock, Events(), simulated=True)
    call = caller.submit("vlm", broken, provider="openai")
    assert call.status() is CallStatus.FAILED
    assert call.error().startswith("openai: ")
    assert isinstance(call.exception(), ModelError)
    caller.close()


def test_simulated_result_visible_exactly_at_submit_plus_latency() -> None:
    """In the simulator the answer appears at submit time + latency on the simulated clock, not before."""
    clock = Clock()
    events = Events()
    caller = ModelCaller(clock, events, simulated=True, latency={"vlm": LatencyModel(1.5, 1.5)})
    clock.t = 10.0
    call = caller.submit("vlm", lambda: "SAFE", provider="offline")
    time.sleep(0.05)  # the worker is long done; the simulated clock decides
    clock.t = 11.49
    assert call.status() is CallStatus.RUNNING
    clock.t = 11.5
    assert call.status() is CallStatus.SUCCEEDED
    assert call.latency == pytest.approx(1.5)
    assert events.events == [("model_call", {
        "role": "vlm", "provider": "offline", "latency": 1.5, "outcome": "succeeded"})]
    caller.close()


def test_simulated_call_waits_for_a_slow_worker_at_its_due_time() -> None:
    """A due simulated call blocks the poll until the worker finishes, so outcomes do not depend on speed."""
    clock = Clock()
    caller = ModelCaller(clock, Events(), simulated=True, latency={"vlm": LatencyModel(0.1, 0.1)})

    def slow() -> str:
        time.sleep(0.2)
        return "done"

    call = caller.submit("vlm", slow)
    clock.t = 0.1
    assert call.status() is CallStatus.SUCCEEDED
    assert call.result() == "done"
    caller.close()


def test_simulated_timeout_is_exact_when_latency_exceeds_it() -> None:
    """A drawn latency above the timeout times out exactly at submit + timeout."""
    clock = Clock()
    caller = ModelCaller(clock, Events(), simulated=True, latency={"vlm": LatencyModel(5.0, 5.0)})
    call = caller.submit("vlm", lambda: "late", timeout=2.0)
    clock.t = 1.99
    assert call.status() is CallStatus.RUNNING
    clock.t = 2.0
    assert call.status() is CallStatus.TIMED_OUT
    assert call.latency == 2.0
    caller.close()


def _latencies(seed: int) -> list[float]:
    clock = Clock()
    caller = ModelCaller(clock, Events(), simulated=True, seed=seed,
                         latency={"vlm": LatencyModel(0.5, 3.0)})
    calls = [caller.submit("vlm", lambda: 1) for _ in range(5)]
    clock.t = 10.0
    out = []
    for call in calls:
        assert call.status() is CallStatus.SUCCEEDED
        out.append(call.latency)
    caller.close()
    return out


def test_simulated_latency_draws_repeat_for_a_seed() -> None:
    """Uniform latency draws are the same for the same seed, differ for another, and stay in bounds."""
    first, again, other = _latencies(7), _latencies(7), _latencies(8)
    assert first == again
    assert first != other
    assert all(0.5 <= x <= 3.0 for x in first)


def test_latency_config_forms() -> None:
    """Latency config accepts a number, {fixed}, {uniform} and refuses anything else clearly."""
    assert LatencyModel.parse(1.0) == LatencyModel(1.0, 1.0)
    assert LatencyModel.parse({"fixed": 2}) == LatencyModel(2.0, 2.0)
    assert LatencyModel.parse({"uniform": [0.5, 3.0]}) == LatencyModel(0.5, 3.0)
    assert LatencyModel.parse(None) is None
    with pytest.raises(ModelConfigError, match="uniform"):
        LatencyModel.parse({"gauss": 1})
    with pytest.raises(ModelConfigError, match="low <= high"):
        LatencyModel.parse({"uniform": [3.0, 0.5]})


def test_chat_convenience_checks_and_grounds_ids() -> None:
    """caller.chat with a schema returns a checked answer whose ids exist; events carry the attempts."""
    from missiontree.reasoning.checks import CheckedAnswer
    from missiontree.reasoning.schemas import IntentResolution

    class TwoAnswers:
        name = "two"

        def __init__(self) -> None:
            self.answers = ['{"candidates": ["ghost"]}', '{"candidates": ["cup_1"]}']

        def chat(self, messages: Any, schema: Any = None) -> str:
            return self.answers.pop(0)

    clock = Clock()
    events = Events()
    caller = ModelCaller(clock, events, simulated=True, models={"llm": TwoAnswers()})
    call = caller.chat("llm", [], IntentResolution, valid_ids={"cup_1"}, node="intent")
    assert call.status() is CallStatus.SUCCEEDED
    answer = call.result()
    assert isinstance(answer, CheckedAnswer) and answer.value.candidates == ["cup_1"]
    event = events.events[-1][1]
    assert event["provider"] == "two" and event["attempts"] == 2 and "ghost" in event["rejected"][0]
    caller.close()


def test_unknown_role_names_the_configured_ones() -> None:
    """Asking a role nobody configured is a ConfigError listing the configured roles."""
    from missiontree.errors import ConfigError

    caller = ModelCaller(Clock(), Events(), models={"vlm": object(), "_calls": None})
    with pytest.raises(ConfigError, match=r"no model configured for role 'llm' \(configured: vlm\)"):
        caller.chat("llm", [])


def test_provider_timeout_error_is_timed_out_with_its_reason() -> None:
    """A provider's own timeout ends the call TIMED_OUT with its reason (not the wall-clock limit's)."""
    from missiontree.errors import ModelTimeoutError

    def slow_server() -> None:
        raise ModelTimeoutError("openai: chat at http://x took longer than 2 s; raise timeout")

    caller = ModelCaller(Clock(), Events(), simulated=True)
    call = caller.submit("vlm", slow_server)
    assert call.status() is CallStatus.TIMED_OUT
    assert "took longer than 2 s" in call.error()
    caller.close()


def test_a_failed_call_is_freed_with_its_images_without_the_garbage_collector() -> None:
    """A provider's exception must not tie the call into a cycle that holds its images until a gc pass."""
    import gc
    import weakref

    import numpy as np

    class Image(np.ndarray):
        """An ndarray subclass, so a weak reference can watch it."""

    gate = threading.Event()

    def broken(images: list[np.ndarray]) -> None:
        gate.wait(5.0)  # fails after submit() returned (the call's handle exists)
        raise ModelError("flaky: injected fault")

    gc.collect()
    gc.disable()
    try:
        for simulated in (True, False):
            caller = ModelCaller(Clock() if simulated else time.monotonic, Events(), simulated=simulated)
            image = np.zeros((240, 320, 3), np.uint8).view(Image)
            watch = weakref.ref(image)
            gate.clear()
            call = caller.submit("vlm", broken, [image])
            gate.set()
            deadline = time.monotonic() + 5.0
            while not call.status().done and time.monotonic() < deadline:
                time.sleep(0.01)
            assert call.status() is CallStatus.FAILED
            del image, call
            caller.close()
            time.sleep(0.05)
            assert watch() is None, f"the failed call's image outlived it (simulated={simulated})"
    finally:
        gc.enable()
