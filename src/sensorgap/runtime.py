"""Process-wide runtime settings of the command-line tool and the benchmarks.

``tune_allocator``: the search evaluates batches as (B, T) float64 arrays of about 1.6 MB
each, allocated and freed thousands of times per second on two threads. glibc's malloc
serves blocks of that size with ``mmap`` and gives freed memory back to the kernel, so
every batch pays fresh page faults, which serialise the threads in the kernel's memory
map: measured on this project's 2-core machine, two threads evaluated candidates only
1.4x as fast as one. Keeping such blocks on the heap (mmap threshold 32 MiB, trim threshold
1 GiB, top pad 64 MiB; ``mallopt(3)``) brings that to 1.7-1.8x and changes no result. The
price: freed memory stays with the process (its resident size stays near its peak) until
it exits. Not glibc (macOS, musl, Windows): nothing is changed.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import sys

#: mallopt parameters (glibc <malloc.h>) and the values set, bytes.
_M_TRIM_THRESHOLD, _M_TOP_PAD, _M_MMAP_THRESHOLD = -1, -2, -3
MMAP_THRESHOLD_B = 32 * 1024 * 1024
TRIM_THRESHOLD_B = 1 << 30
TOP_PAD_B = 64 * 1024 * 1024

_done: bool | None = None


def tune_allocator() -> bool:
    """Apply the allocator settings above once per process (glibc only); True if set."""
    global _done
    if _done is not None:
        return _done
    _done = False
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):  # not glibc
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    mallopt.restype = ctypes.c_int
    _done = bool(mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD_B)
                 and mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD_B)
                 and mallopt(_M_TOP_PAD, TOP_PAD_B))
    return _done
