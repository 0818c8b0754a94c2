"""A batch of captures: several converted at once, the results in order."""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from .engine import process
from .errors import CaptureError, FmcwError
from .options import Options
from .processor import ChunkProcessor, NumpyProcessor
from .track import Track


class _Stopped(Exception):
    """A capture of `process_each` abandoned because the batch stopped."""


def process_each(paths, options: Options | None = None, processor: ChunkProcessor | None = None,
                 workers: int | None = None,
                 progress: Callable[[int, int, int, float], None] | None = None
                 ) -> Iterator[tuple[Path, Track | FmcwError]]:
    """`process` of each capture of `paths`, `workers` at a time, the results in order.

    While one capture's kernels run, the next one is opened, planned and read and its
    host steps run (a device waits on the host for about a fifth of a capture's time
    on PoCL, most of it on a GPU). Each worker has its own `processor.fork()` (queue,
    kernels and buffers); at most `workers` captures are in flight or done and not
    yet yielded.

    Parameters
    ----------
    paths : the capture files.
    options, processor : as for `process` (the processor itself serves the first worker).
    workers : captures converted at once (1: one after the other, in this thread);
        None: the processor's `batch_workers`.
    progress : callable(index, samples_done, samples_total, sample_rate_hz), optional:
        the progress of capture `paths[index]`, called from its worker's thread, first
        with zeros when the capture starts.

    Yields
    ------
    (path, Track), or (path, FmcwError) for a capture that cannot be converted (the
    others still are). Any other exception stops the batch: captures in flight stop at
    their next chunk.
    """
    options = options or Options()
    processor = processor or NumpyProcessor()
    paths = [Path(p) for p in paths]
    # never more workers than captures: a single capture converts in this thread (the
    # OpenCL objects stay in the thread that made them; Oclgrind's checks need that)
    workers = max(1, min(processor.batch_workers if workers is None else workers, len(paths)))
    stop = threading.Event()
    free: queue.SimpleQueue = queue.SimpleQueue()
    for i in range(workers):
        free.put(processor if i == 0 else processor.fork())

    def convert(i: int) -> Track | FmcwError:
        def tick(done: int, total: int, fs: float) -> None:
            if stop.is_set():
                raise _Stopped
            if progress:
                progress(i, done, total, fs)

        worker = free.get()
        try:
            if progress:
                progress(i, 0, 0, 0.0)          # started (its rate counts from here)
            return process(paths[i], options, worker, tick)
        except CaptureError as exc:
            return exc
        except FmcwError as exc:            # an option this capture cannot take: its line names it
            return CaptureError(paths[i], str(exc))
        finally:
            free.put(worker)

    if workers <= 1:
        for i, path in enumerate(paths):
            yield path, convert(i)
        return
    pool = ThreadPoolExecutor(workers)
    try:
        running = {i: pool.submit(convert, i) for i in range(workers)}
        for i, path in enumerate(paths):
            got = running.pop(i).result()          # a yielded track is the caller's alone
            if i + workers < len(paths):
                running[i + workers] = pool.submit(convert, i + workers)
            yield path, got
    finally:
        stop.set()
        pool.shutdown(wait=True, cancel_futures=True)
