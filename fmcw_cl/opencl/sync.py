"""Launchers of kernels/sync.cl (twins: fmcw_cl.stages.sync.block_means, line_fit_sums)."""

from __future__ import annotations

import numpy as np

from .buffers import Buffers
from .context import Runtime, cl


def _codes(bufs: Buffers, x: np.ndarray):
    if x.dtype != np.int16:
        raise TypeError("the sync kernels take int16 ADC codes")
    return bufs.upload_once("sync_codes", x)


def block_means(rt: Runtime, bufs: Buffers, x: np.ndarray, factor: int) -> np.ndarray:
    """Means of the whole blocks of `factor` codes, float64 (exact)."""
    m = x.size // factor
    out = np.empty(m, np.float32)
    if m:
        d_out = bufs.get("block_means", out.nbytes)
        rt.kernel("sync", "block_sum")(rt.queue, (m,), None, _codes(bufs, x), np.int32(factor), d_out)
        rt.copy(out, d_out)
    return out.astype(np.float64) / factor


def line_fit_sums(rt: Runtime, bufs: Buffers, x: np.ndarray, centre: np.ndarray, half: int,
                  spike: float) -> tuple[np.ndarray, np.ndarray]:
    """Sums of x and (i - c) x around each centre, spikes replaced (see the twin; codes
    are integers, so `|d| > spike` is `|d| > floor(spike)`)."""
    n = centre.size
    s0 = np.empty(n, np.int64)
    s1 = np.empty(n, np.int64)
    if n:
        lsz = rt.group_size(16, 128)
        d0, d1 = bufs.get("fit_sum0", s0.nbytes), bufs.get("fit_sum1", s1.nbytes)
        rt.kernel("sync", "line_fit")(
            rt.queue, (n * lsz,), (lsz,), _codes(bufs, x),
            bufs.upload("fit_centre", centre.astype(np.int32)), np.int32(half), np.int32(np.floor(spike)),
            np.int32(max(1, (2**31 - 1) // (max(half, 1) * 32768 + 32768))),
            d0, d1, cl.LocalMemory(8 * lsz), cl.LocalMemory(8 * lsz))
        rt.copy(s0, d0)
        rt.copy(s1, d1)
    return s0.astype(np.float64), s1.astype(np.float64)
