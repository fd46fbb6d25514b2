"""Soak: trees/patrol.yaml for 2 simulated hours with people and model faults; memory, log, tick period.

The patrol runs lap after lap of the combined world (people walking) through the session, as
``missiontree run`` does, with the oracle detector and a vision-language model that fails on cue:
every 7th call raises a model error and every 11th answers garbage that is not the verdict's JSON
(both logged and absorbed below Surveillance's consecutive-failure limit, so the patrol goes on).

Printed as the run goes: each simulated 10 minutes the process's resident memory (RSS), the tick
log's size and the wall time. At the end: the tick log's size per simulated hour, RSS over time,
and the tick period's percentiles. The last line is one JSON object:

- ``rss_growth_mib``: RSS at the last sample of the run (the 2 hours' last simulated minute) minus
  RSS after the first 10 simulated minutes (target <= 10); ``rss_growth_max_mib``: the highest sample
  after 10 minutes minus that value; ``rss_after_run_mib``: RSS once the run ended (the top-down
  picture drawn, the summary written), for reference;
- ``ticklog_mb_per_hour``: the tick log's size (10^6 bytes) per simulated hour (target <= 10);
- ``tick_period_p99_ms``: the 99th percentile of the wall time from one tick to the next (the tree's
  tick, the tick log and the simulator's step to the next tick time); ``tick_cost_p99_ms``: the same
  for the tree's tick and its log line alone.

On glibc the heap's in-use and free MiB (``mallinfo2``) are sampled with the RSS, and printed
over time: growth in the free part is fragmentation, growth in the in-use part is memory kept
(the process is tuned as the command line tunes its own, glibc's mmap threshold pinned against the
former: ``missiontree.session.process``).
``heap_inuse_growth_mib`` and ``heap_free_growth_mib`` are their changes over the same span as
``rss_growth_mib``. A single sample carries what is in flight at that instant (frames held by model
calls, the oracle detector's recent frames; the simulator's 10 s of instance masks sit in one fixed
buffer). The heap's in-use part used to swing by 5-9 MiB between samples: every failed model call
(every 7th here) sat in a reference cycle with its traceback and its frames until the cyclic
garbage collector ran, which numpy buffers do not hasten (fixed in ``missiontree.reasoning.calls``).
``rss_floor_growth_mib`` is the retained part, the lowest RSS
of the last 10 simulated minutes minus the lowest of minutes 10-20 (RSS read every 5 ticks).

The warnings the run prints (one per rejected model answer) go to ``<out>.warnings.log``.

Usage: ``python benchmarks/soak.py [--hours 2] [--out runs/soak]``.
"""

from __future__ import annotations

import argparse
import ctypes
import json
import os
import shutil
import sys
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import structlog

from missiontree.errors import ModelError
from missiontree.plugins.manager import load_plugins
from missiontree.reasoning.providers import create_offline_vlm
from missiontree.session import MissionRequest, Session
from missiontree.session.process import tune_process

REPO = Path(__file__).resolve().parents[1]
MISSION = REPO / "trees" / "patrol.yaml"
SAMPLE_S = 60.0  # simulated seconds between memory samples
BASELINE_S = 600.0  # RSS growth counts from here (the first 10 simulated minutes warm up)
PAGE = os.sysconf("SC_PAGE_SIZE")


def rss_mib() -> float:
    """This process's resident set size, MiB."""
    with open("/proc/self/statm", encoding="ascii") as handle:
        return int(handle.read().split()[1]) * PAGE / 2**20


class _MallInfo2(ctypes.Structure):
    _fields_ = [(name, ctypes.c_size_t) for name in (
        "arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks", "uordblks", "fordblks",
        "keepcost")]


def _mallinfo2() -> Any:
    try:
        function = ctypes.CDLL("libc.so.6").mallinfo2  # glibc >= 2.33
    except (OSError, AttributeError):
        return None
    function.restype = _MallInfo2
    return function


_MALLINFO2 = _mallinfo2()


def heap_mib() -> tuple[float, float]:
    """The glibc heap: (in use incl. mmapped blocks, free in the heap) MiB; (nan, nan) elsewhere."""
    if _MALLINFO2 is None:
        return float("nan"), float("nan")
    info = _MALLINFO2()
    return (info.uordblks + info.hblkhd) / 2**20, info.fordblks / 2**20


class FlakyVision:
    """A vision-language model that fails on cue.

    Every ``fail_every``-th call raises, every ``garbage_every``-th answers text that is not the
    asked JSON; the rest go to ``inner``.
    """

    def __init__(self, inner: Any, fail_every: int, garbage_every: int) -> None:
        self.inner = inner
        self.fail_every = fail_every
        self.garbage_every = garbage_every
        self.calls = 0
        self.name = "flaky_vlm"

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)

    def ask(self, images: Sequence[np.ndarray], prompt: str, schema: Any = None) -> str:
        """Answer, fail or babble, by call number."""
        self.calls += 1
        if self.calls % self.fail_every == 0:
            raise ModelError(f"flaky_vlm: injected fault on call {self.calls}")
        if self.calls % self.garbage_every == 0:
            return "<html>502 bad gateway</html> {not json"
        return str(self.inner.ask(images, prompt, schema))


def create_flaky_vlm(options: Mapping[str, Any], models: Mapping[str, Any], seed: int = 0) -> FlakyVision:
    """Provider ``flaky_vlm``: ``offline_vlm`` on the detector role, failing on cue."""
    inner_options = {k: v for k, v in options.items() if k not in ("fail_every", "garbage_every")}
    inner = create_offline_vlm(inner_options, models, seed)
    return FlakyVision(inner, int(options.get("fail_every", 7)), int(options.get("garbage_every", 11)))


create_flaky_vlm.wants_models = True  # type: ignore[attr-defined]

MODELS: dict[str, Any] = {
    "roles": {
        "detector": {"provider": "oracle", "miss_rate": 0.05, "false_positive_rate": 0.01},
        "vlm": {"provider": "flaky_vlm", "detector": "detector", "latency": {"uniform": [0.5, 3.0]},
                "timeout": 10, "fail_every": 7, "garbage_every": 11},
    },
    "calls": {"timeout": 30},
}


def soak(hours: float, out: Path) -> dict[str, Any]:
    """Run the patrol for ``hours`` simulated hours; return the figures."""
    out.parent.mkdir(parents=True, exist_ok=True)
    warnings = (out.parent / f"{out.name}.warnings.log").open("w", encoding="utf-8")
    structlog.configure(logger_factory=structlog.PrintLoggerFactory(file=warnings))
    plugins = load_plugins(autoload=False)
    plugins.providers["flaky_vlm"] = create_flaky_vlm
    seconds = hours * 3600.0
    if out.exists():
        shutil.rmtree(out)
    request = MissionRequest(mission=MISSION, out=out, models=MODELS, max_duration=seconds,
                             params={"laps": "100000"}, quiet=True, plugins=plugins)
    ticks_max = int(seconds * 10) + 100
    period = np.zeros(ticks_max)  # allocated before the baseline: the measurement does not grow
    cost = np.zeros(ticks_max)
    samples: list[tuple[float, float, int, float]] = []  # (robot s, RSS MiB, log bytes, wall s)
    heap: list[tuple[float, float]] = []  # (in use, free) MiB at each sample
    state = {"n": 0, "last": 0.0, "next_sample": 0.0, "wall0": time.perf_counter()}
    floor: list[float] = []  # the lowest RSS read (every 5 ticks) since the previous sample, MiB
    window = {"low": float("inf")}

    with Session.open(request) as session:
        runner = session.runner
        tick = runner.tick
        log_path = out / "ticks.jsonl"

        def timed_tick() -> Any:
            start = time.perf_counter()
            status = tick()
            n = state["n"]
            if n < ticks_max:
                cost[n] = time.perf_counter() - start
                if state["last"]:
                    period[n] = start - state["last"]
            state["last"] = start
            state["n"] = n + 1
            now = runner.robot.now()
            if n % 5 == 0:
                window["low"] = min(window["low"], rss_mib())
            if now >= state["next_sample"]:
                state["next_sample"] += SAMPLE_S
                size = log_path.stat().st_size if log_path.exists() else 0
                samples.append((now, rss_mib(), size, time.perf_counter() - state["wall0"]))
                heap.append(heap_mib())
                floor.append(min(window["low"], samples[-1][1]))
                window["low"] = float("inf")
                if len(samples) % 10 == 1:
                    print(f"  t={now / 60:6.1f} min  rss={samples[-1][1]:7.1f} MiB  "
                          f"log={size / 1e6:6.2f} MB  wall={samples[-1][3]:6.0f} s", flush=True)
            return status

        runner.tick = timed_tick  # type: ignore[method-assign]
        result = session.run()
        vlm_calls = getattr(session.models.get("vlm"), "calls", 0)
    wall = time.perf_counter() - state["wall0"]
    n = min(state["n"], ticks_max)
    log_bytes = (out / "ticks.jsonl").stat().st_size
    after = [s for s in samples if s[0] >= BASELINE_S]
    base = after[0][1] if after else samples[0][1]
    base_heap = heap[samples.index(after[0])] if after else heap[0]
    rss_end = samples[-1][1]
    early = [f for s, f in zip(samples, floor, strict=True) if BASELINE_S <= s[0] < BASELINE_S + 600.0]
    late = [f for s, f in zip(samples, floor, strict=True) if s[0] > samples[-1][0] - 600.0]
    floor_growth = min(late) - min(early) if early and late else float("nan")
    rss_after = rss_mib()
    structlog.reset_defaults()
    warnings.close()
    per_hour = []
    for hour in range(1, int(np.ceil(result.duration / 3600.0)) + 1):
        until = [s[2] for s in samples if s[0] <= hour * 3600.0]
        since = [s[2] for s in samples if s[0] <= (hour - 1) * 3600.0]
        per_hour.append(((until[-1] if until else 0) - (since[-1] if since else 0)) / 1e6)
    periods = period[1:n][period[1:n] > 0] * 1e3
    costs = cost[:n] * 1e3
    print(f"\npatrol: {result.status.name} ({result.stopped_by}) after {result.ticks} ticks, "
          f"{result.duration / 3600:.2f} simulated h in {wall:.0f} s wall "
          f"({result.duration / wall:.1f}x real time)")
    print(f"events: {json.dumps(result.summary.get('events', {}), sort_keys=True)}; vlm calls {vlm_calls}")
    print("RSS over time (simulated min: MiB): "
          + ", ".join(f"{s[0] / 60:.0f}: {s[1]:.1f}" for s in samples[::10]))
    print("RSS floor over time (simulated min: lowest MiB of the minute before): "
          + ", ".join(f"{s[0] / 60:.0f}: {f:.1f}" for s, f in list(zip(samples, floor, strict=True))[::10]))
    paired = list(zip(samples, heap, strict=True))[::10]
    print("heap in use / free over time (simulated min: MiB): "
          + ", ".join(f"{s[0] / 60:.0f}: {h[0]:.1f}/{h[1]:.1f}" for s, h in paired))
    print("tick log per simulated hour (MB): " + ", ".join(f"{v:.2f}" for v in per_hour))
    print(f"tick period ms: p50 {np.percentile(periods, 50):.2f}  p99 {np.percentile(periods, 99):.2f}  "
          f"max {periods.max():.2f}; tick cost ms: p50 {np.percentile(costs, 50):.3f}  "
          f"p99 {np.percentile(costs, 99):.3f}")
    return {
        "simulated_hours": round(result.duration / 3600.0, 3),
        "status": result.status.name, "stopped_by": result.stopped_by,
        "rss_baseline_mib": round(base, 2), "rss_end_mib": round(rss_end, 2),
        "rss_after_run_mib": round(rss_after, 2),
        "rss_growth_mib": round(rss_end - base, 2),
        "rss_floor_growth_mib": round(floor_growth, 2),
        "heap_inuse_growth_mib": round(heap[-1][0] - base_heap[0], 2),
        "heap_free_growth_mib": round(heap[-1][1] - base_heap[1], 2),
        "rss_growth_max_mib": round(max(s[1] for s in after) - base, 2) if after else 0.0,
        "ticklog_mb_per_hour": round(log_bytes / 1e6 / (result.duration / 3600.0), 3),
        "ticklog_mb_per_hour_each": [round(v, 3) for v in per_hour],
        "tick_period_p99_ms": round(float(np.percentile(periods, 99)), 3),
        "tick_period_p50_ms": round(float(np.percentile(periods, 50)), 3),
        "tick_cost_p99_ms": round(float(np.percentile(costs, 99)), 3),
        "vlm_calls": vlm_calls, "model_failures_injected": vlm_calls // 7 + vlm_calls // 11,
        "wall_s": round(wall, 1),
        "targets_met": bool(rss_end - base <= 10.0 and log_bytes / 1e6 / (result.duration / 3600.0) <= 10.0),
    }


def main(argv: Sequence[str] | None = None) -> int:
    """Run the soak and print the figures (last line JSON)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--hours", type=float, default=2.0, help="simulated hours (default 2)")
    parser.add_argument("--out", type=Path, default=REPO / "runs" / "soak", help="run directory")
    args = parser.parse_args(argv)
    tune_process()  # as `missiontree run` does: the mmap threshold pinned, the heap frozen during the run
    print(f"soak: {MISSION.name} for {args.hours:g} simulated hours, people and model faults", flush=True)
    figures = soak(args.hours, args.out)
    print(json.dumps(figures, sort_keys=True))
    return 0


if __name__ == "__main__":
    sys.exit(main())
