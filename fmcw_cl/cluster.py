"""Batch conversion on a Dask cluster (optional extra: ``pip install ".[cluster]"`` in the fmcw-cl folder).

Two levels of parallelism:
- one task per capture: the worker reads the capture, converts it and writes its
  track (atomically) to the shared output folder;
- a long capture is cut into ranges of whole chunks (`chunks.split_ranges`): a worker
  task makes the plan once (G(I), LUT, sync delay), range tasks convert their chunks
  with it, and the client stitches the pairs and writes the track. Because the ranges
  are whole chunks of the one-machine pass, the track equals the one-machine track.

Each worker process builds its backend (its OpenCL context and programs) once and
reuses it across tasks; the device comes from the worker's environment
(``PYOPENCL_CTX``, e.g. one GPU per worker) unless `device` is given.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from pathlib import Path

from . import spectrum_ops
from .assemble import assemble
from .backend import make_processor
from .capture import Capture
from .chunks import capture_parts, split_ranges
from .engine import check_tuning, chosen, process, with_choice, with_objects
from .errors import FmcwError
from .objects import SceneObject
from .options import Options
from .plan import make_plan
from .processor import NumpyProcessor
from .track import track_path, write_track

TASK_SECONDS = 1.0      # capture seconds per range task of a long capture
CONNECT_TIMEOUT_S = 10  # a scheduler address that does not answer in this time is refused

_BACKENDS: dict = {}    # per worker process: (name, device) -> backend


def _backend(name: str, device: str | None):
    key = (name, device)
    if key not in _BACKENDS:
        _BACKENDS[key] = make_processor(name, device)
    return _BACKENDS[key]


# Dask starts workers with MALLOC_TRIM_THRESHOLD_=65536, which also turns off glibc's
# adaptive mmap threshold: every array over 128 KB is then mapped and unmapped afresh, and
# a conversion (many chunk-sized temporaries) ran 1.6x slower in a worker than alone.
# Heap reuse up to 32 MB arrays and trimming beyond 256 MB restore the plain speed.
WORKER_MALLOC = {"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": 256 << 20,
                 "distributed.nanny.pre-spawn-environ.MALLOC_MMAP_THRESHOLD_": 32 << 20}


def connect(scheduler: str):
    """A Dask client: ``local:N`` starts a LocalCluster of N worker processes here;
    anything else is a scheduler address (``tcp://host:8786``)."""
    try:
        import dask
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise FmcwError('--scheduler needs Dask: pip install ".[cluster]" (in the fmcw-cl folder)') from None
    if scheduler.startswith("local:"):
        n = scheduler.split(":", 1)[1]
        if not n.isdigit() or int(n) < 1:
            raise FmcwError(f"--scheduler {scheduler!r}: local:N needs a whole number of workers N >= 1")
        dask.config.set(WORKER_MALLOC)
        cluster = LocalCluster(n_workers=int(n), threads_per_worker=1, processes=True,
                               dashboard_address=None)
        return Client(cluster)
    try:
        return Client(scheduler, timeout=CONNECT_TIMEOUT_S)
    except (ValueError, OSError, TimeoutError) as exc:
        raise FmcwError(f"--scheduler {scheduler!r}: no Dask scheduler there ({exc}); give "
                        "tcp://host:port or local:N") from None


def _written(capture: str, out: str, track) -> dict:
    """Write `track` to `out`; the result record run_batch yields for it."""
    write_track(out, track)
    return {"capture": capture, "track": out, "attrs": track.attrs, "valid": track.valid,
            "pairs": track.pairs}


def _convert(capture: str, out: str, options: Options, backend: str, device: str | None) -> dict:
    """Task: one whole capture to its track file (or the error, as data)."""
    try:
        track = process(capture, options, _backend(backend, device))
        return _written(capture, out, track)
    except FmcwError as exc:
        return {"capture": capture, "error": str(exc)}


def _plan(capture: str, options: Options, task_seconds: float, backend: str, device: str | None):
    """Task: the plan of a long capture and its ranges."""
    with Capture(capture) as cap:
        plan = make_plan(cap, options, processor=_backend(backend, device))
        return plan, split_ranges(cap.info, plan.options, task_seconds)


def _range(capture: str, plan, start: int, stop: int, backend: str, device: str | None):
    """Task: the owned pairs of one range, and which backend made them."""
    stages = _backend(backend, device)
    with Capture(capture, stages.reads_in_place) as cap:
        return capture_parts(cap, plan, stages, start, stop), stages.name, stages.device


class _Made(spectrum_ops.SpectrumOps):
    """What assemble() records of the backend that made the pairs; the verification's
    tests run in numpy here."""

    def __init__(self, name: str, device: str) -> None:
        self.name, self.device = name, device


def run_batch(client, captures: list[Path], outdir: Path, options: Options, backend: str = "auto",
              device: str | None = None, split_seconds: float = 2 * TASK_SECONDS,
              task_seconds: float = TASK_SECONDS,
              progress: Callable[[int, int, float], None] | None = None) -> Iterator[dict]:
    """Convert `captures` on the cluster; yields one result per capture as it completes:
    ``{"capture", "track", "attrs", "valid", "pairs"}`` or ``{"capture", "error"}``.

    Captures longer than `split_seconds` are split into ranges of about `task_seconds`
    (whole chunks) across workers.
    Paths must be valid on the workers (a shared filesystem). `progress` is called as
    each capture completes with (samples done, samples in the batch, sample rate), as
    `engine.process` calls it per chunk.
    """
    started = time.perf_counter()
    jobs: dict = {}                 # future -> (kind, capture, track path, range index)
    samples: dict = {}              # capture -> (samples, sample rate)
    refused = []
    for cap in captures:            # submitted now, not when the results are first asked for
        out = str(track_path(outdir, cap))
        try:
            with Capture(cap) as c:
                long = c.info.duration_s > split_seconds
                samples[str(cap)] = (c.info.samples, c.info.sample_rate_hz)
        except FmcwError as exc:
            refused.append({"capture": str(cap), "error": str(exc)})
            continue
        if long:
            jobs[client.submit(_plan, str(cap), options, task_seconds, backend, device,
                               pure=False)] = ("plan", cap, out, None)
        else:
            jobs[client.submit(_convert, str(cap), out, options, backend, device, pure=False)] = (
                "convert", cap, out, None)
    return _collect(client, jobs, samples, refused, backend, device, started, progress)


def _collect(client, jobs: dict, samples: dict, refused: list, backend: str, device: str | None,
             started: float, progress) -> Iterator[dict]:
    """Results of run_batch's tasks as they complete; long captures' ranges submitted
    when their plan is ready, stitched when their last range is."""
    from dask.distributed import as_completed

    yield from refused
    total, done = sum(n for n, _ in samples.values()), 0
    ranges: dict = {}               # capture -> [plan, number of ranges, {index: parts}]
    pending = as_completed(list(jobs))

    def submit_ranges(cap, out, plan, cuts, choice) -> None:
        """The range tasks of one pass over a long capture (`choice`: the target of its
        first pass, None in the first)."""
        shared = client.scatter(plan)
        ranges[str(cap)] = [plan, len(cuts), {}, choice, cuts]
        for i, (a, b) in enumerate(cuts):
            f = client.submit(_range, str(cap), shared, a, b, backend, device, pure=False)
            jobs[f] = ("range", cap, out, i)
            pending.add(f)

    for fut in pending:
        kind, cap, out, index = jobs.pop(fut)
        try:
            value = fut.result()
        except FmcwError as exc:
            value = {"capture": str(cap), "error": str(exc)}
            kind = "convert"
            ranges.pop(str(cap), None)
        if kind == "plan":
            submit_ranges(cap, out, *value, None)
            continue
        if kind == "range":
            if str(cap) not in ranges:          # an earlier range of it failed
                continue
            plan, count, got, choice, cuts = ranges[str(cap)]
            got[index] = value
            if len(got) < count:
                continue
            del ranges[str(cap)]
            parts = [p for i in range(count) for p in got[i][0]]
            made = _Made(*got[0][1:])
            track = assemble(plan, parts, made, time.perf_counter() - started, choice)
            if choice is None:                    # the first pass: which echo is the target
                with Capture(cap) as c:
                    choice = chosen(c, plan, NumpyProcessor(), track)[0]
                if choice.band_m != plan.options.band_m:    # its band: the ranges again
                    submit_ranges(cap, out, plan.with_band(choice.band_m), cuts, choice)
                    continue
                track = with_choice(plan, parts, made, time.perf_counter() - started, track, choice)
            with Capture(cap) as c:
                check_tuning(c, plan, track, NumpyProcessor())
            # a capture split into ranges gives its target only: the objects' own bands
            # would each be a pass over every range
            only = "the target: a capture split into ranges is converted for its target only"
            track = with_objects([SceneObject(1, bool(choice.moving), track, only)], 0)
            value = _written(str(cap), out, track)
        n, fs = samples[str(cap)]
        done += n
        if progress:
            progress(done, total, fs)
        yield value
