"""Where MRPT's sample datasets (Debian's ``mrpt-common``, BSD-3) are found on this machine.

One lookup for every reader, world source, test and benchmark that needs them, so an install
without root (``make setup-mrpt``: ``apt-get download mrpt-common`` + ``dpkg-deb -x``) is found
as an apt install is. The folders tried, in order:

1. ``$MISSIONTREE_MRPT_DATASETS`` when set (then only it);
2. ``/usr/share/mrpt/datasets`` and ``/usr/local/share/mrpt/datasets`` (apt, a source build);
3. the package extracted by ``make setup-mrpt`` into ``.cache/mrpt-common`` of the source
   checkout, or of the working folder (``<root>/.cache/mrpt-common/usr/share/mrpt/datasets``).
"""

from __future__ import annotations

import os
from pathlib import Path

#: Environment variable naming the folder that holds MRPT's datasets (overrides the others).
DATASETS_ENV = "MISSIONTREE_MRPT_DATASETS"
#: Where Debian's (and a source build's) ``mrpt-common`` puts the datasets.
SYSTEM_DIRS = (Path("/usr/share/mrpt/datasets"), Path("/usr/local/share/mrpt/datasets"))
#: Where ``make setup-mrpt`` extracts the package when it cannot install it, below a root folder.
EXTRACT_DIR = Path(".cache/mrpt-common")
#: The datasets folder inside an extracted ``mrpt-common`` package.
PACKAGE_DATASETS = Path("usr/share/mrpt/datasets")
#: The Debian package that ships them.
APT_PACKAGE = "mrpt-common"
INSTALL_HINT = (f"install Debian's {APT_PACKAGE} (apt-get install -y {APT_PACKAGE}, or `make setup-mrpt`, "
                f"which extracts it into {EXTRACT_DIR} without root) or set ${DATASETS_ENV} to a folder "
                "holding its datasets")
#: The source checkout this module runs from (src/missiontree/mapping/ -> the checkout).
SOURCE_ROOT = Path(__file__).resolve().parents[3]


def candidate_dirs() -> list[Path]:
    """The folders tried for the datasets, in order (see the module docstring)."""
    override = os.environ.get(DATASETS_ENV)
    if override:
        return [Path(override)]
    roots = [SOURCE_ROOT, Path.cwd()]
    extracted = [root / EXTRACT_DIR / PACKAGE_DATASETS for root in roots]
    return list(SYSTEM_DIRS) + list(dict.fromkeys(extracted))


def find_dataset(filename: str) -> Path | None:
    """The path of one dataset file (e.g. ``tests_rgbd.rawlog``) in the first folder holding it, else None."""
    for folder in candidate_dirs():
        path = folder / filename
        if path.exists():
            return path.resolve()
    return None


def dataset_path(filename: str) -> Path:
    """As :func:`find_dataset`, but a missing file is an error.

    Raises:
        FileNotFoundError: No folder holds the file (the message names the folders and the package).
    """
    path = find_dataset(filename)
    if path is None:
        looked = ", ".join(str(c) for c in candidate_dirs())
        raise FileNotFoundError(f"MRPT's {filename} is not installed (looked in {looked}): {INSTALL_HINT}")
    return path


def missing_reason(filename: str) -> str:
    """Why a test needing ``filename`` skips: the folders looked in and how to install it."""
    looked = ", ".join(str(c) for c in candidate_dirs())
    return f"needs MRPT's {filename} (Debian's {APT_PACKAGE}); not in {looked}: {INSTALL_HINT}"
