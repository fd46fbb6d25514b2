"""The ``missiontree`` command line: one module per subcommand, listed in :mod:`missiontree.cli.main`.

Each subcommand module exposes ``register(subparsers)``, which adds its parser and sets
``func=run``, and ``run(args) -> int`` (the exit code). Shared helpers for subcommands live here.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from missiontree.plugins.manager import DISABLE_ENV, Plugins, load_plugins


def add_plugin_flag(parser: argparse.ArgumentParser) -> None:
    """Add ``--no-plugins`` (skip entry-point plugins; built-ins stay)."""
    parser.add_argument(
        "--no-plugins", action="store_true",
        help=f"do not load installed plugins (built-ins stay); same as {DISABLE_ENV}=1",
    )


def plugins_from_args(args: argparse.Namespace) -> Plugins:
    """Load plugins as the flags say (``--no-plugins`` wins over the environment)."""
    return load_plugins(autoload=False if getattr(args, "no_plugins", False) else None)


def print_json(data: Any) -> None:
    """Print ``data`` as indented JSON with sorted keys."""
    json.dump(data, sys.stdout, indent=2, sort_keys=True, ensure_ascii=False)
    sys.stdout.write("\n")
