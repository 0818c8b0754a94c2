"""Launcher of kernels/delay.cl (twin: fmcw_cl.stages.sync.fit_periods)."""

from __future__ import annotations

import numpy as np

from ..stages import sync
from .buffers import Buffers, Packed
from .context import Runtime


def fit_periods(rt: Runtime, bufs: Buffers, y: np.ndarray, z: np.ndarray, shift: np.ndarray, period: int,
                span: int) -> tuple[np.ndarray, np.ndarray]:
    """The Gauss-Newton fit of every period of every row, a work-item each: the rows
    (beat and sync) and their coarse lags go up in one copy, lags and misfits come back in
    one."""
    rows, n = y.shape
    periods = sync.period_starts(n, period, span).size      # the kernel's w = span + p period
    out = np.empty((2, rows, periods), np.float32)
    if out.size:
        packed = Packed(bufs, "delay_in", [(np.float32, 2 * rows * n), (np.float32, rows)])
        yz, coarse = packed.views
        yz.reshape(2, rows, n)[:] = y, z
        coarse[:] = shift
        d_yz, d_coarse = packed.send()
        d_out = bufs.get("delay_out", out.nbytes)
        rt.kernel("delay", "delay_fit")(rt.queue, *rt.items(rows * periods), d_yz, np.int32(n),
                                        np.int32(rows), np.int32(periods), np.int32(period), np.int32(span),
                                        d_coarse, d_out)
        rt.copy(out, d_out)
    return out[0].astype(np.float64), out[1].astype(np.float64)
