"""The ``missiontree`` command's entry point (also ``python -m missiontree``).

It imports the command line inside a guard, so Ctrl-C while the (heavy) imports run ends the
command with exit code 130 and one line on stderr, never a KeyboardInterrupt traceback; from then
on :func:`missiontree.cli.main.main` handles signals and exit codes.
"""

from __future__ import annotations

import sys

EXIT_INTERRUPTED = 130  # 128 + SIGINT


def main() -> int:
    """Import and run the command line; Ctrl-C during start-up exits 130 quietly."""
    try:
        from missiontree.startup import guard

        guard()  # a Ctrl-C an import swallows is still seen: cli.main checks once start-up is over
        from missiontree.cli.main import main as cli_main
    except KeyboardInterrupt:
        print("missiontree: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    return cli_main()


if __name__ == "__main__":
    sys.exit(main())
