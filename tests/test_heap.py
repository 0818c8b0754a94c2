"""fmcw_cl.heap: the freed heap kept for the next allocations (glibc)."""

from __future__ import annotations

import subprocess
import sys

import pytest

CHURN = """
import ctypes, sys
import numpy as np
from fmcw_cl import heap
if sys.argv[1] == "keep":
    assert heap.keep_freed()
else:       # glibc's initial thresholds (its dynamic ones follow what the imports freed)
    mallopt = ctypes.CDLL(None).mallopt
    assert mallopt(heap.M_MMAP_THRESHOLD, 128 << 10) == 1 and mallopt(heap.M_TRIM_THRESHOLD, 128 << 10) == 1

class Info(ctypes.Structure):                 # glibc's struct mallinfo2
    _fields_ = [(k, ctypes.c_size_t) for k in ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks",
                                               "fsmblks", "uordblks", "fordblks", "keepcost")]

mallinfo2 = ctypes.CDLL(None).mallinfo2
mallinfo2.restype = Info
arrays = [np.ones(n) for n in (12_000, 40_000) for _ in range(150)]   # 96 and 320 kB: 53 MB
del arrays
print(mallinfo2().fordblks)
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's malloc")
def test_freed_heap_is_kept_for_the_next_allocations():
    """With glibc's initial thresholds, arrays over 128 kB are mmapped and the freed top
    of the heap goes back at once (the next chunk's temporaries take page faults
    again); with keep_freed, the process keeps it."""
    free = {}
    for mode in ("default", "keep"):
        run = subprocess.run([sys.executable, "-c", CHURN, mode], capture_output=True, text=True, check=False)
        if run.returncode and "mallinfo2" in run.stderr:
            pytest.skip("no glibc mallinfo2 here")
        assert run.returncode == 0, run.stderr
        free[mode] = int(run.stdout)
    assert free["default"] < 8 << 20
    assert free["keep"] > 48 << 20
