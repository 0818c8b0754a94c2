"""Launcher of kernels/resample.cl (twin: fmcw_cl.stages.resample.resample)."""

from __future__ import annotations

import numpy as np

from ..numeric import median
from .buffers import Buffers, DeviceRows, Packed
from .context import Runtime, cl

GPU_LOCAL = 128     # work-items of `resample`'s groups (a half-sweep each)


def codes_of(bufs: Buffers, codes: np.ndarray):
    """A chunk's beat codes on the device, uploaded once for all its launches; the last
    two chunks' stay (a chunk's range check runs with the next one's resampling, whose
    clipping counts are launched with the one before)."""
    return bufs.upload_once("codes", codes if codes.dtype == np.int16 else codes.astype(np.int16), keep=2)


def resample_each(rt: Runtime, bufs: Buffers, codes: np.ndarray, jobs: list, win: np.ndarray,
                  also: tuple = ()) -> list[DeviceRows]:
    """Resampled, mean-removed, windowed half-sweeps of each (starts, lengths, u[, runs])
    of `jobs` (a pair's rising and falling half-sweeps), (S, N) float32 each, left on the
    device (twin: stages.resample.resample): `resample_groups` of one group, the device
    buffers of `also` following the rows in the list returned."""
    rows, extra = resample_groups(rt, bufs, [(codes, jobs, win)], also)
    return rows[0] + extra


def _runs(job: tuple) -> list[tuple[int, int]]:
    """The (first, end) half-sweeps of each run of `job` (starts, lengths, u[, runs]):
    `runs` counts consecutive half-sweeps whose positions are split at their own median
    length, so that their float32 rows do not depend on the others' (the chunks of one
    pass of the delay's trials); without it, one run."""
    counts = job[3] if len(job) > 3 else (job[0].size,)
    ends = np.cumsum(counts, dtype=np.int64)
    return [(int(e - n), int(e)) for n, e in zip(counts, ends, strict=True) if n]


def resample_groups(rt: Runtime, bufs: Buffers, groups: list, also: tuple = ()) -> tuple[list, list]:
    """`resample_each` of each (codes, jobs, window) of `groups` (a chunk's pairs, the
    range check of the chunk before), the positions of every job and the arrays `also` (a
    later step's inputs) up by one copy. The codes are uploaded once for all launches on
    one array (`codes_of`).

    Returns the rows of each group's jobs, and the device buffers of `also`."""
    parts, values = [], []
    for _, jobs, _ in groups:
        for job in jobs:
            starts, lengths, u = job[:3]
            for a, b in _runs(job):
                nominal = median(lengths[a:b])
                base = np.floor(starts[a:b]).astype(np.int32)
                whole = u * nominal
                lut_int = np.floor(whole)
                # the sweeps' positions and the LUT split at this nominal length
                parts += [(np.int32, b - a), (np.float32, b - a), (np.float32, b - a), (np.int32, u.size),
                          (np.float32, u.size)]
                values += [base, starts[a:b] - base, np.asarray(lengths[a:b]) - nominal, lut_int,
                           whole - lut_int]
    parts += [(a.dtype, a.size) for a in also]
    buffers = Packed(bufs, "positions", parts).upload(*values, *also)
    out, i = [], 0
    for codes, jobs, win in groups:
        d_codes = codes_of(bufs, codes)
        d_win = bufs.constant("win", win)
        rows_of = []
        for job in jobs:
            starts, _, u = job[:3]
            rows = DeviceRows(bufs, starts.size, u.size)
            rows_of.append(rows)
            for a, b in _runs(job):
                args = (d_codes, *buffers[5 * i: 5 * i + 5], bufs.constant("u", u), d_win, np.int32(u.size),
                        np.int32(a), rows.buffer)
                if rt.lanes:
                    rt.kernel("resample", "resample_lanes")(rt.queue, (b - a,), (1,), *args)
                else:
                    rt.kernel("resample", "resample")(rt.queue, ((b - a) * GPU_LOCAL,), (GPU_LOCAL,), *args,
                                                      cl.LocalMemory(4 * GPU_LOCAL))
                i += 1
        out.append(rows_of)
    return out, buffers[5 * i:]
