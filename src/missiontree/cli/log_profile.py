"""``missiontree log profile RUN``: where a run's time went, as the NAIS paper's Table III.

Reads the ``profile`` section of the run's ``summary.json`` (written by every run:
:mod:`missiontree.engine.profile`) and prints one row per node (ticks, rate in Hz, CPU seconds and
share of the run's CPU), one per model role (calls, latency p50/p95, CPU), the simulator's
stepping, the engine's own bookkeeping, and the run's totals (CPU, wall and robot time, real-time
factor, peak RSS), then the largest cost centres.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from missiontree.cli import print_json
from missiontree.engine.profile import cost_centres
from missiontree.engine.recorder import SUMMARY_FILE, read_summary
from missiontree.errors import ConfigError


def add_to(actions: Any) -> None:
    """Add ``log profile`` to the ``log`` subcommand group."""
    parser = actions.add_parser(
        "profile", help="where the run's time went (per node, model and simulator)",
        description="Print a run's profile from its summary.json, as the NAIS paper's Table III: per "
        "node its ticks, rate (Hz) and CPU; per model role its calls and latency; the simulator's "
        "stepping; the run's CPU, wall and robot time and peak memory; the largest cost centres.",
    )
    parser.add_argument("run_path", metavar="RUN", type=Path, help="a run directory or its summary.json")
    parser.add_argument("--top", type=int, default=0, metavar="N",
                        help="show only the N nodes that used the most CPU (default: every node ticked)")
    parser.add_argument("--json", action="store_true", help="print the profile as JSON")
    parser.set_defaults(func=run)


def read_profile(run_path: Path) -> tuple[str, dict[str, Any]]:
    """The mission's name and the ``profile`` section of a run's summary.json.

    Raises:
        ConfigError: No readable summary, or one without a profile (written by an older version).
    """
    path = run_path / SUMMARY_FILE if run_path.is_dir() else run_path
    summary = read_summary(path)
    profile = summary.get("profile")
    if not isinstance(profile, dict) or not isinstance(profile.get("run"), dict):
        done = summary.get("complete", True)
        why = "the run has not finished yet" if not done else "it was written by a version without profiles"
        raise ConfigError(f"{path} has no profile section ({why}); run the mission again to get one")
    return str(summary.get("mission", "?")), profile


def _pct(part: float, whole: float) -> str:
    return f"{100.0 * part / whole:5.1f}" if whole > 0 else "    -"


def format_profile(mission: str, profile: dict[str, Any], top: int = 0) -> str:
    """The text table of a run's profile (see the module docstring)."""
    run = profile["run"]
    cpu = float(run.get("cpu_s", 0.0))
    out = [f"mission {mission}: {run.get('robot_s', 0):.1f} s on the robot clock in "
           f"{run.get('wall_s', 0):.2f} s wall ({run.get('realtime_factor', 0):.1f}x real time) "
           f"and {cpu:.2f} s CPU "
           f"({run.get('cpu_realtime_factor', 0):.1f}x); peak RSS {run.get('rss_peak_mb', 0):.0f} MB; "
           f"start-up before the first tick {run.get('startup_cpu_s', 0):.2f} s CPU"]
    nodes = sorted(profile.get("nodes", {}).items(), key=lambda kv: (-kv[1].get("cpu_s", 0.0), kv[0]))
    if top > 0:
        nodes = nodes[:top]
    width = max([len("node"), *(len(path) for path, _ in nodes)])
    out.append("")
    out.append(f"{'node':<{width}}  {'ticks':>7}  {'rate Hz':>7}  {'CPU s':>8}  {'CPU %':>5}")
    for path, entry in nodes:
        out.append(f"{path:<{width}}  {entry.get('ticks', 0):>7}  {entry.get('rate_hz', 0.0):>7.2f}  "
                   f"{entry.get('cpu_s', 0.0):>8.3f}  {_pct(entry.get('cpu_s', 0.0), cpu)}")
    models = profile.get("models", {})
    if models:
        out.append("")
        out.append(f"{'model role':<12}  {'calls':>6}  {'p50 ms':>8}  {'p95 ms':>8}  {'CPU s':>8}  "
                   f"{'CPU %':>5}")
        for role, entry in models.items():
            out.append(f"{role:<12}  {entry.get('calls', 0):>6}  {entry.get('latency_ms_p50', 0.0):>8.1f}  "
                       f"{entry.get('latency_ms_p95', 0.0):>8.1f}  {entry.get('cpu_s', 0.0):>8.3f}  "
                       f"{_pct(entry.get('cpu_s', 0.0), cpu)}")
    out.append("")
    for label, key in (("simulator stepping", "sim_cpu_s"), ("engine (ticking, tick log)", "engine_cpu_s"),
                       ("all nodes", "nodes_cpu_s")):
        value = float(run.get(key, 0.0))
        out.append(f"{label:<27} {value:8.3f} s CPU  {_pct(value, cpu)} %")
    out.append("")
    centres = cost_centres(profile, top=5)
    out.append("largest cost centres: " + ("; ".join(f"{name} {share:.0%}" for name, _, share in centres)
                                           or "none (the run used no CPU after its start)"))
    return "\n".join(out)


def run(args: argparse.Namespace) -> int:
    """Print one run's profile."""
    mission, profile = read_profile(args.run_path)
    if args.json:
        print_json(profile)
    else:
        print(format_profile(mission, profile, top=args.top))
    return 0
