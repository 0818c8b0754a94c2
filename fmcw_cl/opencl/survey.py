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
    return hidden_each(rt, bufs, [(plain, dechirped, tracked_bin, plain_bin, others)], lo)[0]


def upload(bufs: Buffers, bins: list, head: tuple = ()) -> list:
    """The arrays of `head`, then each (tracked_bin, plain_bin, others) of `bins` (float32),
    up by one copy: their sub-buffers in that order (`hidden_each`'s `inputs` after the
    head's)."""
    parts, values = [(a.dtype, a.size) for a in head], list(head)
    for tracked_bin, plain_bin, others in bins:
        parts += [(np.float32, np.size(a)) for a in (tracked_bin, plain_bin, others)]
        values += [tracked_bin, plain_bin, np.ravel(others)]
    return Packed(bufs, "survey_in", parts).upload(*values)


def hidden_each(rt: Runtime, bufs: Buffers, jobs: list, lo: int, inputs: list | None = None) -> list[tuple]:
    """`hidden` of each (plain, dechirped, tracked_bin, plain_bin, others) of `jobs` (a
    pair's two directions): their inputs go up in one copy (`inputs`: already up, from
    `upload`), their results come back in one."""
    if inputs is None:
        inputs = upload(bufs, [job[2:] for job in jobs])
    outputs = []
    for plain, _, _, _, _ in jobs:
        rows = plain.shape[0]
        outputs += [(np.float32, rows), (np.float32, rows), (np.int32, rows)]
    out = Packed(bufs, "survey_out", outputs)
    lsz = rt.group_size(16, 256)
    rules = (np.int32(echoes.EXPLAIN_BINS), np.float32(echoes.SHARP),
             np.float32(10 ** (-echoes.RIVAL_DB / 10)), np.float32(echoes.HIDDEN_SIGMAS))
    for i, (plain, dechirped, _, _, others) in enumerate(jobs):
        (rows, half), m = plain.shape, others.shape[1]
        if rows == 0:
            continue
        d_tracked, d_plain_bin, d_others = inputs[3 * i: 3 * i + 3]
        results = out.buffers[3 * i: 3 * i + 3]
        band = half - lo
        if rt.lanes:
            rt.kernel("survey", "hidden_lanes")(
                rt.queue, (-(-rows // 8),), (1,), plain.buffer, dechirped.buffer, np.int32(half),
                np.int32(lo), np.int32(rows), d_tracked, d_plain_bin, d_others, np.int32(m), *rules, *results,
                cl.LocalMemory(32 * band), cl.LocalMemory(32 * band), cl.LocalMemory(32 * max(m, 1)))
        else:
            rt.kernel("survey", "hidden")(
                rt.queue, (rows * lsz,), (lsz,), plain.buffer, dechirped.buffer, np.int32(half), np.int32(lo),
                d_tracked, d_plain_bin, d_others, np.int32(m), *rules, *results,
                cl.LocalMemory(4 * band), cl.LocalMemory(24 * lsz), cl.LocalMemory(8))
    if all(plain.shape[0] == 0 for plain, *_ in jobs):
        return [(np.zeros(0), np.zeros(0), np.zeros(0, bool))] * len(jobs)
    got = out.download()
    return [(ratio.astype(np.float64), centroid.astype(np.float64), found.astype(bool))
            for ratio, centroid, found in zip(got[0::3], got[1::3], got[2::3], strict=True)]
