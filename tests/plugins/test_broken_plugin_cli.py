"""A broken installed plugin names itself and does not take down unrelated commands (real CLI processes).

Two broken distributions are "installed" by putting their ``.dist-info`` folders on PYTHONPATH, as
pip would leave them in site-packages: one fails to import (an API it used was renamed), one raises
in its registration hook. Unrelated commands still run, say on stderr which plugin was left out and
how to fix it, and a mission that needs the broken plugin's node is refused with exit 2.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
MISSIONTREE = Path(sys.executable).parent / "missiontree"

CRASHY = '''\
from missiontree.engine.leaf import Leaf, Status
from missiontree.plugins.hookspecs import hookimpl


class Flicker(Leaf):
    """Never registered: the hook below fails first."""

    def update(self):
        return Status.SUCCESS


@hookimpl
def missiontree_register_nodes(registry):
    registry.add(Flicker)
    raise KeyError("FLICKER_RATE")
'''


def _dist(root: Path, name: str, module: str, source: str) -> None:
    info = root / f"{name.replace('-', '_')}-0.1.dist-info"  # as pip names it (normalised name)
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: 0.1\n", encoding="utf-8")
    (info / "entry_points.txt").write_text(f"[missiontree]\n{name.replace('-', '_')} = {module}\n",
                                           encoding="utf-8")
    (root / f"{module}.py").write_text(source, encoding="utf-8")


@pytest.fixture
def broken_env(tmp_path: Path) -> dict[str, str]:
    site = tmp_path / "site"
    _dist(site, "mt-renamed", "mt_renamed_plugin",
          'raise ImportError("cannot import name \'OldLeaf\' from \'missiontree.engine.leaf\'")\n')
    _dist(site, "mt-crashy", "mt_crashy_plugin", CRASHY)
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(site), env.get("PYTHONPATH", "")]))
    env.pop("MISSIONTREE_DISABLE_PLUGIN_AUTOLOAD", None)
    return env


def _run(env: dict[str, str], *args: str | Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(MISSIONTREE), *map(str, args)], cwd=REPO, env=env, capture_output=True,
                          text=True, timeout=300, check=False)


def test_unrelated_mission_runs_and_the_broken_plugins_are_named(broken_env: dict[str, str],
                                                                tmp_path: Path) -> None:
    done = _run(broken_env, "run", "trees/examples/timer_and_blackboard.yaml", "--out", tmp_path / "run")
    assert done.returncode == 0, done.stdout + done.stderr
    assert "SUCCESS" in done.stdout
    assert "warning" not in done.stdout  # stdout stays the command's own
    assert "plugin 'mt_renamed' (entry point 'mt_renamed_plugin' from distribution mt-renamed 0.1) " \
           "failed to import: ImportError" in done.stderr
    assert "pip uninstall mt-renamed" in done.stderr and "--no-plugins" in done.stderr
    assert "plugin 'mt_crashy' failed in missiontree_register_nodes: KeyError: 'FLICKER_RATE'" in done.stderr


def test_plugins_command_lists_the_broken_ones(broken_env: dict[str, str]) -> None:
    done = _run(broken_env, "plugins")
    assert done.returncode == 0, done.stderr
    assert "mt_renamed  (mt-renamed 0.1, BROKEN: left out)" in done.stdout
    assert "mt_crashy  (mt-crashy 0.1, BROKEN: left out)" in done.stdout
    assert "builtin  (missiontree.plugins.builtin, built in)" in done.stdout


def test_mission_needing_the_broken_plugin_is_refused_clearly(broken_env: dict[str, str],
                                                               tmp_path: Path) -> None:
    mission = tmp_path / "flicker.yaml"
    mission.write_text("version: 1\nroot:\n  Flicker: {}\n", encoding="utf-8")
    done = _run(broken_env, "validate", mission)
    assert done.returncode == 2
    assert "expected a known node type, found 'Flicker'" in done.stdout + done.stderr
    assert "plugin 'mt_crashy' failed in missiontree_register_nodes" in done.stderr
    assert "Traceback" not in done.stdout + done.stderr


def test_no_plugins_skips_them_silently(broken_env: dict[str, str], tmp_path: Path) -> None:
    done = _run(broken_env, "nodes", "--no-plugins", "Wait")
    assert done.returncode == 0 and "Wait  (leaf, from builtin)" in done.stdout
    assert "mt_renamed" not in done.stderr
