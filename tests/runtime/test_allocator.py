"""blendlib.runtime.allocator: glibc keeps freed arrays for reuse in processes that ask for it.

Each check runs in a fresh Python process: the allocator settings are per process, and the
test process's own must not depend on test order.
"""

from __future__ import annotations

import platform
import subprocess
import sys

import pytest

pytestmark = pytest.mark.skipif(platform.system() != "Linux" or platform.libc_ver()[0] != "glibc",
                                reason="glibc's allocator only")

# Frees a 16 MiB array, then prints the heap's free bytes (mallinfo2's fordblks) in MiB.
PROBE = """
import ctypes, sys
import numpy as np
from blendlib.runtime.allocator import keep_freed_memory
class MallInfo2(ctypes.Structure):
    _fields_ = [(n, ctypes.c_size_t) for n in ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks",
                                                 "fsmblks", "uordblks", "fordblks", "keepcost")]
libc = ctypes.CDLL(None)
libc.mallinfo2.restype = MallInfo2
took = keep_freed_memory() if sys.argv[1] == "keep" else None
array = np.ones(2 << 20)
del array
print(took, libc.mallinfo2().fordblks >> 20)
"""


def probe(mode: str) -> tuple[str, int]:
    out = subprocess.run([sys.executable, "-c", PROBE, mode], capture_output=True, text=True, check=True).stdout
    took, free_mib = out.split()
    return took, int(free_mib)


def test_freed_arrays_stay_in_the_heap_after_keep_freed_memory():
    took, kept = probe("keep")
    assert took == "True"
    assert kept >= 16  # the freed array is the heap's to reuse
    took, default = probe("default")
    assert took == "None"
    assert default < 16  # by default glibc unmaps it (a fresh array gets fresh zeroed pages)
