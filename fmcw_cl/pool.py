"""Int16 read buffers kept across captures in one process.

Memory the system hands out fresh costs its first touch: on the 2-core CI machine
reading a 0.3 s capture into new arrays took 110-430 ms against 17 ms into arrays
already touched, a quarter of the whole conversion. A capture borrows its chunk slots
here (`Capture.slot`) and returns them when closed, so that the captures of a batch,
and the repeated runs of a benchmark, read into memory that is already there (the
streaming engines of OCT allocate their buffers once the same way).

A GPU's processor has the pool hand out page-locked memory (`use`): its driver copies
such memory to the device by DMA without waiting, where pageable memory first goes
through a staging copy of the driver's own. Making it costs more still (on an H100's
host 25 ms per 80 MB slot: 1.1-1.2 s a batch of 8 captures when the plain limit let
slots go), so the pool keeps more of it (KEEP_PAGE_LOCKED_BYTES).
"""

from __future__ import annotations

import threading
from collections.abc import Callable

import numpy as np

LIMIT_BYTES = 1 << 30     # kept while unused, at most (the largest first)
# ... of page-locked memory: two captures at once (a GPU's batch) hold about 1 GB (each
# three read slots of 8192 periods, 82 MB a channel, and the trial stretches)
KEEP_PAGE_LOCKED_BYTES = 8 << 30

_free: list[np.ndarray] = []
_lock = threading.Lock()
_allocate: Callable[[int], np.ndarray] | None = None    # None: np.empty


def use(allocate: Callable[[int], np.ndarray] | None) -> None:
    """Make new arrays with `allocate(samples)`, page-locked memory (an int16 array of
    that many; it may raise MemoryError, and np.empty then makes it), or with np.empty
    (None). The kept arrays made otherwise are let go."""
    global _allocate
    with _lock:
        if allocate is not _allocate:
            _allocate = allocate
            _free.clear()


def _limit() -> int:
    """Bytes kept while unused under the allocator in use."""
    return LIMIT_BYTES if _allocate is None else max(LIMIT_BYTES, KEEP_PAGE_LOCKED_BYTES)


def lease(samples: int) -> np.ndarray:
    """An int16 array of at least `samples` (the smallest kept one that holds them, else
    a new one); `give` it back when done."""
    with _lock:
        fits = [i for i, a in enumerate(_free) if a.size >= samples]
        if fits:
            return _free.pop(min(fits, key=lambda i: _free[i].size))
        allocate = _allocate
    if allocate is not None:
        try:
            return allocate(samples)
        except MemoryError:
            pass
    return np.empty(samples, np.int16)


def give(array: np.ndarray) -> None:
    """Keep `array` for a later `lease` (nothing may use it any more); beyond
    LIMIT_BYTES (KEEP_PAGE_LOCKED_BYTES of page-locked memory) the smallest kept arrays
    are let go."""
    if not array.size:
        return
    with _lock:
        _free.append(array)
        _free.sort(key=lambda a: -a.size)
        total = 0
        for i, a in enumerate(_free):
            total += a.nbytes
            if total > _limit():
                del _free[i:]
                break


def clear() -> None:
    """Let every kept array go (its memory returns to the system)."""
    with _lock:
        _free.clear()
