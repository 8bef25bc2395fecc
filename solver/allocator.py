"""The C allocator keeps the memory a command frees, for the next array of the command (units: bytes).

A command's batched kinematics allocate and free arrays of tens to hundreds of MiB thousands of times (the
hexapod's simulated calibrations: full Jacobians of 2,592 configurations, 175 MiB each).  glibc's ``malloc``
serves every block above its mmap threshold (at most 32 MiB) with a fresh ``mmap`` and returns it with
``munmap`` when freed, and gives the top of its heap back to the system above 128 KiB free: every such array
is then zero-filled again by the kernel, page by page (a page fault each 4 KiB).  On the hexapod's
``accuracy`` that was 2.2-2.7 s of *system* CPU out of 19-20 s.  :func:`keep_freed_memory` tells glibc
(``mallopt``) to serve large blocks from its heap and to keep what is freed there, so the next array reuses
pages that are already mapped: the same computations, the same bits, less system time.  It is set by the
``hyperstat`` command only (its process ends with the command), not when the Python API (``hyperstat.report``)
runs a command inside a user's own process.

The peak resident memory can grow where a freed block is too small for the next one (measured: +23 MiB on the
hexapod's 720 MiB); the heap's untouched top pad costs address space, not memory.  ``HYPERSTAT_KEEP_MEMORY=0``
leaves the allocator as it is; other C libraries than glibc (no ``mallopt``) are left as they are.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import sys

__all__ = ["keep_freed_memory"]

#: mallopt's parameters (glibc's malloc.h)
_M_TRIM_THRESHOLD, _M_TOP_PAD, _M_MMAP_THRESHOLD = -1, -2, -3
#: blocks below this come from the heap (bytes): larger than any array of a command
MMAP_THRESHOLD = 1 << 30
#: free memory at the top of the heap kept (bytes)
TRIM_THRESHOLD = 4 << 30
#: extra address space requested each time the heap grows (bytes; touched only when used)
TOP_PAD = 256 << 20

_done = False


def keep_freed_memory() -> bool:
    """Set glibc's allocator to keep freed memory for reuse (once per process); whether it was set.

    The ``hyperstat`` command calls it first thing (``tests/solver/test_allocator.py`` runs it in a child: the
    setting stays with the process that made it).

    Examples
    --------
    >>> MMAP_THRESHOLD // 2**20, TRIM_THRESHOLD // 2**20, TOP_PAD // 2**20  # MiB
    (1024, 4096, 256)
    """
    global _done
    if _done:
        return True
    if os.environ.get("HYPERSTAT_KEEP_MEMORY", "1").strip() == "0" or not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):  # not glibc
        return False
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    # the thresholds first: setting one turns off glibc's own adjustment of both
    _done = bool(mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD) and mallopt(_M_TRIM_THRESHOLD, min(TRIM_THRESHOLD, 2**31 - 1))
                 and mallopt(_M_TOP_PAD, TOP_PAD))
    return _done
