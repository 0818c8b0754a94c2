"""Capture -> chunks: whole modulation periods read ahead into two slots, and the
chunk processor run over them.

A chunk's core is `chunk_periods` periods; a margin of context periods on each side lets
the tracker's continuity reach across chunk boundaries, and each pair is owned by the
chunk whose core holds its first turning point. Memory is bounded by the chunk, not the
capture.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from typing import TYPE_CHECKING

import numpy as np

from .capture import Capture, Chunk
from .capture_format import CaptureInfo
from .options import Options
from .stages import delay

if TYPE_CHECKING:
    from .plan import Plan
    from .processor import ChunkMeasurements, ChunkProcessor


class ReadAhead:
    """The items of `chunks`, the next one read by a thread while this one is processed
    (HDF5 reads and the kernels' waits release the GIL). The first read starts at once.
    `close` (or leaving the `with`) waits for a read in flight, so that its slot is not
    handed on mid-read."""

    def __init__(self, chunks: Iterator, geometry: tuple = ()) -> None:
        self._chunks, self._pool = chunks, ThreadPoolExecutor(1)
        self._ahead = self._pool.submit(next, chunks, None)
        self.geometry = geometry        # what the chunks are (`chunk_geometry`)

    def __iter__(self) -> Iterator:
        while (item := self._ahead.result()) is not None:
            self._ahead = self._pool.submit(next, self._chunks, None)
            yield item

    def peek(self):
        """The item after the one being processed (None after the last), once read. The
        read after it starts only when the iteration moves on: it takes the slot of the
        item being processed."""
        return self._ahead.result()

    def close(self) -> None:
        self._pool.shutdown(wait=True, cancel_futures=True)

    def __enter__(self) -> ReadAhead:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def core_samples(info: CaptureInfo, options: Options) -> int:
    """Samples in the core of one chunk (chunks start at multiples of this)."""
    return info.core_samples(options.chunk_periods)


def split_ranges(info: CaptureInfo, options: Options, seconds: float) -> list[tuple[int, int]]:
    """The capture cut into ranges of about `seconds` made of whole chunks, so that
    processing them apart gives exactly the chunks (and the track) of one pass."""
    core = core_samples(info, options)
    per = max(1, round(seconds * info.sample_rate_hz / core)) * core
    return [(a, min(a + per, info.samples)) for a in range(0, info.samples, per)]


def margin_samples(info: CaptureInfo, options: Options) -> int:
    """Samples read on each side of a chunk's core: the context periods, one more for
    the half-sweep that starts in the core, and the largest sync delay."""
    return int((options.context_periods + 1) * info.samples_per_period + delay.MAX_DELAY_SAMPLES + 8)


READ_SLOTS = 3    # a chunk's codes are read by its range check while the next one is
                  # processed and the one after is read


def chunk_geometry(info: CaptureInfo, options: Options, start: int = 0, stop: int | None = None) -> tuple:
    """What `read_chunks` of these arguments reads: periods a core, margin, range."""
    return options.chunk_periods, margin_samples(info, options), start, stop


def read_chunks(cap: Capture, options: Options, start: int = 0, stop: int | None = None) -> ReadAhead:
    """The chunks of `options` whose cores lie in samples [start, stop), read ahead into
    the capture's slots 0 .. READ_SLOTS - 1: a chunk's results keep none of its samples,
    and its kernels are done when the chunk after the next one starts."""
    periods, margin, *_ = geometry = chunk_geometry(cap.info, options, start, stop)
    return ReadAhead(cap.chunks(periods, margin, start, stop, slots=READ_SLOTS), geometry)


HELD_SLOT = READ_SLOTS     # the capture's slot that held chunks take, end to end


def held_end_to_end(cap: Capture, options: Options, ranges: list[tuple[int, int]]
                    ) -> tuple[np.ndarray, list[Chunk], list[int], list[int]]:
    """The chunks of `options` whose cores lie in each sample range [start, stop) of
    `ranges`, read once, end to end, into the capture's slot HELD_SLOT (pooled memory,
    touched before: Capture.slot; what `Capture.held` said it held is gone): for a
    caller that converts the same samples more than once, the chunks together
    (ChunkProcessor.process_apart).

    Returns the beat codes of them all, the chunks (their arrays views into the slot),
    where each chunk's codes start in the first, and the range each chunk lies in."""
    margin = margin_samples(cap.info, options)
    cap.held = None
    spans = [(k, *span) for k, (a, b) in enumerate(ranges)
             for span in cap.chunk_spans(options.chunk_periods, margin, a, b)]
    sizes = [hi - lo for _, lo, hi, *_ in spans]
    offsets = np.cumsum([0, *sizes]).tolist()
    beat, sync = cap.slot(HELD_SLOT, offsets[-1])
    cuts = [slice(at, at + hi - lo) for (_, lo, hi, *_), at in zip(spans, offsets, strict=False)]
    read = cap.read_spans([(lo, hi) for _, lo, hi, *_ in spans], [beat[c] for c in cuts],
                          [sync[c] for c in cuts])
    chunks = [Chunk(lo, b, s, core_start, core_stop)
              for (_, lo, _, core_start, core_stop), (b, s) in zip(spans, read, strict=True)]
    return beat, chunks, offsets[:-1], [k for k, *_ in spans]


def capture_parts(cap: Capture, plan: Plan, processor: ChunkProcessor, start: int = 0,
                  stop: int | None = None, progress: Callable[[int, int, float], None] | None = None,
                  ahead: ReadAhead | None = None) -> list[ChunkMeasurements]:
    """The measurements of every chunk whose core lies in samples [start, stop)
    (`start` a multiple of `core_samples`), read ahead (`read_chunks`; `ahead`: those
    chunks already being read, used where their geometry is the plan's), by `processor`
    opened with `plan`; each chunk is processed knowing the one after it (a chunk's
    range check and survey run in the trips of the next one, which a device prepares in
    them: `ChunkProcessor.process`)."""
    parts = []
    processor.open(plan)
    if ahead is None or ahead.geometry != chunk_geometry(cap.info, plan.options, start, stop):
        if ahead is not None:
            ahead.close()                  # its read in flight would share the first slot
        ahead = read_chunks(cap, plan.options, start, stop)
    with ahead:
        for chunk in ahead:
            parts += processor.process(chunk, following=ahead.peek)
            if progress:
                progress(chunk.core_stop, cap.info.samples, cap.info.sample_rate_hz)
    return parts
