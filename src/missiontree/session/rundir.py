"""Run directories: one run at a time, checked before the robot starts, no leftovers of older runs.

::

    claim = RunDirectory.claim(Path("runs/patrol"))   # ConfigError (exit 2) when it cannot be used
    ...                                                # the run writes ticks.jsonl, summary.json, ...
    claim.release()

:meth:`RunDirectory.claim`:

- refuses an empty path, a path that is a file, and a directory that cannot be created or written
  (read-only, a parent that is a file, no permission) with a :class:`~missiontree.errors.ConfigError`
  naming the path and the reason, never a traceback;
- takes the lock file ``run.lock`` (created exclusively, holding the owner's pid). A lock held by a
  live process is a ConfigError naming its pid; a stale lock (its pid is dead, or unreadable) is
  taken over. A lock this process already holds is accepted (the CLI claims before serving the
  live viewer, then the session claims again);
- clears an earlier run's files so none of them (alarms, pictures, maps) sits beside the new summary:
  a directory holding ``ticks.jsonl`` or ``summary.json`` is an earlier run's and every entry in it
  is removed; any other non-empty directory is refused (so ``--out ~`` never deletes your files).
"""

from __future__ import annotations

import contextlib
import os
import shutil
from pathlib import Path

from missiontree.errors import ConfigError

__all__ = ["LOCK_FILE", "RUN_MARKERS", "RunDirectory", "pid_alive"]

#: The lock file, holding the pid of the run that owns the directory.
LOCK_FILE = "run.lock"
#: Files that mark a directory as an earlier run's (its entries may be cleared).
RUN_MARKERS = ("ticks.jsonl", "summary.json")


def pid_alive(pid: int) -> bool:
    """True when a process with this pid exists (owned by anyone)."""
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's process
        return True
    except OSError:
        return False
    return True


def _reason(error: OSError) -> str:
    return error.strerror or type(error).__name__


class RunDirectory:
    """A run directory owned by this process (see the module docstring).

    Attributes:
        path: The directory.
        owned: True when this claim created the lock (and :meth:`release` removes it).
    """

    def __init__(self, path: Path, owned: bool) -> None:
        self.path = path
        self.owned = owned

    @classmethod
    def claim(cls, path: Path | str) -> RunDirectory:
        """Check, lock and clear ``path`` for a new run.

        Raises:
            ConfigError: Empty path, a file, not creatable or writable, locked by a live run, or a
                non-empty directory that holds no earlier run.
        """
        if str(path).strip() == "":
            raise ConfigError("--out: the run directory is an empty path; name a directory")
        path = Path(path)
        if path.exists() and not path.is_dir():
            raise ConfigError(f"--out {path} is a file, not a directory; give a directory for the run")
        try:
            path.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise ConfigError(f"cannot create the run directory {path}: {_reason(error)}") from error
        lock = path / LOCK_FILE
        for _attempt in range(3):
            try:
                fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                holder = cls._holder(lock)
                if holder == os.getpid():
                    return cls(path, owned=False)
                if holder is not None and pid_alive(holder):
                    raise ConfigError(
                        f"run directory {path} is in use by another run (pid {holder}, lock file {lock}); "
                        f"wait for it to end or choose another --out") from None
                with contextlib.suppress(FileNotFoundError):  # stale: its run died without releasing
                    lock.unlink()
                continue
            except OSError as error:
                raise ConfigError(f"cannot write in the run directory {path}: {_reason(error)}") from error
            try:
                os.write(fd, f"{os.getpid()}\n".encode())
            except OSError as error:
                os.close(fd)
                with contextlib.suppress(OSError):
                    lock.unlink()
                raise ConfigError(f"cannot write in the run directory {path}: {_reason(error)}") from error
            os.close(fd)
            if cls._holder(lock) != os.getpid():  # another run took over the same stale lock first
                continue
            claim = cls(path, owned=True)
            try:
                claim._clear()
            except BaseException:
                claim.release()
                raise
            return claim
        raise ConfigError(f"run directory {path}: could not take its lock file {lock}; try again")

    @staticmethod
    def _holder(lock: Path) -> int | None:
        """The pid written in the lock file (None when unreadable: a stale or half-written lock)."""
        try:
            return int(lock.read_text(encoding="utf-8").strip() or "x")
        except (OSError, ValueError):
            return None

    def _clear(self) -> None:
        entries = [entry for entry in self.path.iterdir() if entry.name != LOCK_FILE]
        if not entries:
            return
        if not any((self.path / name).exists() for name in RUN_MARKERS):
            raise ConfigError(
                f"--out {self.path} is not empty and holds no earlier run (no ticks.jsonl or summary.json); "
                f"choose a new or empty directory, so no file of yours is deleted")
        try:
            for entry in entries:
                if entry.is_dir() and not entry.is_symlink():
                    shutil.rmtree(entry)
                else:
                    entry.unlink()
        except OSError as error:
            raise ConfigError(f"cannot clear the earlier run's files in {self.path}: {_reason(error)} "
                              f"({error.filename})") from error

    def release(self) -> None:
        """Remove the lock when this claim created it and it still holds this process's pid."""
        if not self.owned:
            return
        self.owned = False
        lock = self.path / LOCK_FILE
        if self._holder(lock) == os.getpid():
            with contextlib.suppress(OSError):
                lock.unlink()
