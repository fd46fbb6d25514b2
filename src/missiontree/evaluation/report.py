"""A batch's results: ``results.jsonl``, ``summary.json``, the printed table and ``junit.xml``.

Success rates come with a 95 % Wilson score interval (:func:`wilson`): unlike the normal
approximation it stays inside [0, 1] and is honest at 0/n and n/n, which small batches hit.
Infrastructure failures (the process running a mission died twice) are counted apart: they are
not results of the mission, so they are in no rate's denominator — but they fail the batch.
"""

from __future__ import annotations

import json
import math
import xml.etree.ElementTree as ET
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from missiontree.evaluation.batch import RunRecord

__all__ = ["batch_passed", "format_table", "percentile", "summarize", "wilson", "write_junit",
           "write_results"]

Z95 = 1.959963984540054


def wilson(successes: int, trials: int, z: float = Z95) -> tuple[float, float]:
    """The Wilson score interval of a success rate (95 % by default); (0, 1) for no trials."""
    if trials <= 0:
        return 0.0, 1.0
    p = successes / trials
    denominator = 1 + z * z / trials
    centre = (p + z * z / (2 * trials)) / denominator
    half = z * math.sqrt(p * (1 - p) / trials + z * z / (4 * trials * trials)) / denominator
    return max(0.0, centre - half), min(1.0, centre + half)


def percentile(values: Sequence[float], q: float) -> float | None:
    """The q-th percentile (0-100, linear between ranks); None for no values."""
    if not values:
        return None
    ordered = sorted(values)
    rank = (len(ordered) - 1) * q / 100.0
    low = math.floor(rank)
    high = min(low + 1, len(ordered) - 1)
    return ordered[low] + (ordered[high] - ordered[low]) * (rank - low)


def _group(records: Iterable[RunRecord]) -> dict[str, Any]:
    records = list(records)
    results = [r for r in records if not r.infra]
    passed = sum(r.passed for r in results)
    low, high = wilson(passed, len(results))
    times = [r.robot_time_s for r in results]
    return {
        "runs": len(records), "results": len(results), "passed": passed, "failed": len(results) - passed,
        "errors": sum(r.status == "ERROR" for r in results), "infra_failures": len(records) - len(results),
        "success_rate": round(passed / len(results), 4) if results else None,
        "wilson95": [round(low, 4), round(high, 4)],
        "robot_time_s": {"median": _round(percentile(times, 50)), "p90": _round(percentile(times, 90))},
        "path_length_m": {"median": _round(percentile([r.path_length_m for r in results], 50))},
    }


def summarize(records: Sequence[RunRecord], sweep_keys: Sequence[str] = (), **extra: Any) -> dict[str, Any]:
    """The batch's ``summary.json``: overall, per world and per value of each parameter."""
    summary = {**_group(records), **extra}
    wall = [r.wall_time_s for r in records if not r.infra]
    summary["wall_time_s"] = {"median": _round(percentile(wall, 50)), "p90": _round(percentile(wall, 90)),
                              "total": round(sum(wall), 3)}
    worlds: dict[str, list[RunRecord]] = {}
    for record in records:
        worlds.setdefault(record.world or "default", []).append(record)
    summary["by_world"] = {world: _group(rs) for world, rs in worlds.items()}
    keys = list(sweep_keys) or sorted({k for r in records for k in r.params if _varies(records, k)})
    by_param: dict[str, dict[str, Any]] = {}
    for key in keys:
        values: dict[str, list[RunRecord]] = {}
        for record in records:
            values.setdefault(str(record.params.get(key)), []).append(record)
        by_param[key] = {value: _group(rs) for value, rs in values.items()}
    summary["by_param"] = by_param
    summary["failed_runs"] = [r.run_id for r in records if not r.passed][:50]
    return summary


def batch_passed(summary: dict[str, Any], min_success: float | None) -> bool:
    """Every run succeeded (no failure, error or infrastructure failure), or ``min_success`` is met.

    With ``min_success`` the batch passes when the success rate reaches it and no run was lost to
    infrastructure; without it, only when every run succeeded.
    """
    if summary["infra_failures"]:
        return False
    if min_success is None:
        return summary["failed"] == 0
    rate = summary["success_rate"]
    return rate is not None and rate + 1e-12 >= min_success


def format_table(summary: dict[str, Any]) -> str:
    """The printed table: success rate with its Wilson interval, robot time median/p90, per group."""
    header = f"{'group':<34} {'runs':>5} {'ok':>5} {'rate':>7}  {'95% Wilson':<15} {'time med':>9} {'p90':>8}"
    lines = [header, "-" * len(header)]

    def row(name: str, group: dict[str, Any]) -> str:
        rate = group["success_rate"]
        low, high = group["wilson95"]
        times = group["robot_time_s"]
        infra = f"  ({group['infra_failures']} infra)" if group["infra_failures"] else ""
        return (f"{name[:34]:<34} {group['results']:>5} {group['passed']:>5} "
                f"{'-' if rate is None else f'{100 * rate:.1f}%':>7}  [{100 * low:5.1f}, {100 * high:5.1f}]%"
                f" {_fmt(times['median']):>9} {_fmt(times['p90']):>8}{infra}")

    lines.append(row("all", summary))
    if len(summary["by_world"]) > 1:
        lines.extend(row(f"world {w}", g) for w, g in summary["by_world"].items())
    for key, values in summary["by_param"].items():
        lines.extend(row(f"{key}={v}", g) for v, g in values.items())
    return "\n".join(lines)


def write_results(records: Sequence[RunRecord], path: Path) -> None:
    """``results.jsonl``: one record a line, in plan order (written whole, then renamed)."""
    partial = path.with_name(path.name + ".partial")
    with partial.open("w", encoding="utf-8") as stream:
        for record in records:
            stream.write(json.dumps(record.to_json(), sort_keys=True) + "\n")
    partial.replace(path)


def write_junit(records: Sequence[RunRecord], path: Path, name: str) -> None:
    """``junit.xml``: one testsuite, one testcase per run (a failure, error or infra error inside).

    The mission's FAILURE or limit is a ``<failure>``; a run that raised or was lost to
    infrastructure is an ``<error>`` (the JUnit distinction between a failed assertion and a
    broken test).
    """
    failures = sum(1 for r in records if not r.passed and r.status not in ("ERROR", "INFRA"))
    errors = sum(1 for r in records if r.status in ("ERROR", "INFRA"))
    total_time = sum(r.wall_time_s for r in records)
    suites = ET.Element("testsuites", name=name, tests=str(len(records)), failures=str(failures),
                        errors=str(errors), time=f"{total_time:.3f}")
    suite = ET.SubElement(suites, "testsuite", name=name, tests=str(len(records)), failures=str(failures),
                          errors=str(errors), skipped="0", time=f"{total_time:.3f}")
    for record in records:
        case = ET.SubElement(suite, "testcase", name=record.run_id,
                             classname=f"{name}.{_classname(record.world or 'default')}",
                             time=f"{record.wall_time_s:.3f}")
        detail = (f"world={record.world or 'default'} seed={record.seed} run_seed={record.run_seed} "
                  f"params={json.dumps(record.params, sort_keys=True)} robot_time_s={record.robot_time_s} "
                  f"run_dir={record.run_dir}")
        if record.status in ("ERROR", "INFRA"):
            kind = "infrastructure" if record.infra else "error"
            ET.SubElement(case, "error", message=record.reason, type=kind).text = detail
        elif not record.passed:
            ET.SubElement(case, "failure", message=record.reason,
                          type=f"{record.status}/{record.stopped_by}").text = detail
        ET.SubElement(case, "system-out").text = detail
    tree = ET.ElementTree(suites)
    ET.indent(tree)
    tree.write(path, encoding="utf-8", xml_declaration=True)


def _classname(text: str) -> str:
    return "".join(c if c.isalnum() or c in "_-" else "_" for c in text)


def _varies(records: Sequence[RunRecord], key: str) -> bool:
    return len({str(r.params.get(key)) for r in records}) > 1


def _round(value: float | None) -> float | None:
    return None if value is None else round(value, 3)


def _fmt(value: float | None) -> str:
    return "-" if value is None else f"{value:.1f}s"
