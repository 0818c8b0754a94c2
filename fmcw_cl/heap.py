"""The host's heap between the steps of a conversion.

A conversion's host steps are numpy operations on arrays of a chunk's pairs (some 8 000
to 40 000 values, 64-320 kB each): their temporaries are made and freed by the
thousand. glibc's malloc gives the top of its heap back to the system whenever more
than 128 kB of it is free, and takes page faults for it again at the next allocation:
the validity's test of pairs 2 ms apart (`pairing._kinematic`, 48 shifts of 40 000
pairs) took 94-97 ms so and 19-20 ms with 64 MB of freed heap kept (2-core EPYC, two
runs). `keep_freed` keeps that much (M_TOP_PAD), once a process, where malloc is glibc's.
"""

from __future__ import annotations

import ctypes
import functools
import sys

M_TOP_PAD = -2                # mallopt's parameter (malloc.h)
TOP_PAD_BYTES = 64 << 20      # freed heap kept for the next allocations


@functools.cache
def keep_freed() -> bool:
    """Have glibc's malloc keep TOP_PAD_BYTES of freed heap instead of giving it back at
    each free; whether it was set (False on other systems and C libraries)."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = (ctypes.c_int, ctypes.c_int), ctypes.c_int
    return mallopt(M_TOP_PAD, TOP_PAD_BYTES) == 1
