"""Launcher of kernels/resample.cl (twin: fmcw_cl.stages.resample.resample)."""

from __future__ import annotations

import numpy as np

from ..numeric import median
from .buffers import Buffers, DeviceRows, Packed
from .context import Runtime, cl

GPU_LOCAL = 128     # work-items of `resample`'s groups (a half-sweep each)


def resample(rt: Runtime, bufs: Buffers, codes: np.ndarray, starts: np.ndarray,
             lengths: np.ndarray, u: np.ndarray, win: np.ndarray) -> DeviceRows:
    """Resampled, mean-removed, windowed half-sweeps, (S, N) float32 left on the device
    (see the numpy twin). The codes are uploaded once for all launches on one array."""
    sweeps, points = starts.size, u.size
    base = np.floor(starts).astype(np.int32)
    offset = (starts - base).astype(np.float32)
    nominal = median(lengths) if sweeps else 0.0
    whole = u * nominal
    lut_int = np.floor(whole)
    d_codes = bufs.upload_once("codes", codes if codes.dtype == np.int16 else codes.astype(np.int16))
    # the sweeps' positions and the LUT split at this nominal length: one upload
    positions = Packed(bufs, "positions", [(np.int32, sweeps), (np.float32, sweeps), (np.float32, sweeps),
                                           (np.int32, points), (np.float32, points)])
    d_base, d_off, d_dlen, d_int, d_frac = positions.upload(base, offset, np.asarray(lengths) - nominal,
                                                            lut_int, whole - lut_int)
    d_u = bufs.constant("u", u)
    d_win = bufs.constant("win", win)
    out = DeviceRows(bufs, sweeps, points)
    if sweeps == 0:
        return out
    args = (d_codes, d_base, d_off, d_dlen, d_int, d_frac, d_u, d_win, np.int32(points))
    if rt.lanes:
        rt.kernel("resample", "resample_lanes")(rt.queue, (sweeps,), (1,), *args, out.buffer)
    else:
        rt.kernel("resample", "resample")(rt.queue, (sweeps * GPU_LOCAL,), (GPU_LOCAL,), *args, out.buffer,
                                          cl.LocalMemory(4 * GPU_LOCAL))
    return out
