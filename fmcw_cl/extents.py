"""Where a raw int16 channel's samples lie in its HDF5 file, for reads straight from it.

h5py's `read_direct` copies a chunked dataset through HDF5's own buffers; where the
samples are stored as they are (no filter, little-endian int16, every chunk written),
one `preadv` per chunk into the destination moves each byte once: about half the CPU
time (the 0.3 s jump's two channels: 21-25 against 42-53 ms here). Any other layout
(compressed, big-endian, a user block, unwritten chunks, external or virtual storage,
no `preadv`) has no extents and is read through h5py, as every capture written to the
contract can be.
"""

from __future__ import annotations

import contextlib
import mmap
import os
import sys
import threading
from concurrent.futures import ThreadPoolExecutor, wait

import h5py
import numpy as np

ITEM = 2    # bytes a sample
PIECE_BYTES = 8 << 20       # a read of several such pieces is shared by threads ...
READERS = min(4, os.cpu_count() or 1)      # ... this many: one thread's copies from the
                                           # page cache fall well short of the memory's speed

_readers: ThreadPoolExecutor | None = None
_readers_lock = threading.Lock()


def _pool() -> ThreadPoolExecutor:
    global _readers
    with _readers_lock:
        if _readers is None:
            _readers = ThreadPoolExecutor(READERS, thread_name_prefix="fmcw-read")
        return _readers


class Extents:
    """File byte offsets of a 1-D int16 dataset's runs of samples.

    `starts[i]` is the first sample of run i and `offsets[i]` its byte offset in the
    file; a run ends where the next begins (a contiguous dataset is one run, a chunked
    one a run per chunk, in sample order whatever their order in the file).
    """

    def __init__(self, starts: np.ndarray, offsets: np.ndarray, samples: int) -> None:
        self.starts, self.offsets, self.samples = starts, offsets, samples

    @classmethod
    def of(cls, dset: h5py.Dataset) -> Extents | None:
        """The extents of `dset`, or None when its samples are not stored raw."""
        if (not hasattr(os, "preadv") or sys.byteorder != "little" or dset.ndim != 1
                or dset.dtype != np.dtype("<i2")):
            return None                # the bytes would not be this machine's int16
        try:
            if (dset.file.userblock_size or dset.id.get_create_plist().get_nfilters() or dset.is_virtual
                    or dset.external):
                return None
            n = dset.shape[0]
            if dset.chunks is None:
                offset = dset.id.get_offset()
                return None if offset is None else cls(np.zeros(1, np.int64), np.array([offset]), n)
            size = dset.chunks[0]
            count = -(-n // size)
            if dset.id.get_num_chunks() != count:       # some never written: HDF5's fill value
                return None
            infos: list = []
            try:
                dset.id.chunk_iter(infos.append)       # one walk of the index: 0.2 ms for 191 chunks
            except AttributeError:                      # HDF5 < 1.12.3: a query a chunk, 2 ms
                infos = [dset.id.get_chunk_info(i) for i in range(count)]
        except (AttributeError, OSError, RuntimeError, ValueError):
            return None               # an HDF5 without the chunk queries: h5py reads it
        if any(c.filter_mask or c.size != size * ITEM for c in infos):
            return None
        order = sorted(infos, key=lambda c: c.chunk_offset[0])
        starts = np.array([c.chunk_offset[0] for c in order], np.int64)
        if not np.array_equal(starts, np.arange(count, dtype=np.int64) * size):
            return None
        return cls(starts, np.array([c.byte_offset for c in order], np.int64), n)

    def file_offset(self) -> int | None:
        """The byte offset of sample 0 where every sample lies in one run of the file (a
        contiguous dataset, or chunks stored one after another in order), else None."""
        ends = self.offsets[:-1] + (self.starts[1:] - self.starts[:-1]) * ITEM
        return int(self.offsets[0]) if np.array_equal(ends, self.offsets[1:]) else None

    def read(self, fd: int, start: int, stop: int, out: np.ndarray) -> None:
        """Samples [start, stop) into out[:stop - start] (a contiguous int16 array), a
        long read in READERS pieces at once (`preadv` lets the GIL go).

        Raises OSError when the file ends early (a truncated copy)."""
        read_all([(self, fd, start, stop, out)])

    def pieces(self, fd: int, start: int, stop: int, out: np.ndarray) -> list[tuple]:
        """The reads of samples [start, stop) into `out`, as arguments of `_read`: one,
        or up to READERS of a long read (PIECE_BYTES or more each)."""
        view = memoryview(out).cast("B")
        count = min(READERS, (stop - start) * ITEM // PIECE_BYTES)
        bounds = np.linspace(start, stop, max(count, 1) + 1).astype(np.int64)
        return [(fd, int(a), int(b), view, start) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]

    def _read(self, fd: int, start: int, stop: int, view: memoryview, origin: int) -> None:
        """Samples [start, stop) into `view`, the bytes of the samples from `origin` on."""
        first = int(np.searchsorted(self.starts, start, side="right")) - 1
        pos = start
        for i in range(first, self.starts.size):
            if pos >= stop:
                break
            end = min(stop, int(self.starts[i + 1]) if i + 1 < self.starts.size else self.samples)
            want = (end - pos) * ITEM
            got = os.preadv(fd, [view[(pos - origin) * ITEM: (end - origin) * ITEM]],
                            int(self.offsets[i]) + (pos - int(self.starts[i])) * ITEM)
            if got != want:
                raise OSError(f"the file ends {want - got} bytes into samples {pos}-{end}")
            pos = end


def unmap_later(mapped: mmap.mmap) -> None:
    """Close `mapped` on a reader thread (unmapping a second of capture's mapped pages
    costs 3 ms of CPU here, which the converting thread need not spend), once no array
    views it; where one still does, it goes with the last."""
    def close() -> None:
        with contextlib.suppress(BufferError):
            mapped.close()

    _pool().submit(close)


def read_all(reads: list[tuple[Extents, int, int, int, np.ndarray]]) -> None:
    """`Extents.read` of each (extents, fd, start, stop, out) of `reads`, all at once on
    the reader threads (a plan's stretches: a dozen reads of a few MB), a single piece
    in this thread. Returns when every piece is done; raises the first piece's OSError."""
    jobs = [(ext, args) for ext, fd, start, stop, out in reads for args in ext.pieces(fd, start, stop, out)]
    if len(jobs) == 1:
        jobs[0][0]._read(*jobs[0][1])
        return
    pieces = [_pool().submit(ext._read, *args) for ext, args in jobs]
    wait(pieces)                    # all done before any error leaves: none writes after
    for piece in pieces:
        piece.result()
