"""Launcher of kernels/resample.cl (twin: fmcw_cl.stages.resample.resample)."""

from __future__ import annotations

import numpy as np

from ..numeric import median
from .buffers import Buffers, DeviceRows, Packed
from .context import Runtime, cl

GPU_LOCAL = 128     # work-items of `resample`'s groups (a half-sweep each)


def resample_each(rt: Runtime, bufs: Buffers, codes: np.ndarray, jobs: list, win: np.ndarray,
                  also: tuple = ()) -> list[DeviceRows]:
    """Resampled, mean-removed, windowed half-sweeps of each (starts, lengths, u) of `jobs`
    (a pair's rising and falling half-sweeps), (S, N) float32 each, left on the device
    (twin: stages.resample.resample). The codes are uploaded once for all launches on
    one array, the positions of every job by one copy; with them the arrays `also` (a
    later step's inputs), whose device buffers follow the rows in the list returned."""
    d_codes = bufs.upload_once("codes", codes if codes.dtype == np.int16 else codes.astype(np.int16))
    parts, values = [], []
    for starts, lengths, u in jobs:
        sweeps, points = starts.size, u.size
        base = np.floor(starts).astype(np.int32)
        nominal = median(lengths) if sweeps else 0.0
        whole = u * nominal
        lut_int = np.floor(whole)
        # the sweeps' positions and the LUT split at this nominal length
        parts += [(np.int32, sweeps), (np.float32, sweeps), (np.float32, sweeps), (np.int32, points),
                  (np.float32, points)]
        values += [base, starts - base, np.asarray(lengths) - nominal, lut_int, whole - lut_int]
    parts += [(a.dtype, a.size) for a in also]
    buffers = Packed(bufs, "positions", parts).upload(*values, *also)
    d_win = bufs.constant("win", win)
    out = []
    for i, (starts, _, u) in enumerate(jobs):
        sweeps, points = starts.size, u.size
        rows = DeviceRows(bufs, sweeps, points)
        out.append(rows)
        if sweeps == 0:
            continue
        args = (d_codes, *buffers[5 * i: 5 * i + 5], bufs.constant("u", u), d_win, np.int32(points))
        if rt.lanes:
            rt.kernel("resample", "resample_lanes")(rt.queue, (sweeps,), (1,), *args, rows.buffer)
        else:
            rt.kernel("resample", "resample")(rt.queue, (sweeps * GPU_LOCAL,), (GPU_LOCAL,), *args,
                                              rows.buffer, cl.LocalMemory(4 * GPU_LOCAL))
    return out + buffers[5 * len(jobs):]
