"""Throughput per stage and end to end, for each backend, on a simulated capture.

Real time is 100 MS/s per channel = 40 000 half-sweeps per second (at 20 kHz).
Each stage is run once to warm up (kernel compilation) and then timed; the figures
are ratios within one run, on whatever else the machine is doing.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from .capture import Capture
from .engine import Options, make_backend, make_plan, process
from .simulate import rail, simulate_capture
from .stages import sync


def _timed(fn, repeat: int = 3) -> float:
    fn()  # warm-up: kernel builds, caches
    best = np.inf
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best


def _stage_rows(be, path: Path, opts: Options, seconds: float) -> list[dict]:
    """Time each stage of one backend on the capture at `path`."""
    with Capture(path) as cap:
        info = cap.info
        plan = make_plan(cap, opts)
        beat, sy = cap.read(0, info.samples)
    hp = info.samples_per_period / 2
    hs = sync.half_sweeps(sync.sync_turning_points(sy, hp), plan.lag)
    ok = (hs.start >= 2) & (hs.start + hs.length < beat.size - 3)
    starts, lengths = hs.start[ok], hs.length[ok]
    sweeps = int(starts.size)
    m = plan.model
    x = be.resample(beat, starts, lengths, plan.lut.u_fall, plan.window)
    v = np.full(sweeps, 1.0)

    def read():
        with Capture(path) as c:
            c.read(0, info.samples)

    stages = {
        "read (HDF5)": read,
        "sync turning points": lambda: sync.sync_turning_points(sy, hp),
        "resample": lambda: be.resample(beat, starts, lengths, plan.lut.u_fall, plan.window),
        "FFT + peak": lambda: be.measure(x, m.beta_fall, None, m, plan.lo_bin),
        "de-chirp + FFT + peak": lambda: be.measure(x, m.beta_fall, v, m, plan.lo_bin),
        "end to end (file to track)": lambda: process(path, opts, be),
    }
    rows = []
    for stage, fn in stages.items():
        secs = _timed(fn, repeat=1 if stage.startswith("end") else 3)
        rows.append({"backend": be.name, "device": be.device, "stage": stage, "seconds": secs,
                     "half_sweeps_per_s": sweeps / secs, "msamples_per_s": info.samples / secs / 1e6,
                     "real_time_multiple": seconds / secs})
    return rows


def run(seconds: float = 0.2, points: int = 1000, backends=("numpy", "opencl"),
        device: str | None = None, progress=None) -> list[dict]:
    """Benchmark rows: backend, device, stage, seconds, half-sweeps/s, MS/s, x real time.

    Half-sweeps/s counts the half-sweeps of the whole capture for every stage, so
    the rows compare directly (the end-to-end row includes all de-chirp passes).
    """
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.h5"
        simulate_capture(path, rail(seconds + 0.1), seconds, seed=1, start_s=0.1, progress=progress)
        for name in backends:
            rows += _stage_rows(make_backend(name, device), path, Options(points=points), seconds)
    return rows
