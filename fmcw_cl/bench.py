"""Throughput per stage and end to end, for each backend, on a simulated capture.

Real time is 100 MS/s per channel = 40 000 half-sweeps per second (at 20 kHz).
Each stage and each end-to-end row is run once to warm up (kernel compilation, caches),
then three times, waiting for the device to finish, and the best kept; the figures are
ratios within one run, on whatever else the machine is doing.
"""

from __future__ import annotations

import contextlib
import functools
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from .backend import make_processor
from .capture import Capture
from .engine import process
from .options import Options
from .plan import make_plan
from .simulator import jump, rail, simulate_captures, static
from .stages import resample, sync

JUMP_S = 0.3      # the jump scenario's length (take-off to landing)


WHOLES = ("resample + FFT + peak + echoes", "end to end, paper's method")   # not parts of file to track


def _timed(fn, finish, repeat: int = 3) -> float:
    """Best of `repeat` warm runs (s): the machine's noise only ever adds time."""
    fn()  # warm-up: kernel builds, caches
    finish()
    best = np.inf
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        finish()
        best = min(best, time.perf_counter() - t)
    return best


def _stage_rows(be, path: Path, opts: Options, seconds: float, scenes: dict[str, tuple[Path, float]]
                ) -> list[dict]:
    """Time each stage of one backend on the capture at `path`, and end to end on it and
    on the `scenes` (name: (path, seconds))."""
    with Capture(path) as cap:
        info = cap.info
        plan = make_plan(cap, opts, processor=be)
        beat, sy = cap.read(0, info.samples)
    be.open(plan)
    hp = info.samples_per_period / 2
    hs = sync.half_sweeps(sync.sync_turning_points(sy, hp), plan.lag)
    ok = resample.inside(hs.start, hs.length, plan.lut, beat.size)
    starts, lengths = hs.start[ok], hs.length[ok]
    sweeps = int(starts.size)
    m = plan.model
    x = be.resample(beat, starts, lengths, plan.lut.u_fall, plan.window)
    v = np.full(sweeps, 1.0)
    finish = be.finish

    def read():
        with Capture(path) as c:
            c.read(0, info.samples)

    def kernels():
        y = be.resample(beat, starts, lengths, plan.lut.u_fall, plan.window)
        be.measure(y, m.beta_fall, None, m, plan.search)

    stages = {
        "read (HDF5)": read,
        "low-pass (sync delay)": lambda: be.intensity(beat, info.sample_rate_hz),
        "sync turning points": lambda: be.turning_points(sy, hp),
        "resample": lambda: be.resample(beat, starts, lengths, plan.lut.u_fall, plan.window),
        "FFT + peak + echoes": lambda: be.measure(x, m.beta_fall, None, m, plan.search),
        # the plain pass lists every echo (CFAR); the de-chirp passes only measure the peak
        "de-chirp + FFT + peak": lambda: be.measure(x, m.beta_fall, v, m, replace(plan.search, echoes=False)),
        "resample + FFT + peak + echoes": kernels,
        "end to end, paper's method": lambda: process(path, Options(dechirp=False), be),
        "end to end (file to track)": lambda: process(path, opts, be),
    }
    rows = []
    for stage, fn in stages.items():
        end = stage.startswith("end")
        secs = _timed(fn, finish)
        rows.append({"backend": be.name, "device": be.device, "stage": stage, "seconds": secs,
                     "half_sweeps_per_s": sweeps / secs, "msamples_per_s": info.samples / secs / 1e6,
                     "real_time_multiple": seconds / secs,
                     **(_where_time_goes(be, fn, finish, seconds) if end else {})})
    # shares of the file-to-track time: its parts (which do not overlap) and itself; the
    # combined kernels row and the paper's method are wholes of their own
    whole = rows[-1]["seconds"]
    for r in rows:
        part = r["stage"] not in WHOLES or r is rows[-1]
        r["share_of_end_to_end"] = r["seconds"] / whole if part else float("nan")
    for name, (scene, length) in scenes.items():       # other scenes, end to end (not in the shares)
        with Capture(scene) as cap:
            n, periods = cap.info.samples, cap.info.periods
        fn = functools.partial(process, scene, opts, be)
        secs = _timed(fn, finish)
        rows.append({"backend": be.name, "device": be.device, "stage": f"end to end, {name}", "seconds": secs,
                     "half_sweeps_per_s": 2 * periods / secs, "msamples_per_s": n / secs / 1e6,
                     "real_time_multiple": length / secs, "share_of_end_to_end": float("nan"),
                     **_where_time_goes(be, fn, finish, length)})
    return rows


def _where_time_goes(be, fn, finish, seconds: float) -> dict:
    """One more run of an end-to-end row, instrumented: the calling thread's CPU time
    per second of capture (on PoCL a wait sleeps, so this is the host work that bounds
    a GPU's end to end), its share of the wall time (the rest the host waits for the
    device or the reads), the chunks processed (the delay's trial conversions and a
    second pass in the target's band included) and per chunk the kernel launches and
    the copies each way."""
    before, chunks = be.traffic(), be.chunks
    be.profile(True)
    wall, cpu = time.perf_counter(), time.thread_time()
    fn()
    finish()
    wall, cpu = time.perf_counter() - wall, time.thread_time() - cpu
    chunks = be.chunks - chunks
    got = {"host_cpu_ms_per_s": 1e3 * cpu / seconds, "host_share_of_wall": cpu / wall, "chunks": chunks}
    for key, value in be.traffic().items():
        got[f"{key}_per_chunk"] = (value - before[key]) / max(chunks, 1)
    busy = be.profile(False)
    if busy is not None:
        got["device_busy_share"] = busy / wall
    return got


def captures(seconds: float, folder: Path) -> list[dict]:
    """The bench's captures in `folder`, as jobs of `simulator.simulate_captures`: the
    guide rail of `seconds`, a static target at 0.3 m as long, and the jump (its first
    `JUMP_S` s at most)."""
    jump_s = min(seconds, JUMP_S)
    return [{"path": folder / f"bench_rail_{seconds:g}s.h5", "trajectory": rail(seconds + 0.1),
             "duration_s": seconds, "seed": 1, "start_s": 0.1},
            {"path": folder / f"bench_static_{seconds:g}s.h5", "trajectory": static(seconds, 0.3),
             "duration_s": seconds, "seed": 2},
            {"path": folder / f"bench_jump_{jump_s:g}s.h5", "trajectory": jump(JUMP_S), "duration_s": jump_s,
             "seed": 3}]


def run(seconds: float = 0.2, points: int = 1000, backends=("numpy", "opencl"),
        device: str | None = None, progress=None, folder: Path | None = None) -> list[dict]:
    """Benchmark rows: backend, device, stage, seconds, half-sweeps/s, MS/s, x real time.

    Half-sweeps/s counts the half-sweeps of the whole capture for every stage, so
    the rows compare directly (the end-to-end rows include every pass and check).
    The captures (`captures`) are kept and found in `folder` (those missing written at
    once, a thread each), else written to a temporary folder and removed.
    """
    rows = []
    with contextlib.ExitStack() as stack:
        folder = Path(folder or stack.enter_context(tempfile.TemporaryDirectory()))
        path, static_path, jump_path = simulate_captures(captures(seconds, folder), progress=progress)
        scenes = {"static target": (static_path, seconds),
                  f"jump ({min(seconds, JUMP_S):g} s)": (jump_path, min(seconds, JUMP_S))}
        for name in backends:
            rows += _stage_rows(make_processor(name, device), path, Options(points=points), seconds, scenes)
    return rows
