r"""Every example ``missiontree`` command of the README, docs/*.md and the trees' headers runs as written.

What counts as an example command:

- in README.md and docs/*.md, a line of a fenced code block that starts with ``missiontree`` or
  ``.venv/bin/missiontree`` (or pipes into one, ``printf ... | missiontree ...``), joined with its
  ``\\`` continuation lines. Commands named inside prose (`` `missiontree run` ``, ``missiontree run
  M --set name=value``) are mentions of a subcommand or templates, not examples, and are left out;
- in trees/*.yaml and trees/examples/*.yaml, an indented line of the leading comment block that
  reads so (``#   missiontree run trees/patrol.yaml``; prose that begins a line with the word
  missiontree is not indented).

A trailing ``# comment`` is dropped. Each command runs with bash in a scratch directory that holds
links to the repository's ``trees``, ``config``, ``plugins``, ``tests`` (the recorded data the
docs read, e.g. ``tests/data/ros2bag/sim_office.mcap``) and ``.venv`` (so the paths read as
written and every ``runs/...`` the command writes lands in the scratch directory), ``HOME`` pointing
into it (``--out ~/patrol.html``) and the venv's ``bin`` first on ``PATH`` (as after activating
``.venv``). A command that reads an earlier run's directory (``log summarize runs/patrol``,
``--set scene_graph=runs/map_scene/scene_graph.json``) first runs the documented command that
writes it. The same command written in several places runs once. It must exit 0; a command that
fails because of the code (not the docs) is listed in :data:`KNOWN_FAILURES` with what goes wrong,
runs, and is reported as xfail until fixed.

Cost: about 5.5 minutes of CPU for the whole file (some 50 runs after de-duplication, the missions
taking 2-25 s of CPU each), so about 5-6 minutes of wall time on an idle 2-core machine (the runs
go one after another); ``-m "not docs"`` leaves it out of a quick run.

Skipped, by the rules in :data:`SKIP_RULES` (the reason is the skip message): commands for a ROS 2
robot or ``missiontree sim-ros`` (a robot, or a server that runs until Ctrl-C), ``bag record`` (a
running ROS 2 robot over DDS), ``--models
openai`` (OpenAI's API: a key and the network), a Dask scheduler's address, ``view --follow`` (a
server until Ctrl-C), and templates a user fills in (``MISSION.yaml``, ``/path/to/...``,
``path/to/...``, ``HOST``, ``"..."``).

Long commands (:data:`LONG_RULES`) run with ``--max-duration`` appended: the README's batch is 20
patrols (about 3 minutes of two idle cores); capped at 20 s of robot clock each, it still checks its
command line, its sweep and its junit.xml, and may exit 1 (capped patrols end unfinished) but not 2
(bad input) or 3 (a crash).
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
import yaml

pytestmark = pytest.mark.docs

ROOT = Path(__file__).resolve().parents[2]
#: Links made in the scratch directory so that the documented paths resolve.
LINKED = ("trees", "config", "plugins", "tests")
#: A documented command line: starts with missiontree (bare or from .venv/bin), or pipes into it.
_COMMAND = re.compile(r"^(?:printf\s.*\|\s*)?(?:[A-Z_]+=\S+\s+)*(?:\.venv/bin/)?missiontree\s")
#: (pattern, why the command cannot run here); the first rule that matches skips it.
SKIP_RULES: tuple[tuple[str, str], ...] = (
    (r"--backend ros2", "needs a ROS 2 robot (Nav2) or `missiontree sim-ros` in another terminal"),
    (r"\bmissiontree sim-ros\b", "serves the simulator over ROS 2 until Ctrl-C"),
    (r"\bmissiontree bag record\b", "records from a running ROS 2 robot over DDS (the ros2 extra, rclpy)"),
    (r"--models openai", "calls OpenAI's API (needs a key and the network)"),
    (r"--dask tcp://", "needs a running Dask scheduler at the user's address"),
    (r"\bview --follow\b", "serves the viewer until Ctrl-C"),
    (r"MISSION\.yaml|/path/to/|\bpath/to/|\bHOST\b|\"\.\.\.\"|<[a-z ]+>",
     "a template: the user substitutes a file, path, host or text"),
) + (() if Path("/usr/share/mrpt/datasets").is_dir() else (
    (r"/usr/share/mrpt/", "needs MRPT's datasets (Debian's mrpt-common; `make setup-mrpt` installs them)"),))
#: (pattern, --max-duration seconds, exit codes accepted) for commands too long to run whole.
LONG_RULES: tuple[tuple[str, int, tuple[int, ...]], ...] = (
    (r"\bmissiontree batch\b", 20, (0, 1)),
)
#: Documented commands that end FAILURE because of the code, not the docs (command -> what goes
#: wrong); each runs and is reported as xfail until the code is fixed (then XPASS: remove it here).
KNOWN_FAILURES: dict[str, str] = {
    'missiontree run trees/examples/report_search.yaml --set target="red backpack"':
        "the report's method (as the report describes it) ends FAILURE in the office after three rounds: "
        "the red backpack lies 6 m from the centre of the largest region its scan points reach",
    'printf "I\'m tired\\nthe grey backpack\\n" | missiontree run trees/map_and_go_to_intent.yaml':
        "after mapping, 'the grey backpack' fails: its standoff goal (6.83, 1.23) lies within the robot "
        "radius of an obstacle on the learned map (twice, 1184 and 1185 ticks); go_to_intent.yaml on the "
        "known map serves the same commands",
}
#: Wall-clock limit of one command (the CI machine may be loaded).
TIMEOUT_S = 1800


@dataclass(frozen=True)
class DocCommand:
    """One documented command and where it is written."""

    source: str      # file:line, relative to the repository
    text: str        # the command as written, comment dropped, continuations joined

    @property
    def key(self) -> str:
        """The command with ``.venv/bin/`` dropped and spaces collapsed: one run for the same command."""
        return " ".join(self.text.replace(".venv/bin/missiontree", "missiontree").split())


def _drop_comment(line: str) -> str:
    """``line`` without a trailing ``# comment`` (a ``#`` inside quotes stays)."""
    quote = ""
    for i, ch in enumerate(line):
        if quote:
            quote = "" if ch == quote else quote
        elif ch in "'\"":
            quote = ch
        elif ch == "#" and (i == 0 or line[i - 1].isspace()):
            return line[:i].rstrip()
    return line.rstrip()


def _joined(lines: list[tuple[int, str]]) -> Iterator[tuple[int, str]]:
    """Commands from (line number, text) pairs, with backslash continuations joined."""
    start, parts = 0, list[str]()
    for number, text in lines:
        text = _drop_comment(text)
        if not parts:
            if not _COMMAND.match(text.strip()):
                continue
            start = number
        if text.endswith("\\"):
            parts.append(text[:-1].strip())
            continue
        parts.append(text.strip())
        yield start, " ".join(parts)
        parts = []


def markdown_commands(path: Path) -> list[DocCommand]:
    """The commands in the fenced code blocks of a markdown file."""
    inside, lines = False, []
    for number, text in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        if text.lstrip().startswith("```"):
            inside = not inside
            continue
        if inside:
            lines.append((number, text.strip()))
        else:
            lines.append((number, ""))   # a block's end ends a continuation
    rel = path.relative_to(ROOT)
    return [DocCommand(f"{rel}:{n}", text) for n, text in _joined(lines)]


def tree_header_commands(path: Path) -> list[DocCommand]:
    """The commands in the leading comment block of a tree file."""
    lines = []
    for number, text in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        if not text.startswith("#"):
            break
        body = text[1:]
        # an example is indented in the comment (`#   missiontree run ...`); prose is not
        lines.append((number, body.strip() if body.startswith("  ") else ""))
    rel = path.relative_to(ROOT)
    return [DocCommand(f"{rel}:{n}", text) for n, text in _joined(lines)]


def all_commands() -> list[DocCommand]:
    """Every documented command, README first, then docs/ and the trees in name order."""
    found = markdown_commands(ROOT / "README.md")
    for page in sorted((ROOT / "docs").glob("*.md")):
        found += markdown_commands(page)
    trees = sorted((ROOT / "trees").glob("*.yaml")) + sorted((ROOT / "trees" / "examples").glob("*.yaml"))
    for tree in trees:
        found += tree_header_commands(tree)
    return found


COMMANDS = all_commands()


def skip_reason(command: DocCommand) -> str | None:
    """Why ``command`` cannot run in CI, or None."""
    for pattern, why in SKIP_RULES:
        if re.search(pattern, command.text):
            return why
    return None


def _words(command: str) -> list[str]:
    return shlex.split(command.split("|")[-1])


def run_dir_written(command: str) -> str | None:
    """The run directory a ``missiontree run`` writes (its ``--out``, else ``runs/<tree stem>``)."""
    words = _words(command)
    if "run" not in words:
        return None
    after = words[words.index("run") + 1:]
    if "--out" in after:
        return after[after.index("--out") + 1].rstrip("/")
    trees = [w for w in after if w.endswith((".yaml", ".yml"))]
    return f"runs/{Path(trees[0]).stem}" if trees else None


def run_dirs_read(command: str) -> list[str]:
    """Earlier runs' directories the command reads (``runs/x`` or ``runs/x/file``), not the one it writes."""
    written = run_dir_written(command)
    read = []
    for word in _words(command):
        value = word.split("=", 1)[-1]
        match = re.match(r"(runs/[^/\s]+)", value)
        if match and match.group(1) != written:
            read.append(match.group(1))
    return read


class Workspace:
    """The scratch directory the commands run in, and each command's result (one run per command)."""

    def __init__(self, base: Path) -> None:
        self.base = base
        for name in LINKED:
            (base / name).symlink_to(ROOT / name)
        (base / ".venv").symlink_to(Path(sys.prefix))
        (base / "home").mkdir()
        self.results: dict[str, subprocess.CompletedProcess[str]] = {}
        bin_dir = str(Path(sys.executable).parent)
        self.env = {**os.environ, "HOME": str(base / "home"),
                    "PATH": bin_dir + os.pathsep + os.environ.get("PATH", "")}

    def run(self, command: DocCommand) -> subprocess.CompletedProcess[str]:
        """Run ``command`` (after the commands writing the runs it reads), once per command."""
        if command.key in self.results:
            return self.results[command.key]
        for needed in run_dirs_read(command.text):
            if not (self.base / needed).exists():
                producer = next((c for c in COMMANDS if run_dir_written(c.text) == needed
                                 and skip_reason(c) is None), None)
                if producer is not None:
                    self.run(producer)
        text = command.text
        for pattern, seconds, _ in LONG_RULES:
            if re.search(pattern, text):
                text = f"{text} --max-duration {seconds}"
        result = subprocess.run(["bash", "-c", text], cwd=self.base, env=self.env, capture_output=True,
                                text=True, timeout=TIMEOUT_S, stdin=subprocess.DEVNULL, check=False)
        self.results[command.key] = result
        return result

    def summary(self, command: DocCommand) -> str:
        """``missiontree log summarize`` of the run the command wrote (why it failed), or nothing."""
        run_dir = run_dir_written(command.text)
        if run_dir is None or not (self.base / run_dir / "ticks.jsonl").is_file():
            return ""
        found = subprocess.run(["missiontree", "log", "summarize", run_dir], cwd=self.base, env=self.env,
                               capture_output=True, text=True, timeout=300, check=False)
        return "\n" + "\n".join(found.stdout.splitlines()[:20])


@pytest.fixture(scope="module")
def workspace(tmp_path_factory: pytest.TempPathFactory) -> Workspace:
    """One scratch directory for all the commands, so a later command reads an earlier one's run."""
    return Workspace(tmp_path_factory.mktemp("doc_commands"))


def test_commands_are_found() -> None:
    """The extraction finds the documented commands of each kind of source (a broken extractor fails here)."""
    sources = {c.source.split(":")[0] for c in COMMANDS}
    assert "README.md" in sources and "trees/patrol.yaml" in sources and "docs/patrol.md" in sources
    texts = {c.key for c in COMMANDS}
    assert "missiontree run trees/patrol.yaml" in texts
    assert any(t.startswith("printf ") for t in texts)          # a piped command
    assert any("--max-duration 1800" in t for t in texts)       # a continuation line joined


def test_extraction_rules() -> None:
    """A comment is dropped (a # in quotes stays); continuations join; a YAML line is no command."""
    kept = 'missiontree run t.yaml --set c="#1"'
    assert _drop_comment(kept + "   # note") == kept
    lines = [(1, "missiontree run a.yaml \\"), (2, "  --out runs/x"), (3, "run:   # `missiontree run`"),
             (4, "printf 'a\\n' | .venv/bin/missiontree run b.yaml")]
    assert list(_joined(lines)) == [(1, "missiontree run a.yaml --out runs/x"),
                                    (4, "printf 'a\\n' | .venv/bin/missiontree run b.yaml")]
    assert run_dir_written("missiontree run trees/explore.yaml --out runs/explore7") == "runs/explore7"
    assert run_dirs_read("missiontree run trees/go_to_intent.yaml --set scene_graph=runs/map_scene/g.json") \
        == ["runs/map_scene"]


def test_skip_rules_and_known_failures_are_not_stale() -> None:
    """Each skip rule and known failure matches a documented command (one nothing needs is stale)."""
    for pattern, why in SKIP_RULES:
        assert any(re.search(pattern, c.text) for c in COMMANDS), f"no command needs the rule {why!r}"
    keys = {c.key for c in COMMANDS}
    assert set(KNOWN_FAILURES) <= keys, f"known failures no doc writes: {set(KNOWN_FAILURES) - keys}"


@pytest.mark.parametrize("command", COMMANDS, ids=[c.source for c in COMMANDS])
def test_documented_command_runs(command: DocCommand, workspace: Workspace) -> None:
    """The documented command exits 0 (a long one capped as LONG_RULES says) or is skipped by a named rule."""
    why = skip_reason(command)
    if why is not None:
        pytest.skip(f"{command.text}: {why}")
    accepted: tuple[int, ...] = (0,)
    for pattern, _, codes in LONG_RULES:
        if re.search(pattern, command.text):
            accepted = codes
    result = workspace.run(command)
    known = KNOWN_FAILURES.get(command.key)
    if known is not None and result.returncode not in accepted:
        pytest.xfail(f"{command.source}: {known}")
    tail = "\n".join((result.stdout + result.stderr).splitlines()[-15:])
    if result.returncode not in accepted:
        tail += workspace.summary(command)
    assert result.returncode in accepted, (f"{command.source}: `{command.text}` exited {result.returncode}:\n"
                                           f"{tail}")
    assert "Traceback (most recent call last)" not in result.stderr, tail


def test_documented_runs_name_real_trees() -> None:
    """Every tree a documented run names exists and is a YAML mapping (a renamed tree fails here, fast)."""
    for command in COMMANDS:
        if skip_reason(command) is not None:
            continue
        for word in _words(command.text):
            local = "/" in word and not word.startswith(("runs/", "~", "/")) and "*" not in word
            if word.endswith(".yaml") and local:
                path = ROOT / word
                assert path.is_file(), f"{command.source}: {word} does not exist"
                assert isinstance(yaml.safe_load(path.read_text(encoding="utf-8")), dict), word


def test_the_bag_commands_in_the_docs_run() -> None:
    """The documented bag commands (bag info, a run on a bag, map convert of one) run in CI as written."""
    bag = [c for c in COMMANDS if c.source.startswith("docs/real-data.md") and ".mcap" in c.text]
    runnable = [c for c in bag if skip_reason(c) is None]
    assert {w for c in runnable for w in _words(c.text)} >= {"info", "run", "convert"}
    assert all("bag record" in c.text for c in bag if c not in runnable)
