"""Writing a file whole: a reader never sees half of it, and writers at once never mix their bytes.

The bytes go to a temporary file of the writer's own (a unique name beside the target) and are
renamed over the target, which POSIX makes atomic. Run directories, learned maps, scene graphs and
the evaluation's world files all go through :func:`write_whole`, so batch workers writing one
folder at once cannot collide on a shared temporary name.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

#: Permissions of a file written whole (a temporary file is created private, 0600).
FILE_MODE = 0o644


def write_whole(path: str | os.PathLike[str], payload: bytes) -> Path:
    """Replace ``path`` by ``payload`` in one rename (its folder is made if missing); return the path."""
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    temporary = Path(name)
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(payload)
        os.chmod(temporary, FILE_MODE)
        temporary.replace(target)
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise
    return target
