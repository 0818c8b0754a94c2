"""Launcher of kernels/survey.cl (twin: fmcw_cl.echoes.hidden)."""

from __future__ import annotations

import numpy as np

from .. import echoes
from .buffers import Buffers, DeviceRows
from .context import Runtime, cl


def hidden(rt: Runtime, bufs: Buffers, plain: DeviceRows, dechirped: DeviceRows, lo: int,
           tracked_bin: np.ndarray, plain_bin: np.ndarray, others: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(ratio, centroid, found) of each row's spectra left on the device (see the twin)."""
    rows, half = plain.shape
    if rows == 0:
        return np.zeros(0), np.zeros(0), np.zeros(0, bool)
    lsz = rt.group_size(16, 256)
    out = [bufs.get(name, 4 * rows) for name in ("survey_ratio", "survey_centroid", "survey_found")]
    rt.kernel("survey", "hidden")(
        rt.queue, (rows * lsz,), (lsz,), plain.buffer, dechirped.buffer, np.int32(half), np.int32(lo),
        bufs.upload("survey_tracked", np.asarray(tracked_bin, np.float32)),
        bufs.upload("survey_plain_bin", np.asarray(plain_bin, np.float32)),
        bufs.upload("survey_others", np.ascontiguousarray(others, np.float32)), np.int32(others.shape[1]),
        np.int32(echoes.EXPLAIN_BINS), np.float32(echoes.SHARP), np.float32(10 ** (-echoes.RIVAL_DB / 10)),
        np.float32(echoes.HIDDEN_SIGMAS), *out, cl.LocalMemory(4 * (half - lo)), cl.LocalMemory(24 * lsz),
        cl.LocalMemory(8))
    got = np.empty(rows, np.float32), np.empty(rows, np.float32), np.empty(rows, np.int32)
    for host, dev in zip(got, out, strict=True):
        rt.copy(host, dev)
    return got[0].astype(np.float64), got[1].astype(np.float64), got[2].astype(bool)
