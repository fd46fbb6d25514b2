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
    except Exception as error:
        # a Ctrl-C inside a class body of an imported module comes out as another error (a
        # RuntimeError from __set_name__): with one recorded, or one behind it, it is the interrupt
        if _interrupted() or _behind(error):
            print("missiontree: interrupted", file=sys.stderr)
            return EXIT_INTERRUPTED
        raise
    return cli_main()


def _interrupted() -> bool:
    """Whether start-up recorded a Ctrl-C (False when the recorder itself was not imported yet)."""
    startup = sys.modules.get("missiontree.startup")
    return startup is not None and bool(startup.interrupted())


def _behind(error: BaseException) -> bool:
    """Whether a KeyboardInterrupt caused ``error`` (one arriving before the guard was in place)."""
    seen: set[int] = set()
    cause: BaseException | None = error
    while cause is not None and id(cause) not in seen:
        if isinstance(cause, KeyboardInterrupt):
            return True
        seen.add(id(cause))
        cause = cause.__cause__ or cause.__context__
    return False


if __name__ == "__main__":
    sys.exit(main())
