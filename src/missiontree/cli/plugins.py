"""``missiontree plugins``: which plugins are loaded and what each provides."""

from __future__ import annotations

import argparse
from dataclasses import asdict
from typing import Any

from missiontree.cli import add_plugin_flag, plugins_from_args, print_json
from missiontree.plugins.manager import DISABLE_ENV, autoload_enabled


def register(subparsers: Any) -> None:
    """Add the ``plugins`` subcommand."""
    parser = subparsers.add_parser(
        "plugins", help="list loaded plugins and what they provide",
        description="List the built-in plugin and every plugin installed under the entry point group "
        "'missiontree', with the node types, backends and model providers each registers.",
    )
    parser.add_argument("--json", action="store_true", help="print as JSON")
    add_plugin_flag(parser)
    parser.set_defaults(func=run)


def _names(label: str, names: list[str]) -> str:
    return f"    {label}: {', '.join(sorted(names))}" if names else f"    {label}: none"


def run(args: argparse.Namespace) -> int:
    """Print the plugins."""
    plugins = plugins_from_args(args)
    autoload = not args.no_plugins and autoload_enabled()
    if args.json:
        print_json({"autoload": autoload, "plugins": [asdict(p) for p in plugins.info],
                    "broken": [asdict(b) for b in plugins.broken]})
        return 0
    for plugin in plugins.info:
        origin = plugin.distribution or "built in"
        print(f"{plugin.name}  ({plugin.module}, {origin})")
        print(_names("nodes", plugin.nodes))
        print(_names("backends", plugin.backends))
        print(_names("providers", plugin.providers))
        if plugin.sensors:
            print(_names("sensors", plugin.sensors))
    for broken in plugins.broken:
        print(f"{broken.name}  ({broken.distribution or 'entry point'}, BROKEN: left out)")
        print(f"    {broken.error}")
    if not autoload:
        print(f"(installed plugins not loaded: --no-plugins or {DISABLE_ENV} is set)")
    return 0
