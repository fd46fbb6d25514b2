"""Where a run's time went: per node, per model role and for the robot's own stepping (NAIS Table III).

The NAIS paper reports, for every node of its system, its rate (Hz), CPU share and memory. A run's
:class:`RunProfile` measures the same for a mission, cheaply enough to be on in every run
(``summary.json``'s ``profile`` section; ``missiontree log profile RUN`` prints it):

- per node path: ``ticks``, ``rate_hz`` (ticks per robot-second while the node was active: ticked,
  or left RUNNING between ticks) and ``cpu_s``, the tick thread's CPU time inside the node's own
  ``initialise``, ``update`` and ``terminate`` (children not included). py_trees' own composites
  and decorators (:data:`~missiontree.engine.guards.TRUSTED_TYPES`), which only route ticks, are
  not timed one by one: their few microseconds are in the engine's figure;
- per model role: ``calls``, ``cpu_s`` and ``latency_ms_p50`` / ``latency_ms_p95``, timed around the
  provider's ``detect`` / ``ask`` / ``chat`` / ``embed`` wherever it is called (a worker thread or the
  tick thread). A provider that calls another (the offline VLM stand-in asks its detector) counts
  the inner call under the inner role too. A role not built yet (a pending provider, built on its
  first use) is wrapped when it is built: looking its methods up before would build every model;
- for the run: ``cpu_s`` (the process's CPU from the first tick to the end, all threads), ``wall_s``,
  ``robot_s`` (the robot clock), ``realtime_factor`` (robot seconds per wall second),
  ``cpu_realtime_factor`` (robot seconds per CPU second), ``rss_peak_mb``, ``tick_cpu_s`` (the tick
  thread inside ticks: nodes plus the engine's bookkeeping and tick log), ``sim_cpu_s`` (the tick
  thread inside ``robot.spin_until``: the simulator's stepping, about nothing on ROS 2) and
  ``startup_cpu_s`` (the process's CPU before the run: imports, world, models).

CPU is read from the thread's own clock (``time.thread_time``), so waiting for a worker or for the
GIL is not counted as a node's cost. The wrappers sit on the instances and are removed when the run
ends (a model shared by the runs of a batch is left as it was).
"""

from __future__ import annotations

import os
import resource
import sys
import threading
import time
from collections import Counter
from collections.abc import Callable, Iterable
from typing import Any

import py_trees

from missiontree.engine.guards import TRUSTED_TYPES
from missiontree.engine.node_words import BASE_CLASS

Behaviour = py_trees.behaviour.Behaviour
RUNNING = py_trees.common.Status.RUNNING

#: Lifecycle methods timed on every node.
NODE_METHODS = ("initialise", "update", "terminate")

#: Provider methods timed, by the role's protocol (a role not listed here is timed on all of them).
MODEL_METHODS = ("detect", "ask", "chat", "embed")

#: Latency samples kept per role (the first ones; enough for stable percentiles, bounded memory).
MAX_SAMPLES = 20_000

_thread_time = time.thread_time


def rss_peak_mb() -> float:
    """The process's peak resident set so far, in MiB (``ru_maxrss``: KiB on Linux, bytes on macOS)."""
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / (2**20 if sys.platform == "darwin" else 1024)


def process_cpu_s() -> float:
    """CPU seconds (user + system, all threads) this process has used so far."""
    times = os.times()
    return times.user + times.system


def percentile(values: list[float], q: float) -> float:
    """The ``q``-th percentile (0-100) of ``values`` by linear interpolation (0.0 when empty)."""
    if not values:
        return 0.0
    ordered = sorted(values)
    k = (len(ordered) - 1) * q / 100.0
    low = int(k)
    high = min(low + 1, len(ordered) - 1)
    return ordered[low] + (ordered[high] - ordered[low]) * (k - low)


class _RoleStats:
    """Calls, CPU and latencies of one model role."""

    __slots__ = ("calls", "cpu_s", "latencies")

    def __init__(self) -> None:
        self.calls = 0
        self.cpu_s = 0.0
        self.latencies: list[float] = []

    def add(self, latency: float, cpu: float) -> None:
        self.calls += 1
        self.cpu_s += cpu
        if len(self.latencies) < MAX_SAMPLES:
            self.latencies.append(latency)


class _Outer(threading.local):
    """Per thread: how deep in model calls it is, so nested calls are not counted twice."""

    depth = 0


class _WorkerCpu:
    """CPU of the outermost model calls made off the tick thread (not inside any node's figure)."""

    def __init__(self, tick_thread: int) -> None:
        self.tick_thread = tick_thread
        self.cpu_s = 0.0
        self.outer = _Outer()
        self.lock = threading.Lock()


class RunProfile:
    """Measures one run (see the module docstring); the runner drives it.

    Args:
        root: The tree's root.
        path_of: Gives a node's path (the tick recorder's, so paths match the tick log).
        models: The context's providers by role.
    """

    def __init__(self, root: Behaviour, path_of: Callable[[Behaviour], str],
                 models: dict[str, Any] | None = None) -> None:
        self.root = root
        self.path_of = path_of
        # the entries as they stand (a pending provider stays pending: looking it up would build it)
        self.models = dict(dict.items(models)) if isinstance(models, dict) else dict(models or {})
        self.node_cpu: dict[Behaviour, float] = {}
        self.ticks: Counter[Behaviour] = Counter()
        self.active_s: dict[Behaviour, float] = {}
        self.roles: dict[str, _RoleStats] = {}
        self.tick_cpu_s = 0.0
        self.sim_cpu_s = 0.0
        self._open: set[Behaviour] = set()
        self._since: dict[Behaviour, float] = {}
        self._known = 0
        self._last_t: float | None = None
        self._wrapped_nodes: list[Behaviour] = []
        self._wrapped_models: list[tuple[Any, str]] = []
        self._unlisten: list[Callable[[], None]] = []
        self._seen_models: set[int] = set()
        self._cpu0 = 0.0
        self._wall0 = 0.0
        self._startup_cpu = 0.0
        self._attached = False
        self.worker = _WorkerCpu(threading.get_ident())

    # -- attaching -----------------------------------------------------------------------------

    def attach(self) -> None:
        """Wrap every node's lifecycle methods and every model's call methods; start the clocks."""
        if self._attached:
            return
        self._attached = True
        for node in self.root.iterate():
            self._wrap_node(node)
        self.worker = _WorkerCpu(threading.get_ident())
        self._wrap_models()
        self._startup_cpu = process_cpu_s()
        self.start()

    def start(self) -> None:
        """(Re)start the run's clocks: the CPU and wall time counted are from here on."""
        self._cpu0 = process_cpu_s()
        self._wall0 = time.perf_counter()

    def detach(self) -> None:
        """Remove every wrapper (nodes and models are as they were)."""
        for node in self._wrapped_nodes:
            for name in NODE_METHODS:
                node.__dict__.pop(name, None)
        self._wrapped_nodes.clear()
        for provider, name in self._wrapped_models:
            try:
                delattr(provider, name)
            except AttributeError:
                pass
        self._wrapped_models.clear()
        for remove in self._unlisten:
            remove()
        self._unlisten.clear()
        self._seen_models.clear()
        self._attached = False

    def _wrap_node(self, node: Behaviour) -> None:
        if node in self.node_cpu:
            return
        self.node_cpu[node] = 0.0
        # py_trees' own composites (also when switched to the tick recorder's watching subclass)
        if getattr(type(node), BASE_CLASS, type(node)) in TRUSTED_TYPES:
            return
        cpu = self.node_cpu
        cls_of = type
        for name in NODE_METHODS:
            if name in node.__dict__:  # already an instance attribute: leave it alone
                continue

            def timed(*args: Any, _name: str = name, **kwargs: Any) -> Any:
                start = _thread_time()
                try:
                    # looked up on the class at each call: the tick recorder may switch the class
                    return getattr(cls_of(node), _name)(node, *args, **kwargs)
                finally:
                    cpu[node] += _thread_time() - start

            node.__dict__[name] = timed
        self._wrapped_nodes.append(node)

    def _wrap_models(self) -> None:
        for role in sorted(self.models):
            provider = self.models[role]
            if role.startswith("_") or provider is None:
                continue
            when_built = getattr(provider, "when_built", None)
            if callable(when_built):  # a pending provider: wrapped when built, on its first use
                self._unlisten.append(when_built(lambda built, _role=role: self._wrap_model(_role, built)))
            else:
                self._wrap_model(role, provider)

    def _wrap_model(self, role: str, provider: Any) -> None:
        """Time ``provider``'s call methods under ``role`` (once per provider)."""
        if provider is None or id(provider) in self._seen_models or not self._attached:
            return
        self._seen_models.add(id(provider))
        stats = self.roles.setdefault(role, _RoleStats())
        for name in MODEL_METHODS:
            method = getattr(provider, name, None)
            if not callable(method):
                continue
            try:
                setattr(provider, name, _timed_call(method, stats, self.worker))
            except (AttributeError, TypeError):  # slots or a frozen provider: not timed
                continue
            self._wrapped_models.append((provider, name))

    # -- per tick ------------------------------------------------------------------------------

    def record_tick(self, t: float, visited: Iterable[Behaviour]) -> None:
        """Count the nodes ticked at robot time ``t``; keep when each became active and stopped being.

        A node is active from a tick that ticked it (or left it RUNNING) to the next tick that does
        neither; only the nodes whose activity changed are looked at one by one (set operations do
        the rest), so the cost follows what changed, not the tree's size.
        """
        self._last_t = t
        ticked = set(visited)
        self.ticks.update(ticked)
        if len(self.ticks) > self._known:  # nodes added to the tree during the run
            for node in ticked:
                if node not in self.node_cpu:
                    self._wrap_node(node)
            self._known = len(self.ticks)
        was_open = self._open
        still = {n for n in was_open - ticked if n.status is RUNNING}
        now_open = ticked | still if still else ticked
        since, active = self._since, self.active_s
        for node in was_open - now_open:
            active[node] = active.get(node, 0.0) + (t - since.pop(node))
        for node in now_open - was_open:
            since[node] = t
        self._open = now_open

    def add_tick_cpu(self, seconds: float) -> None:
        """Add CPU the tick thread spent ticking (nodes and the engine's bookkeeping)."""
        self.tick_cpu_s += seconds

    def add_sim_cpu(self, seconds: float) -> None:
        """Add CPU the tick thread spent in the robot's stepping."""
        self.sim_cpu_s += seconds

    def close_active(self, t: float, period: float = 0.0) -> None:
        """Count the last interval's active time: up to robot time ``t``, at least one tick ``period``.

        A run that ends on a final status ends at its last tick; that tick still stands for a
        period of the node's activity (four ticks at 10 Hz are 10 Hz, not 13).
        """
        if self._last_t is None:
            return
        end = max(t, self._last_t + period)
        for node in self._open:
            self.active_s[node] = self.active_s.get(node, 0.0) + (end - self._since.pop(node))
        self._open = set()

    # -- the result ----------------------------------------------------------------------------

    def summary(self, robot_s: float) -> dict[str, Any]:
        """The ``profile`` section of summary.json (see the module docstring)."""
        cpu_s = max(process_cpu_s() - self._cpu0, 0.0)
        wall_s = max(time.perf_counter() - self._wall0, 0.0)
        nodes: dict[str, dict[str, Any]] = {}
        for node in set(self.ticks) | {n for n, c in self.node_cpu.items() if c > 0}:
            ticks = self.ticks.get(node, 0)
            active = self.active_s.get(node, 0.0)
            nodes[self.path_of(node)] = {
                "ticks": ticks,
                "rate_hz": round(ticks / active, 3) if active > 0 else 0.0,
                "active_s": round(active, 3),
                "cpu_s": round(self.node_cpu.get(node, 0.0), 6),
            }
        models = {
            role: {"calls": s.calls, "cpu_s": round(s.cpu_s, 6),
                   "latency_ms_p50": round(percentile(s.latencies, 50) * 1e3, 3),
                   "latency_ms_p95": round(percentile(s.latencies, 95) * 1e3, 3)}
            for role, s in sorted(self.roles.items()) if s.calls}
        nodes_cpu = sum(self.node_cpu.values())
        run = {
            "cpu_s": round(cpu_s, 4),
            "wall_s": round(wall_s, 6),
            "robot_s": round(robot_s, 4),
            "realtime_factor": round(robot_s / wall_s, 3) if wall_s > 0 else 0.0,
            "cpu_realtime_factor": round(robot_s / cpu_s, 3) if cpu_s > 0 else 0.0,
            "rss_peak_mb": round(rss_peak_mb(), 1),
            "startup_cpu_s": round(self._startup_cpu, 4),
            "tick_cpu_s": round(self.tick_cpu_s, 4),
            "nodes_cpu_s": round(nodes_cpu, 4),
            "engine_cpu_s": round(max(self.tick_cpu_s - nodes_cpu, 0.0), 4),
            "sim_cpu_s": round(self.sim_cpu_s, 4),
            "models_cpu_s": round(sum(s.cpu_s for s in self.roles.values()), 4),
            "worker_models_cpu_s": round(self.worker.cpu_s, 4),
        }
        return {"run": run, "nodes": dict(sorted(nodes.items())), "models": models,
                "sim_cpu_s": run["sim_cpu_s"]}


def _timed_call(method: Callable[..., Any], stats: _RoleStats, worker: _WorkerCpu) -> Callable[..., Any]:
    """``method`` timed into ``stats`` (wall latency and the calling thread's CPU)."""
    outer = worker.outer

    def timed(*args: Any, **kwargs: Any) -> Any:
        wall = time.perf_counter()
        cpu = _thread_time()
        outer.depth += 1
        try:
            return method(*args, **kwargs)
        finally:
            outer.depth -= 1
            used = _thread_time() - cpu
            latency = time.perf_counter() - wall
            with worker.lock:  # two workers may finish at once
                stats.add(latency, used)
                if outer.depth == 0 and threading.get_ident() != worker.tick_thread:
                    worker.cpu_s += used

    timed.__wrapped__ = method  # type: ignore[attr-defined]  # functools-style: the original stays reachable
    return timed


def cost_centres(profile: dict[str, Any], top: int = 8) -> list[tuple[str, float, float]]:
    """The run's largest costs: (what, CPU seconds, share of the run's CPU), largest first.

    Nodes by path (their own CPU), ``model:<role>`` per role, ``sim stepping``, ``engine`` (ticking
    and the tick log) and ``other`` (the rest of the run's CPU: what no node, model call or the
    simulator took, e.g. the end's pictures). A model call made inside a node on the tick thread is
    in both figures, and a nested model call in both roles': the list is of cost centres, not a sum.
    """
    run = profile.get("run", {})
    total = float(run.get("cpu_s", 0.0))
    if total <= 0:  # a run that ended before its first tick: nothing to share out
        return []
    items: list[tuple[str, float]] = [(path, float(v.get("cpu_s", 0.0)))
                                      for path, v in profile.get("nodes", {}).items()]
    items += [(f"model:{role}", float(v.get("cpu_s", 0.0))) for role, v in profile.get("models", {}).items()]
    items += [("sim stepping", float(run.get("sim_cpu_s", 0.0))),
              ("engine", float(run.get("engine_cpu_s", 0.0)))]
    accounted = sum(float(run.get(key, 0.0)) for key in ("tick_cpu_s", "sim_cpu_s", "worker_models_cpu_s"))
    items.append(("other", max(total - accounted, 0.0)))
    items = [i for i in items if i[1] > 0]
    items.sort(key=lambda i: -i[1])
    return [(name, cpu, cpu / total) for name, cpu in items[:top]]
