"""Launcher of kernels/delay.cl (twins: fmcw_cl.stages.delay.period_delays, fit_periods)."""

from __future__ import annotations

import numpy as np

from ..stages import delay, lpf
from . import lpf as k_lpf
from .buffers import Buffers, Packed
from .context import Runtime, cl

CENTRE_LOCAL = 256   # work-items a row of delay_centre on GPUs


def period_delays(rt: Runtime, bufs: Buffers, beat: np.ndarray, sy: np.ndarray, sample_rate_hz: float,
                  half_period: float) -> tuple[np.ndarray, np.ndarray]:
    """delay.period_delays on the device, from the codes to the per-period lags and
    misfits: the low-pass (kernels/lpf.cl), each row trimmed and centred, its coarse lag,
    the fits; nothing goes up (the codes: once, none on a CPU device), one copy comes down."""
    low, shapes = k_lpf.launch(rt, bufs, [beat, sy], sample_rate_hz)
    rows, m = shapes[0][0] if len(shapes[0]) == 2 else 1, shapes[0][-1]
    step = float(lpf.DECIMATION)
    got = delay.delay_windows((rows, m), step, half_period)
    if got is None:
        return np.zeros(0), np.zeros(0)
    edge, span, period = got
    n = m - 2 * edge
    yz = bufs.get("delay_yz", 8 * rows * n)
    lags = 2 * span + 1
    d_c, coarse = bufs.get("delay_c", 8 * rows * lags), bufs.get("delay_coarse", 4 * rows)
    # a row a work-group (CPUs: of one work-item): on an H100 a row a work-item took 5.7 ms,
    # the most of any kernel of a capture
    lsz = 1 if rt.lanes else min(CENTRE_LOCAL, rt.device.max_work_group_size)
    part = cl.LocalMemory(np.dtype(rt.real).itemsize * lsz)
    rt.kernel("delay", "delay_centre")(rt.queue, (2 * rows * lsz,), (lsz,), *low.buffers, np.int32(m),
                                       np.int32(rows), np.int32(edge), yz, part)
    rt.kernel("delay", "delay_correlate")(rt.queue, *rt.items(rows * lags), yz, np.int32(n), np.int32(rows),
                                          np.int32(span), d_c)
    rt.kernel("delay", "delay_coarse")(rt.queue, *rt.items(rows), d_c, np.int32(rows), np.int32(span), coarse)
    out = _fit(rt, bufs, yz, n, rows, coarse, period, span)
    return (out[0].astype(np.float64) * step).ravel(), out[1].ravel().astype(np.float64)


def fit_periods(rt: Runtime, bufs: Buffers, y: np.ndarray, z: np.ndarray, shift: np.ndarray, period: int,
                span: int) -> tuple[np.ndarray, np.ndarray]:
    """The Gauss-Newton fit of every period of every row, a work-item each: the rows
    (beat and sync) and their coarse lags go up in one copy, lags and misfits come back in
    one."""
    rows, n = y.shape
    packed = Packed(bufs, "delay_in", [(np.float32, 2 * rows * n), (np.float32, rows)])
    yz, coarse = packed.views
    yz.reshape(2, rows, n)[:] = y, z
    coarse[:] = shift
    d_yz, d_coarse = packed.send()
    out = _fit(rt, bufs, d_yz, n, rows, d_coarse, period, span)
    return out[0].astype(np.float64), out[1].astype(np.float64)


def _fit(rt: Runtime, bufs: Buffers, d_yz, n: int, rows: int, d_coarse, period: int, span: int) -> np.ndarray:
    """delay_fit of the centred rows `d_yz` (2, rows, n) from their coarse lags, its lags
    and misfits (2, rows, periods) by one copy."""
    periods = delay.period_starts(n, period, span).size      # the kernel's w = span + p period
    out = np.empty((2, rows, periods), np.float32)
    if out.size:
        d_out = bufs.get("delay_out", out.nbytes)
        rt.kernel("delay", "delay_fit")(rt.queue, *rt.items(rows * periods), d_yz, np.int32(n),
                                        np.int32(rows), np.int32(periods), np.int32(period), np.int32(span),
                                        d_coarse, d_out)
        rt.copy(out, d_out)
    return out
