"""The one exception tree of missiontree.

Expected failures ("no path", "object not seen", "model said no") are *values*
(:class:`missiontree.robot.actions.ActionResult` with a reason), never exceptions.
Exceptions are for broken contracts and bad input::

    MissionTreeError
    ├── ConfigError (ValueError)            bad user input; the CLI exits with code 2
    │   ├── MissionFileError                a mission file failed checking (carries every Problem)
    │   ├── WorldFileError                  a simulator world or robot profile is broken
    │   └── ModelConfigError                a model provider is misconfigured (missing file, wrong shape)
    ├── PluginError                         a plugin failed to load or registered something broken
    ├── BackendError (RuntimeError)         a robot backend cannot do what was asked
    │   └── BackendUnavailableError (ImportError)  an extra is not installed (names the extra)
    └── ModelError (RuntimeError)           a model call failed (unreachable, rejected, malformed)
        ├── ModelTimeoutError (TimeoutError)
        └── ModelAnswerError (ValueError)   the answer failed schema or grounding checks

Every message says where, what was expected, what was found and how to fix it.
"""

from __future__ import annotations

from dataclasses import dataclass


class MissionTreeError(Exception):
    """Base of every error missiontree raises on purpose."""


class ConfigError(MissionTreeError, ValueError):
    """Bad user input: a file, a parameter or a flag. The CLI exits with code 2."""


@dataclass(frozen=True)
class Problem:
    """One problem found while checking a file.

    Attributes:
        file: Path of the file, as the user named it.
        line: 1-based line, 0 when unknown.
        col: 1-based column, 0 when unknown.
        path: Where in the document (node path such as ``root/Patrol[2]/Retry``), may be empty.
        message: What was expected and what was found.
        hint: How to fix it, may be empty.
    """

    file: str
    line: int
    col: int
    path: str
    message: str
    hint: str = ""

    def __str__(self) -> str:
        # no position is known (a missing file, a flag's value): name the file or flag alone, never 0:0
        where = self.file if self.line <= 0 else f"{self.file}:{self.line}"
        where += f":{self.col}" if self.line > 0 and self.col > 0 else ""
        path = _short_path(self.path)
        text = f"{where}: {path}: {self.message}" if path else f"{where}: {self.message}"
        return f"{text} (hint: {self.hint})" if self.hint else text


#: Longest node path segment shown in a problem; longer ones (a file read by mistake, a pasted
#: text as a key) are cut, so a problem never echoes a file's content back.
PATH_SEGMENT_CHARS = 60


def _short_path(path: str) -> str:
    parts = path.split("/")
    return "/".join(p if len(p) <= PATH_SEGMENT_CHARS else f"{p[:40]}… ({len(p):,} characters)"
                    for p in parts)


class ProblemsError(ConfigError):
    """A file failed checking; carries every problem found, not just the first."""

    def __init__(self, problems: list[Problem]) -> None:
        self.problems = list(problems)
        super().__init__("\n".join(str(p) for p in self.problems))


class MissionFileError(ProblemsError):
    """A mission file (or a subtree it includes) failed checking."""


class WorldFileError(ProblemsError):
    """A simulator world file or robot profile failed checking."""


class ModelConfigError(ConfigError):
    """A model provider is misconfigured: a missing file, a wrong output shape, a bad option."""


class PluginError(MissionTreeError):
    """A plugin failed to load or registered something broken."""


class BackendError(MissionTreeError, RuntimeError):
    """A robot backend cannot do what was asked (not an expected navigation failure)."""


class BackendUnavailableError(BackendError, ImportError):
    """A backend's extra is not installed; the message names the extra to install."""


class ModelError(MissionTreeError, RuntimeError):
    """A model call failed: server unreachable, key rejected, provider crashed."""


class ModelTimeoutError(ModelError, TimeoutError):
    """A model call did not answer within its timeout."""


class ModelAnswerError(ModelError, ValueError):
    """A model answered, but the answer failed schema or grounding checks."""
