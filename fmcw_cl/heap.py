"""The host's heap between the steps of a conversion.

A conversion's host steps are numpy operations on arrays of a chunk's pairs (8 000 to
40 000 values, 64-320 kB each) and on its spectra (a few MB): their temporaries are
made and freed by the thousand. glibc's malloc serves those over 128 kB by mmap, or
gives the top of its heap back to the system once more than twice that is free, and
takes page faults for the memory again at the next allocation: the validity's test of
pairs 2 ms apart (`verification._kinematic`, 48 shifts of 40 000 pairs) took 94-97 ms so and
19-20 ms with freed memory kept (2-core EPYC, two runs). `keep_freed` keeps it, once a
process, where malloc is glibc's: arrays up to MMAP_BYTES from the heap, and up to
TRIM_BYTES of it free before any goes back.
"""

from __future__ import annotations

import ctypes
import functools
import sys

M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3     # mallopt's parameters (malloc.h)
MMAP_BYTES = 32 << 20         # glibc's largest dynamic threshold
TRIM_BYTES = 128 << 20


@functools.cache
def keep_freed() -> bool:
    """Have glibc's malloc keep freed memory for the next allocations (MMAP_BYTES,
    TRIM_BYTES); whether it was set (False on other systems and C libraries)."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = (ctypes.c_int, ctypes.c_int), ctypes.c_int
    return mallopt(M_MMAP_THRESHOLD, MMAP_BYTES) == 1 and mallopt(M_TRIM_THRESHOLD, TRIM_BYTES) == 1
