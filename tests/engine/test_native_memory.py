"""glibc's mmap threshold stays pinned: a big buffer freed does not send later ones into the heap."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from missiontree.engine import native_memory

pytestmark = pytest.mark.skipif(native_memory.glibc_version() is None, reason="glibc only")

#: Frees a 4 MiB block (glibc then raises its threshold to 4 MiB unless pinned), then asks for
#: 512 KiB and prints whether that block got its own mapping (mallinfo2's count of mmapped blocks).
_PROBE = """
import ctypes, os, sys
from missiontree.engine.native_memory import pin_mmap_threshold
class Info(ctypes.Structure):
    _fields_ = [(n, ctypes.c_size_t) for n in ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks",
                                              "fsmblks", "uordblks", "fordblks", "keepcost")]
libc = ctypes.CDLL("libc.so.6")
libc.mallinfo2.restype = Info
libc.malloc.restype = ctypes.c_void_p
libc.malloc.argtypes = [ctypes.c_size_t]
libc.free.argtypes = [ctypes.c_void_p]
pinned = pin_mmap_threshold() if sys.argv[1] == "pin" else False
libc.free(libc.malloc(4 << 20))
before = libc.mallinfo2().hblks
block = libc.malloc(512 << 10)
print(pinned, libc.mallinfo2().hblks - before)
libc.free(block)
"""


def _probe(mode: str, env: dict[str, str] | None = None) -> str:
    done = subprocess.run([sys.executable, "-c", _PROBE, mode], capture_output=True, text=True, timeout=60,
                          env=env, check=True)
    return done.stdout.strip()


def test_without_the_pin_a_freed_big_block_sends_later_buffers_into_the_heap() -> None:
    """The reference: glibc's dynamic threshold (what made the soak's heap grow)."""
    assert _probe("default") == "False 0"


def test_pinned_a_big_buffer_still_gets_its_own_mapping() -> None:
    assert _probe("pin") == "True 1"


def test_a_users_own_threshold_is_left_alone() -> None:
    env = {**os.environ, native_memory.USER_SETTING: str(8 << 20)}
    assert _probe("pin", env) == "False 0"  # their 8 MiB threshold holds: 512 KiB comes from the heap


def test_pinning_is_done_once_and_remembered() -> None:
    first = native_memory.pin_mmap_threshold()
    assert native_memory.pin_mmap_threshold() is first
