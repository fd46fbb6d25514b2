"""Helpers shared by the runlog tests: read a tick log back and replay it the plain way."""

from __future__ import annotations

import json
from pathlib import Path


def read_lines(run: Path) -> list[dict]:
    """The run's tick log, one dict a line."""
    return [json.loads(line) for line in (run / "ticks.jsonl").read_text().splitlines() if line.strip()]


def statuses_by_replaying(lines: list[dict], upto_tick: int) -> dict[str, str]:
    """Every node's status after tick ``upto_tick``, replayed straight from the lines (the oracle)."""
    status: dict[str, str] = {}
    for line in lines:
        if line.get("event") != "tick" or line["tick"] > upto_tick:
            continue
        for change in line.get("changed", []):
            status[change["node"]] = change["status"]
    return status
