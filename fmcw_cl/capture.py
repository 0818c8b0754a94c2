"""Capture files (contract section 1): open and read in chunks (the contract and its
validation: capture_format; the writer: capture_writer).

A capture holds two int16 ADC channels (beat, sync) that may be several GB long, so
reading is always by sample range; nothing here loads a whole channel.
"""

from __future__ import annotations

import contextlib
import mmap
import os
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from . import pool
from .capture_format import TRUTH_FIELDS, Truth, _open_problem, validate
from .errors import CaptureError
from .extents import ITEM, Extents, read_all, unmap_later


@dataclass(frozen=True)
class Chunk:
    """Samples [start, stop) of both channels; `core` is the range this chunk owns.

    The margins around the core let a stage look past the core's ends (filters,
    interpolation, a half-sweep that starts in the core and ends after it).
    """

    start: int
    beat: np.ndarray
    sync: np.ndarray
    core_start: int
    core_stop: int

    @property
    def stop(self) -> int:
        return self.start + self.beat.size


def _read_truth(g: h5py.Group) -> Truth:
    visible = np.asarray(g["visible"][()], bool) if "visible" in g else None
    return Truth(*(np.asarray(g[k][()], dtype=np.float64) for k in TRUTH_FIELDS), visible,
                 str(g.attrs.get("kind", "moving")))


class Capture:
    """An open capture file. Use as a context manager; read by sample range.

    Parameters
    ----------
    path : the capture file.
    in_place : bool
        Give the chunk reader's chunks (`chunks` with slots) as read-only views of the
        file's pages where both channels lie raw in one run of the file each (a
        contiguous dataset, as `CaptureWriter` stores them uncompressed): no copy, for a
        processor on the CPU (`ChunkProcessor.reads_in_place`). Other layouts are read.

    Examples
    --------
    >>> with Capture("run.h5") as cap:                      # doctest: +SKIP
    ...     for chunk in cap.chunks(periods=4096, margin=6000):
    ...         ...
    """

    def __init__(self, path: str | os.PathLike, in_place: bool = False) -> None:
        self.path = Path(path)
        if not self.path.exists():
            raise CaptureError(self.path, "no such file")
        try:
            self._file = h5py.File(self.path, "r")
        except OSError as exc:
            raise CaptureError(self.path, _open_problem(str(exc))) from None
        try:
            self.info = validate(self._file, self.path)
        except CaptureError:
            self._file.close()
            raise
        except (KeyError, OSError, TypeError, ValueError) as exc:
            self._file.close()
            raise CaptureError(self.path, f"damaged capture ({exc})") from None
        self._beat = self._file["adc/beat"]
        self._sync = self._file["adc/sync"]
        # channels stored raw are read straight from the file (fmcw_cl.extents)
        self._extents = [Extents.of(self._beat), Extents.of(self._sync)]
        self._fd = os.open(self.path, os.O_RDONLY) if any(self._extents) else None
        self._mmap: mmap.mmap | None = None
        self._map_offsets: list[int] = []
        self._mapped = self._map() if in_place else None
        self._slots: list[tuple[np.ndarray, np.ndarray]] = []
        self._slots_lock = threading.Lock()     # the chunk reader's thread takes slots too
        self.held: tuple | None = None          # (key, value) of what the held slot holds now
                                                # (refine.stretches: read once, converted often)

    def __enter__(self) -> Capture:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _map(self) -> tuple[np.ndarray, ...] | None:
        """Both channels as read-only arrays over the file mapped in memory, where each
        lies raw in one run of the file (`Extents.file_offset`), else None. Views of them
        are the page cache itself: a chunk that a CPU's processor reads in place costs no
        copy (a 2 s capture's two channels: 800 MB, 110-150 ms of CPU read here)."""
        offsets = [None if e is None else e.file_offset() for e in self._extents]
        if self._fd is None or None in offsets:
            return None
        try:
            mapped = mmap.mmap(self._fd, 0, access=mmap.ACCESS_READ)
        except (OSError, ValueError):
            return None
        if max(offsets) + ITEM * self.info.samples > len(mapped):
            return None                  # a truncated file: the reads name it
        self._map_offsets = offsets
        self._mmap = mapped     # closed with the capture where no chunk views it any more
        return tuple(np.frombuffer(mapped, np.int16, self.info.samples, o) for o in offsets)

    def _in_place(self, lo: int, hi: int) -> tuple[np.ndarray, np.ndarray]:
        """Samples [lo, hi) of both channels as views of the mapped file, their pages
        brought in by this thread (the chunk reader's): one touch a page maps them 16 at a
        time, about 10 ms per 400 MB here, where the device's threads would stop for them, and
        waits for the disk where the page cache does not hold them yet. A file cut since
        it was opened is an error here, where a touch of its lost pages would end the
        process."""
        if os.fstat(self._fd).st_size < max(self._map_offsets) + ITEM * hi:
            raise CaptureError(self.path, f"cannot read samples {lo}-{hi} (the file ends before them)")
        views = tuple(a[lo:hi] for a in self._mapped)
        for v, offset in zip(views, self._map_offsets, strict=True):
            if v.size:
                first = (offset + ITEM * lo) // mmap.PAGESIZE * mmap.PAGESIZE
                with contextlib.suppress(AttributeError, OSError):      # no madvise: the touches' read-ahead
                    self._mmap.madvise(mmap.MADV_WILLNEED, first, offset + ITEM * hi - first)
                v[:: mmap.PAGESIZE // ITEM].max()
        return views

    def close(self) -> None:
        for pair in self._slots:      # the slots go back to the pool for the next capture
            for a in pair:
                pool.give(a)
        self._slots = []
        self.held = None
        if self._mmap is not None:
            self._mapped = None         # the views of it here: a reader thread unmaps it
            unmap_later(self._mmap)
            self._mmap = None
        self._file.close()
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None

    def read(self, start: int, stop: int) -> tuple[np.ndarray, np.ndarray]:
        """Samples [start, stop) of (beat, sync) as int16 ADC codes (clipped to the file),
        in new arrays."""
        n = max(0, min(self.info.samples, int(stop)) - max(0, int(start)))
        return self.read_into(start, stop, np.empty(n, np.int16), np.empty(n, np.int16))

    def read_into(self, start: int, stop: int, beat: np.ndarray, sync: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
        """`read` into the given int16 arrays (long enough): their first stop - start
        samples, as views. Reading into arrays that exist costs a fifth of the CPU of
        new ones (no pages to fault in and free: 85 against 470 ms per 333 MB here)."""
        start = max(0, int(start))
        stop = min(self.info.samples, int(stop))
        n = max(0, stop - start)
        try:
            for ds, ext, out in ((self._beat, self._extents[0], beat), (self._sync, self._extents[1], sync)):
                if n and ext is not None and out.dtype == np.int16 and out.flags.c_contiguous:
                    ext.read(self._fd, start, stop, out)
                elif n:
                    ds.read_direct(out, np.s_[start:stop], np.s_[0:n])
        except (OSError, ValueError, TypeError) as exc:
            raise CaptureError(self.path, f"cannot read samples {start}-{stop} ({exc})") from None
        return beat[:n], sync[:n]

    def read_spans(self, spans: list[tuple[int, int]], beats: list[np.ndarray], syncs: list[np.ndarray]
                   ) -> list[tuple[np.ndarray, np.ndarray]]:
        """`read_into` of each (start, stop) of `spans` into beats[i] and syncs[i]: all at
        once on the reader threads where both channels are read straight from the file
        (`fmcw_cl.extents`: a plan's stretches, some 40 MB, no longer copied by the
        converting thread alone), else one after another."""
        bounds = [(max(0, int(a)), min(self.info.samples, int(b))) for a, b in spans]
        arrays = [*beats, *syncs]
        if not all(e is not None for e in self._extents) or any(
                a.dtype != np.int16 or not a.flags.c_contiguous for a in arrays):
            return [self.read_into(a, b, beat, sync)
                    for (a, b), beat, sync in zip(spans, beats, syncs, strict=True)]
        reads = [(ext, self._fd, a, b, out) for ext, outs in zip(self._extents, (beats, syncs), strict=True)
                 for (a, b), out in zip(bounds, outs, strict=True) if b > a]
        try:
            read_all(reads)
        except OSError as exc:
            first, last = min(a for a, _ in bounds), max(b for _, b in bounds)
            raise CaptureError(self.path, f"cannot read samples {first}-{last} ({exc})") from None
        return [(beat[: max(0, b - a)], sync[: max(0, b - a)])
                for (a, b), beat, sync in zip(bounds, beats, syncs, strict=True)]

    def slot(self, i: int, samples: int) -> tuple[np.ndarray, np.ndarray]:
        """Int16 arrays of `samples` (beat, sync) for `read_into`, slot i of those this
        capture holds: borrowed from `fmcw_cl.pool` and given back when the capture is
        closed, so that memory is touched once per process, not per capture or chunk
        (the chunks take turns in slots 0 .. chunks.READ_SLOTS - 1, the sync delay's
        stretches use slot 1, the delay refinement's held chunks slot chunks.HELD_SLOT).
        What a slot held is overwritten by its next user, after `close` by another
        capture."""
        with self._slots_lock:
            while len(self._slots) <= i:
                self._slots.append((np.empty(0, np.int16), np.empty(0, np.int16)))
            if self._slots[i][0].size < samples:
                for a in self._slots[i]:
                    pool.give(a)
                self._slots[i] = (pool.lease(samples), pool.lease(samples))
            return self._slots[i][0][:samples], self._slots[i][1][:samples]

    def chunks(self, periods: int, margin: int = 0, start: int = 0, stop: int | None = None,
               slots: int = 0, held: int | None = None) -> Iterator[Chunk]:
        """Iterate over the capture in chunks of whole modulation periods.

        Parameters
        ----------
        periods : int
            Modulation periods per chunk core; the core is round(periods * P) samples
            with P = sample_rate / modulation frequency.
        margin : int
            Extra samples read on each side of the core (clipped at the file ends).
        start, stop : int
            Sample range to cover (default: the whole capture).
        slots : int
            0: every chunk in new arrays. k > 0: the chunks take turns in the capture's
            slots 0 .. k - 1 (`slot`), so chunk i's samples are overwritten by chunk
            i + k's: for a consumer that is done with a chunk k - 1 chunks later. A
            capture opened `in_place` whose channels lie raw in the file gives views
            of the file's pages instead (read-only).
        held : int, optional
            Chunk i in slot `held` + i, its own, of its own length instead (a consumer
            that keeps every chunk: the arrays are the pool's, touched before).
        """
        size = min(self.info.core_samples(periods) + 2 * margin, self.info.samples)
        for i, (lo, hi, core_start, core_stop) in enumerate(self.chunk_spans(periods, margin, start, stop)):
            if held is not None:
                beat, sync = self.read_into(lo, hi, *self.slot(held + i, hi - lo))
            elif not slots:
                beat, sync = self.read(lo, hi)
            elif self._mapped is not None:
                beat, sync = self._in_place(lo, hi)
            else:
                beat, sync = self.read_into(lo, hi, *self.slot(i % slots, size))
            yield Chunk(lo, beat, sync, core_start, core_stop)

    def chunk_spans(self, periods: int, margin: int = 0, start: int = 0, stop: int | None = None
                    ) -> Iterator[tuple[int, int, int, int]]:
        """The samples (start, stop, core start, core stop) of each chunk of `chunks`."""
        if periods < 1:
            raise ValueError("periods must be >= 1")
        stop = self.info.samples if stop is None else min(stop, self.info.samples)
        core = self.info.core_samples(periods)
        for core_start in range(int(start), stop, core):
            core_stop = min(core_start + core, stop)
            hi = min(self.info.samples, core_stop + margin)
            yield max(0, core_start - margin), hi, core_start, core_stop

    def truth(self) -> Truth | None:
        """The simulator's true trajectory, or None when the capture has none."""
        if not self.info.has_truth:
            return None
        return _read_truth(self._file["truth"])

    def truth_objects(self) -> list[Truth]:
        """The simulator's truth of every echo of the scene, the target first, then the
        other moving echoes and the static reflectors (`Truth.kind`), each with where it
        can be seen; [] when the capture has no truth."""
        if not self.info.has_truth:
            return []
        g = self._file["truth"]
        others = g.get("objects", {})
        return [_read_truth(g), *(_read_truth(others[k]) for k in sorted(others, key=int))]
