"""Handing the allocator's free pages back to the system during a long drive.

A drive holds the same memory from one minute to the next (the soak benchmark,
``racecar-sim bench soak``), but glibc's allocator keeps the pages that the step's short-lived
arrays of changing sizes free in the middle of its heap, so the resident memory of a two-hour
drive crept up by ~110 bytes per step without anything being held. ``malloc_trim(0)`` returns
those pages; [run_one][mcl.experiments.runs.run_one] calls it once per simulated minute.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
import sys
from collections.abc import Callable

__all__ = ["TRIM_EVERY_S", "release_free_heap"]

TRIM_EVERY_S = 60.0
"""Simulated seconds between two calls of `release_free_heap()` in a drive."""


@functools.cache
def _malloc_trim() -> Callable[[int], int] | None:
    """glibc's ``malloc_trim``, or None where the C library has none (macOS, musl, Windows)."""
    if not sys.platform.startswith("linux"):
        return None
    name = ctypes.util.find_library("c")
    try:
        trim = ctypes.CDLL(name).malloc_trim if name else None
    except (OSError, AttributeError):
        return None
    if trim is not None:
        trim.argtypes = [ctypes.c_size_t]
        trim.restype = ctypes.c_int
    return trim


def release_free_heap() -> bool:
    """Return the C heap's free pages to the system (glibc's ``malloc_trim(0)``); returns whether
    the C library could (False, and nothing done, where it has no ``malloc_trim``)."""
    trim = _malloc_trim()
    if trim is None:
        return False
    trim(0)
    return True
