"""Keep freed heap memory in the process, so per-set buffers are not page-faulted in again.

Fusing and rendering one ring5 set allocates and frees some 30 MB in buffers of 0.2-6 MB. With
glibc's defaults those are mmap'ed or trimmed back to the kernel when freed, and the next set
faults them in again page by page: measured here, ~730 minor page faults and 2-4 ms of a
128 px render (of ~7 ms) per set, against ~25 faults once freed memory stays in the heap.
The perception node and ``actaim2 bench perception`` (both of its paths, old and new renderer)
call :func:`keep_freed_memory` once at start; the heap then stays at its peak size.
"""
from __future__ import annotations

import ctypes
import ctypes.util

M_TRIM_THRESHOLD = -1  # glibc mallopt parameters (malloc.h)
M_MMAP_THRESHOLD = -3
MMAP_THRESHOLD = 32 * 2**20  # glibc's largest allowed value: buffers below it come from the heap
TRIM_THRESHOLD = 256 * 2**20  # free heap kept before any is returned to the kernel


def keep_freed_memory() -> bool:
    """Raise glibc's mmap and trim thresholds; False where the C library has no ``mallopt``."""
    name = ctypes.util.find_library("c")
    mallopt = getattr(ctypes.CDLL(name), "mallopt", None) if name else None
    if mallopt is None:
        return False
    return bool(mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD)) and bool(mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD))
