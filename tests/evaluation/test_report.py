"""Tests of batch reports: Wilson intervals, summaries by world and parameter, JUnit XML shape."""

from __future__ import annotations

import json
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from missiontree.evaluation.batch import RunRecord
from missiontree.evaluation.report import (
    batch_passed,
    format_table,
    percentile,
    summarize,
    wilson,
    write_junit,
    write_results,
)

# The element/attribute shape of the JUnit XSD Jenkins validates against (xunit-plugin junit-10.xsd):
# element -> (required attributes, optional attributes, allowed children)
JUNIT_SHAPE: dict[str, tuple[set[str], set[str], set[str]]] = {
    "testsuites": (set(), {"name", "time", "tests", "failures", "disabled", "errors"}, {"testsuite"}),
    "testsuite": ({"name", "tests"}, {"failures", "errors", "skipped", "disabled", "time", "timestamp",
                                      "hostname", "id", "package", "file", "log", "url", "version", "group"},
                  {"properties", "testcase", "system-out", "system-err"}),
    "testcase": ({"name"}, {"classname", "time", "assertions", "status", "group", "file", "line"},
                 {"skipped", "error", "failure", "system-out", "system-err"}),
    "failure": (set(), {"message", "type"}, set()),
    "error": (set(), {"message", "type"}, set()),
    "skipped": (set(), {"message"}, set()),
    "system-out": (set(), set(), set()),
    "system-err": (set(), set(), set()),
    "properties": (set(), set(), {"property"}),
    "property": ({"name", "value"}, set(), set()),
}
INTEGER = {"tests", "failures", "errors", "skipped", "disabled", "assertions"}
DECIMAL = re.compile(r"^-?\d+(\.\d+)?$")


def validate_junit(path: Path) -> ET.Element:
    """Raise AssertionError where ``path`` breaks the JUnit XSD's shape or its counts disagree."""
    root = ET.parse(path).getroot()
    assert root.tag in ("testsuites", "testsuite")

    def check(element: ET.Element) -> None:
        assert element.tag in JUNIT_SHAPE, f"unknown element {element.tag}"
        required, optional, children = JUNIT_SHAPE[element.tag]
        attributes = set(element.attrib)
        assert required <= attributes, f"{element.tag} lacks {required - attributes}"
        assert attributes <= required | optional, f"{element.tag} has {attributes - required - optional}"
        for name in attributes & INTEGER:
            assert element.attrib[name].isdigit(), f"{element.tag}@{name}={element.attrib[name]!r}"
        if "time" in attributes:
            assert DECIMAL.match(element.attrib["time"]), element.attrib["time"]
        for child in element:
            assert child.tag in children, f"{child.tag} inside {element.tag}"
            check(child)
        if element.tag == "testcase":
            assert len(element.findall("skipped")) <= 1

    check(root)
    for suite in root.iter("testsuite"):
        cases = suite.findall("testcase")
        assert int(suite.attrib["tests"]) == len(cases)
        assert int(suite.attrib.get("failures", 0)) == sum(bool(c.findall("failure")) for c in cases)
        assert int(suite.attrib.get("errors", 0)) == sum(bool(c.findall("error")) for c in cases)
    return root


def record(run_id: str, status: str = "SUCCESS", world: str | None = "office", laps: str = "1",
           robot_time: float = 10.0) -> RunRecord:
    return RunRecord(run_id=run_id, world=world, seed=0, run_seed=0, params={"laps": laps}, status=status,
                     stopped_by="crash" if status == "INFRA" else "status", reason=f"because <{status}> & co",
                     robot_time_s=robot_time, wall_time_s=0.25, path_length_m=3.0, ticks=100,
                     run_dir=None if status == "INFRA" else f"runs/{run_id}")


def test_wilson_matches_published_values() -> None:
    """0/10, 5/10 and 10/10 give the textbook 95 % Wilson intervals; no trials gives [0, 1]."""
    assert wilson(0, 10) == pytest.approx((0.0, 0.2775), abs=1e-4)
    assert wilson(5, 10) == pytest.approx((0.2366, 0.7634), abs=1e-4)
    assert wilson(10, 10) == pytest.approx((0.7225, 1.0), abs=1e-4)
    assert wilson(81, 100) == pytest.approx((0.7222, 0.8749), abs=1e-4)
    assert wilson(0, 0) == (0.0, 1.0)


def test_percentile_is_linear_between_ranks() -> None:
    """Median and p90 of 1..10 are 5.5 and 9.1; nothing gives None."""
    values = [float(v) for v in range(10, 0, -1)]
    assert percentile(values, 50) == pytest.approx(5.5)
    assert percentile(values, 90) == pytest.approx(9.1)
    assert percentile([], 50) is None


def test_summary_groups_by_world_and_parameter_and_counts_infra_apart() -> None:
    """An infrastructure failure is in no rate's denominator but fails the batch."""
    records = [record("a"), record("b", "FAILURE", laps="2", robot_time=30.0),
               record("c", world="generated:1"), record("d", "INFRA", laps="2")]
    summary = summarize(records, ["laps"])
    assert (summary["results"], summary["passed"], summary["infra_failures"]) == (3, 2, 1)
    assert summary["success_rate"] == pytest.approx(2 / 3, abs=1e-4)
    assert summary["by_world"]["office"]["results"] == 2
    assert summary["by_world"]["generated:1"]["success_rate"] == 1.0
    assert summary["by_param"]["laps"]["2"]["passed"] == 0
    assert summary["by_param"]["laps"]["2"]["infra_failures"] == 1
    assert summary["robot_time_s"]["median"] == 10.0
    assert not batch_passed(summary, None)
    assert not batch_passed(summary, 0.5)  # the lost run fails the batch whatever the rate
    table = format_table(summary)
    assert "world generated:1" in table and "laps=2" in table and "(1 infra)" in table


def test_min_success_decides_when_given() -> None:
    """Three of four succeeded: fails without --min-success, passes at 0.75, fails at 0.8."""
    summary = summarize([record("a"), record("b"), record("c"), record("d", "FAILURE")])
    assert not batch_passed(summary, None)
    assert batch_passed(summary, 0.75)
    assert not batch_passed(summary, 0.8)


def test_junit_validates_with_one_testcase_per_run(tmp_path: Path) -> None:
    """Passed runs are bare testcases, FAILURE a <failure>, ERROR and INFRA an <error>; XML escaped."""
    records = [record("ok"), record("failed", "FAILURE"), record("raised", "ERROR"), record("lost", "INFRA")]
    path = tmp_path / "junit.xml"
    write_junit(records, path, name="missiontree.batch.m")
    root = validate_junit(path)
    cases = {c.attrib["name"]: c for c in root.iter("testcase")}
    assert list(cases) == ["ok", "failed", "raised", "lost"]
    assert cases["ok"].find("failure") is None and cases["ok"].find("error") is None
    assert cases["failed"].find("failure").attrib["message"] == "because <FAILURE> & co"
    assert cases["raised"].find("error").attrib["type"] == "error"
    assert cases["lost"].find("error").attrib["type"] == "infrastructure"
    assert cases["ok"].attrib["classname"] == "missiontree.batch.m.office"


def test_the_junit_shape_check_catches_a_broken_file(tmp_path: Path) -> None:
    """The validator itself fails on a testcase without a name and on counts that disagree."""
    path = tmp_path / "bad.xml"
    path.write_text('<testsuites><testsuite name="s" tests="2"><testcase classname="c"/></testsuite>'
                    "</testsuites>")
    with pytest.raises(AssertionError):
        validate_junit(path)
    path.write_text('<testsuite name="s" tests="1" failures="1"><testcase name="x"/></testsuite>')
    with pytest.raises(AssertionError):
        validate_junit(path)


def test_results_jsonl_has_one_record_a_line_in_order(tmp_path: Path) -> None:
    """results.jsonl round-trips every field, no partial file left."""
    records = [record("b"), record("a", "FAILURE")]
    write_results(records, tmp_path / "results.jsonl")
    lines = [json.loads(line) for line in (tmp_path / "results.jsonl").read_text().splitlines()]
    assert [line["run_id"] for line in lines] == ["b", "a"]
    assert RunRecord(**lines[1]) == records[1]
    assert not list(tmp_path.glob("*.partial"))
