"""Launcher of kernels/survey.cl (twin: fmcw_cl.echoes.hidden)."""

from __future__ import annotations

import numpy as np

from .. import echoes
from .buffers import Buffers, DeviceRows, Packed
from .context import Runtime, cl


def hidden(rt: Runtime, bufs: Buffers, plain: DeviceRows, dechirped: DeviceRows, lo: int,
           tracked_bin: np.ndarray, plain_bin: np.ndarray, others: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(ratio, centroid, found) of each row's spectra left on the device (see the twin)."""
    rows, half = plain.shape
    if rows == 0:
        return np.zeros(0), np.zeros(0), np.zeros(0, bool)
    lsz = rt.group_size(16, 256)
    m = others.shape[1]
    inputs = Packed(bufs, "survey_in", [(np.float32, rows), (np.float32, rows), (np.float32, rows * m)])
    out = Packed(bufs, "survey_out", [(np.float32, rows), (np.float32, rows), (np.int32, rows)])
    d_tracked, d_plain_bin, d_others = inputs.upload(tracked_bin, plain_bin, others.ravel())
    rules = (np.int32(echoes.EXPLAIN_BINS), np.float32(echoes.SHARP),
             np.float32(10 ** (-echoes.RIVAL_DB / 10)), np.float32(echoes.HIDDEN_SIGMAS))
    band = half - lo
    if rt.lanes:
        rt.kernel("survey", "hidden_lanes")(
            rt.queue, (-(-rows // 8),), (1,), plain.buffer, dechirped.buffer, np.int32(half), np.int32(lo),
            np.int32(rows), d_tracked, d_plain_bin, d_others, np.int32(m), *rules, *out.buffers,
            cl.LocalMemory(32 * band), cl.LocalMemory(32 * band), cl.LocalMemory(32 * max(m, 1)))
    else:
        rt.kernel("survey", "hidden")(
            rt.queue, (rows * lsz,), (lsz,), plain.buffer, dechirped.buffer, np.int32(half), np.int32(lo),
            d_tracked, d_plain_bin, d_others, np.int32(m), *rules, *out.buffers, cl.LocalMemory(4 * band),
            cl.LocalMemory(24 * lsz), cl.LocalMemory(8))
    ratio, centroid, found = out.download()
    return ratio.astype(np.float64), centroid.astype(np.float64), found.astype(bool)
