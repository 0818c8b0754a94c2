"""Several simulated captures written at once, a thread each: the simulator's numpy work
lets the GIL go for most of its time (two captures on two cores: 1.7x faster than one
after another), and a benchmark's captures (a 1 s capture takes a core 20-40 s) are
independent. Threads, not processes: a caller's script needs no `__main__` guard."""

from __future__ import annotations

import os
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor, as_completed
from pathlib import Path

from ..atomic import output_folder
from .writer import SimulationConfig, simulate_capture


def _samples(job: dict) -> int:
    return int(round(job["duration_s"] * (job.get("config") or SimulationConfig()).sample_rate_hz))


def _write(job: dict) -> int:
    simulate_capture(**job)
    return _samples(job)


def simulate_captures(jobs: list[dict], workers: int | None = None,
                      progress: Callable[[int, int], None] | None = None) -> list[Path]:
    """Write the captures of `jobs` that are not there yet, at once.

    Parameters
    ----------
    jobs : list of dict
        Keyword arguments of `simulate_capture` (`path`, `trajectory`, `duration_s`, ...),
        one capture each. A capture whose `path` exists is kept as it is; the folders of
        the others are made where missing.
    workers : int, optional
        Captures written at once (default: one per capture, at most the CPUs).
    progress : callable(done_samples, total_samples), optional
        Called as each capture is finished, from the calling thread.

    Returns
    -------
    The paths of `jobs`, in order.
    """
    todo = [job for job in jobs if not Path(job["path"]).exists()]
    for folder in {Path(job["path"]).parent for job in todo}:
        output_folder(folder)
    total, done = sum(_samples(job) for job in todo), 0
    workers = max(1, min(workers or os.cpu_count() or 1, len(todo)))
    with ThreadPoolExecutor(workers, thread_name_prefix="fmcw-simulate") as pool:
        for finished in as_completed([pool.submit(_write, job) for job in todo]):
            done += finished.result()
            if progress:
                progress(done, total)
    return [Path(job["path"]) for job in jobs]
