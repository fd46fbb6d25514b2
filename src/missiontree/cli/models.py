"""``missiontree models``: list the configured model providers and check that each one is usable.

For every role of a models config (config/models/*.yaml, default ``offline``) it builds the
provider and checks it — loads the model, pings the server (the provider's ``check()``; a detector
without one is run on a blank frame) — and prints one line per role. With ``--no-check`` it builds
none: the config is still checked whole, and the roles are listed from it. Exit code 0 when every role is
usable, 1 when one is not (its line says why and how to fix it), 2 when the config itself is broken.
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import numpy as np

from missiontree.cli import add_plugin_flag, plugins_from_args, print_json
from missiontree.reasoning.models import Models
from missiontree.session.models import (
    DEFAULT_MODELS,
    build_models,
    describe_source,
    load_models_config,
)

EXIT_UNUSABLE = 1
_BLANK = np.zeros((64, 64, 3), dtype=np.uint8)


def register(subparsers: Any) -> None:
    """Add the ``models`` subcommand."""
    parser = subparsers.add_parser(
        "models", help="list the configured model providers and check each one",
        description="Build every role of a models config, check each provider (load the model, ping "
        "the server) and print one line per role. Exit 0 when all are usable, 1 otherwise.",
    )
    parser.add_argument("--models",
                        help=f"models config: a shipped name or a path (default: {DEFAULT_MODELS})")
    parser.add_argument("--no-check", action="store_true", help="list the providers without checking them")
    parser.add_argument("--json", action="store_true", help="print the result as JSON")
    add_plugin_flag(parser)
    parser.set_defaults(func=run)


def check_provider(provider: Any) -> str:
    """Check one provider; return its one-line description (raises with the reason when unusable).

    A detector is also run on test frames and its answer checked as a mission checks it: boxes
    that are not finite or lie outside the image make it unusable, whatever its ``check()`` said.
    """
    check = getattr(provider, "check", None)
    detect = getattr(provider, "detect", None)
    line = str(check()) if callable(check) else ""
    if callable(detect) and not getattr(provider, "needs_robot", False):  # the oracle needs the robot
        _check_detections(provider)
        if not line:
            labels = list(getattr(provider, "labels", []) or [])
            more = " ..." if len(labels) > 8 else ""
            line = f"detector with {len(labels)} labels: {', '.join(labels[:8])}{more}"
    return line or f"{type(provider).__name__} (no check available)"


def _check_detections(detector: Any) -> None:
    """Run ``detector`` on test frames; raise ModelError when its answer holds unusable boxes."""
    from missiontree.errors import ModelError
    from missiontree.perception.detectors import checked_detections

    for frame in _test_frames():
        height, width = frame.shape[:2]
        answer = detector.detect(frame)
        _, dropped = checked_detections(answer, width, height, str(getattr(detector, "name", "detector")))
        if dropped:
            more = f" (and {len(dropped) - 1} more)" if len(dropped) > 1 else ""
            raise ModelError(f"the detector's answer on a {width}x{height} test frame is unusable: "
                             f"{dropped[0]}{more}; a mission would drop these boxes: fix the model")


def _test_frames() -> list[np.ndarray]:
    """A blank frame and a seeded noise frame of the camera's usual size."""
    noise = np.random.default_rng(0).integers(0, 256, size=(240, 320, 3), dtype=np.uint8)
    return [_BLANK, noise]


def run(args: argparse.Namespace) -> int:
    """List and check the providers; return 0 when all are usable."""
    plugins = plugins_from_args(args)
    name = args.models if args.models is not None else DEFAULT_MODELS
    document = load_models_config(name)
    models = Models(build_models(name, plugins.providers, strict=False))  # unknown providers become rows
    settings = models.settings
    rows: list[dict[str, Any]] = []
    for role, section in document.data["roles"].items():
        latency = settings.latency.get(role)
        row: dict[str, Any] = {
            "role": role,
            "provider": str(section.get("provider")),
            "plugin": plugins.provided_by("providers", str(section.get("provider"))),
            "timeout": settings.timeouts.get(role, settings.default_timeout),
            "latency": None if latency is None else [latency.low, latency.high],
        }
        if args.no_check:
            row["status"] = "unchecked"
        else:
            start = time.perf_counter()
            try:  # the role is built here, as part of its check (--no-check builds none)
                row["detail"] = check_provider(models[role])
                row["status"] = "ok"
            except Exception as exc:  # noqa: BLE001 - any failure is this provider's verdict, shown in full
                row["status"] = "unusable"
                row["error"] = str(exc) if str(exc) else type(exc).__name__
            row["check_seconds"] = round(time.perf_counter() - start, 3)
        rows.append(row)
    usable = all(r["status"] != "unusable" for r in rows)
    if args.json:
        print_json({"config": describe_source(name), "usable": usable, "roles": rows})
    else:
        print(f"models config: {describe_source(name)}")
        width = max((len(r["role"]) for r in rows), default=4)
        pwidth = max((len(r["provider"]) for r in rows), default=8)
        for r in rows:
            timing = _timing(r)
            text = r.get("detail") or r.get("error") or ""
            print(f"  {r['role']:<{width}}  {r['provider']:<{pwidth}}  {r['status']:<9} {text}{timing}")
        bad = [r["role"] for r in rows if r["status"] == "unusable"]
        print("all providers usable" if usable else f"unusable: {', '.join(bad)}")
    return 0 if usable else EXIT_UNUSABLE


def _timing(row: dict[str, Any]) -> str:
    parts = []
    if row.get("latency") is not None:
        low, high = row["latency"]
        parts.append(f"simulated latency {low:g} s" if low == high
                     else f"simulated latency {low:g}-{high:g} s")
    if row.get("timeout") is not None:
        parts.append(f"timeout {row['timeout']:g} s")
    return f"  [{', '.join(parts)}]" if parts else ""
