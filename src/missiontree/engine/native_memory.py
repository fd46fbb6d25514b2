"""Native heap settings for long runs: keep glibc's heap from growing by fragmentation.

glibc's malloc serves a large request (128 KiB and more) with its own ``mmap`` and gives it back
on ``free``, but each time such a block is freed it raises that threshold to the block's size
(up to 32 MiB). After the first big buffer of a run is freed (a map, a model answer), every camera
frame, depth image and numpy temporary of the run comes from the heap instead, between small
long-lived objects; the heap's top then only climbs and the free holes stay resident. Measured on
the two-hour soak (``benchmarks/soak.py``): the memory in use stayed within a few MiB while the
heap's free part grew from 4 to 19 MiB in an hour, which was most of the RSS growth. With the
threshold pinned at its initial 128 KiB, large buffers go back to the system on ``free`` and the
heap's free part stays near 1 MiB.

:func:`pin_mmap_threshold` does that once per process (``mallopt(M_MMAP_THRESHOLD, 128 KiB)``),
on glibc only, and leaves a threshold the user set (``MALLOC_MMAP_THRESHOLD_``) alone. The runner
calls it when a mission starts. Other C libraries (musl, macOS) are left as they are.
"""

from __future__ import annotations

import ctypes
import os
import sys

#: glibc's ``mallopt`` parameter number for the mmap threshold (malloc.h: ``M_MMAP_THRESHOLD``).
M_MMAP_THRESHOLD = -3
#: Requests of this size and more get their own mapping, returned to the system when freed.
MMAP_THRESHOLD = 128 * 1024
#: The environment variable through which a user sets glibc's threshold themselves.
USER_SETTING = "MALLOC_MMAP_THRESHOLD_"

_pinned: bool | None = None


def glibc_version() -> str | None:
    """The running glibc's version ("2.36"), or None on another C library or system."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        found = os.confstr("CS_GNU_LIBC_VERSION")
    except (ValueError, OSError, AttributeError):
        return None
    if not found or not found.startswith("glibc "):
        return None
    return found.split(" ", 1)[1]


def pin_mmap_threshold(threshold: int = MMAP_THRESHOLD) -> bool:
    """Pin glibc's mmap threshold (once per process); True when it is pinned by this call or an earlier one.

    Nothing is done (False) off glibc, or when the user set ``MALLOC_MMAP_THRESHOLD_`` (glibc then
    already uses their value, fixed).
    """
    global _pinned
    if _pinned is not None:
        return _pinned
    _pinned = False
    if os.environ.get(USER_SETTING) is not None or glibc_version() is None:
        return False
    try:
        libc = ctypes.CDLL("libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    mallopt.restype = ctypes.c_int
    _pinned = bool(mallopt(M_MMAP_THRESHOLD, int(threshold)))
    return _pinned
