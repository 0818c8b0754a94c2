"""Several simulated captures written at once, one process each: the simulator is numpy on
one core, and a benchmark's captures (a 1 s capture takes some 20-40 s) are independent."""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

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
        one capture each. A capture whose `path` exists is kept as it is.
    workers : int, optional
        Processes at once (default: one per capture, at most the CPUs). Each starts a
        fresh interpreter (spawned, not forked: the caller may hold OpenCL threads).
    progress : callable(done_samples, total_samples), optional
        Called as each capture is finished.

    Returns
    -------
    The paths of `jobs`, in order.
    """
    todo = [job for job in jobs if not Path(job["path"]).exists()]
    total, done = sum(_samples(job) for job in todo), 0
    workers = max(1, min(workers or os.cpu_count() or 1, len(todo)))
    if workers == 1:
        for job in todo:
            done += _write(job)
            if progress:
                progress(done, total)
    else:
        with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) as pool:
            for finished in as_completed([pool.submit(_write, job) for job in todo]):
                done += finished.result()
                if progress:
                    progress(done, total)
    return [Path(job["path"]) for job in jobs]
