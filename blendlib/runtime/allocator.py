"""Keep freed memory in the process: glibc's allocator settings for processes this project runs.

A render allocates the same large arrays chunk after chunk and frame after frame. glibc's
``malloc`` by default serves arrays over its (adaptive, 128 KiB to 32 MiB) mmap threshold
with fresh mappings and gives freed memory at the top of the heap back to the system beyond
its trim threshold; either way the next allocation gets fresh pages, which the kernel must
zero on first touch: in a process that also extracts scenes and renders other frames between
viewport frames, that zeroing was a large part of a viewport frame's time (docs/benchmark.md,
"Why the constants are what they are"). Blender's own Linux build links jemalloc, which keeps
freed pages for reuse anyway; the ``bpy`` module from PyPI and a plain Python use glibc.

:func:`keep_freed_memory` is for processes this project owns (the band helper, the command
line, the benchmark's workers); the library never changes the allocator of a process that
imports it.
"""

from __future__ import annotations

import ctypes
import platform

#: mallopt parameter numbers (glibc's malloc.h).
_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3

#: Arrays below this many bytes come from the heap (glibc's largest adaptive threshold).
MMAP_THRESHOLD = 32 << 20
#: Free memory at the top of the heap kept before any is given back.
TRIM_THRESHOLD = 1 << 30


def _glibc():
    """This process's C library when it is glibc (the functions below are glibc's), else None."""
    if platform.system() != "Linux" or platform.libc_ver()[0] != "glibc":
        return None
    try:
        return ctypes.CDLL(None)
    except OSError:
        return None


def keep_freed_memory() -> bool:
    """Make glibc keep freed memory for reuse (:data:`MMAP_THRESHOLD`, :data:`TRIM_THRESHOLD`).

    Returns whether the settings took (False on other C libraries, where nothing changes).
    Call it early in a process this project owns, before large allocations.
    """
    mallopt = getattr(_glibc(), "mallopt", None)
    if mallopt is None:
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    mallopt.restype = ctypes.c_int
    return bool(mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD)) and bool(mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD))


def give_back_freed_memory() -> bool:
    """Return the heap's free memory to the system now (glibc's ``malloc_trim(0)``), e.g. when a
    process that keeps freed memory (:func:`keep_freed_memory`) goes idle. Returns whether glibc
    gave any back (False on other C libraries, where nothing happens)."""
    trim = getattr(_glibc(), "malloc_trim", None)
    if trim is None:
        return False
    trim.argtypes = (ctypes.c_size_t,)
    trim.restype = ctypes.c_int
    return bool(trim(0))
