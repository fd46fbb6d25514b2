"""Entry point of the ``missiontree`` command: parses arguments and runs one subcommand.

Subcommands are the modules in :data:`SUBCOMMANDS` (append yours there); each exposes
``register(subparsers)`` and ``run(args) -> int``. Bad input (``ConfigError`` and its
``ProblemsError`` reports), a broken plugin or a missing extra print their message on stderr and
exit with code 2, without a traceback. A run stopped by signal N exits 128+N (130 for Ctrl-C/SIGINT,
143 for SIGTERM), the shell convention; Ctrl-C at any other moment (start-up included, see
:mod:`missiontree.__main__`) exits 130 with one line on stderr.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import sys
from collections.abc import Iterator, Sequence

from missiontree import __version__
from missiontree.errors import BackendUnavailableError, ConfigError, PluginError, ProblemsError
from missiontree.redact import SafeTerminal
from missiontree.startup import interrupted

#: Subcommand modules, in the order ``missiontree --help`` lists them.
SUBCOMMANDS: list[str] = [
    "missiontree.cli.run",
    "missiontree.cli.nodes",
    "missiontree.cli.plugins",
    "missiontree.cli.log",
    "missiontree.cli.validate",
    "missiontree.cli.world",
    "missiontree.cli.render",
    "missiontree.cli.schema",
    "missiontree.cli.models",
    "missiontree.cli.sim_ros",
    "missiontree.cli.view",
    "missiontree.cli.batch",
    "missiontree.cli.map",
    "missiontree.cli.bag",
]

EXIT_BAD_INPUT = 2
EXIT_INTERRUPTED = 130


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every subcommand registered."""
    parser = argparse.ArgumentParser(
        prog="missiontree",
        description="Behaviour-tree missions for mobile robots: run, check and inspect YAML missions.",
    )
    parser.add_argument("--version", action="version", version=f"missiontree {__version__}")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for module_name in SUBCOMMANDS:
        importlib.import_module(module_name).register(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the exit code."""
    try:
        parser = build_parser()
        args = parser.parse_args(argv)
        # a Ctrl-C during start-up whose KeyboardInterrupt an import swallowed (missiontree.startup)
        stopped = interrupted()
    except KeyboardInterrupt:  # Ctrl-C while the subcommands' modules are imported
        stopped = True
    if stopped:
        print("missiontree: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    from missiontree.session.process import tune_process  # loaded by the subcommands already

    tune_process()  # the process settings for long runs are the application's to set: here
    with safe_terminal():
        return _run(args)


@contextlib.contextmanager
def safe_terminal() -> Iterator[None]:
    """Send the command's stdout and stderr through :class:`~missiontree.redact.SafeTerminal`.

    The one place where text leaves for the terminal: secrets are scrubbed and the control
    characters of ids, labels and answers from files and models are shown escaped.
    """
    stdout, stderr = sys.stdout, sys.stderr
    safe_out, safe_err = SafeTerminal(stdout), SafeTerminal(stderr)
    sys.stdout, sys.stderr = safe_out, safe_err  # type: ignore[assignment]
    try:
        yield
    finally:
        sys.stdout, sys.stderr = stdout, stderr
        for safe in (safe_out, safe_err):
            with contextlib.suppress(OSError, ValueError):  # a closed pipe: nothing more to show
                safe.flush()


def _run(args: argparse.Namespace) -> int:
    """Run the parsed subcommand; errors of bad input become one line on stderr and exit 2."""
    try:
        return int(args.func(args))
    except ProblemsError as error:
        print(str(error), file=sys.stderr)
        count = len(error.problems)
        print(f"{count} problem{'s' if count != 1 else ''} found", file=sys.stderr)
        return EXIT_BAD_INPUT
    except (ConfigError, PluginError, BackendUnavailableError) as error:
        print(f"missiontree {args.command}: error: {error}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print(f"missiontree {args.command}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:  # output piped into `head` and the like
        sys.stderr.close()
        return 0
    except Exception:
        # a Ctrl-C during the command's own imports can surface as another error (a class body's
        # __set_name__ wraps it in a RuntimeError): with one recorded, it is the interrupt
        if interrupted():
            print(f"missiontree {args.command}: interrupted", file=sys.stderr)
            return EXIT_INTERRUPTED
        raise


if __name__ == "__main__":
    sys.exit(main())
