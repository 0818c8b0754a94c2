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


def input_arrays(bins: list, head: tuple = ()) -> list[np.ndarray]:
    """The arrays of `head`, then each (tracked_bin, plain_bin, others) of `bins` as
    float32, in the order `hidden_each` reads them (its `inputs` after the head's)."""
    out = list(head)
    for tracked_bin, plain_bin, others in bins:
        out += [np.asarray(a, np.float32).ravel() for a in (tracked_bin, plain_bin, others)]
    return out


def upload(bufs: Buffers, bins: list, head: tuple = ()) -> list:
    """`input_arrays`, up by one copy: their sub-buffers in that order."""
    arrays = input_arrays(bins, head)
    return Packed(bufs, "survey_in", [(a.dtype, a.size) for a in arrays]).upload(*arrays)


def parts(counts: list[int], half: int) -> list:
    """The (dtype, count) of what `hidden_each` writes for jobs of `counts` rows of
    `half` bins each: their ratio, centroid and found, and their plain spectra's
    echoes.block_sums, in order."""
    return [(dtype, n) for rows in counts
            for dtype, n in ((np.float32, rows), (np.float32, rows), (np.int32, rows),
                             (np.float32, echoes.block_rows(rows).size * half))]


def hidden_each(rt: Runtime, bufs: Buffers, jobs: list, lo: int, inputs: list | None = None,
                out: Packed | None = None, first: int = 0) -> list[tuple] | None:
    """`hidden` of each (plain, dechirped, tracked_bin, plain_bin, others) of `jobs` (a
    pair's two directions): their inputs go up in one copy (`inputs`: already up, from
    `upload`), their results come back in one. With `out` (a Packed whose parts from
    `first` on are `parts`') the results stay there and nothing comes back (None:
    `results` reads them after its download)."""
    if inputs is None:
        inputs = upload(bufs, [job[2:] for job in jobs])
    deferred = out is not None
    if out is None:
        out = Packed(bufs, "survey_out", parts([plain.shape[0] for plain, *_ in jobs], jobs[0][0].shape[1]))
    lsz = rt.group_size(16, 256)
    rules = (np.int32(echoes.EXPLAIN_BINS), np.float32(echoes.SHARP),
             np.float32(10 ** (-echoes.RIVAL_DB / 10)), np.float32(echoes.HIDDEN_SIGMAS))
    for i, (plain, dechirped, _, _, others) in enumerate(jobs):
        (rows, half), m = plain.shape, others.shape[1]
        if rows == 0:
            continue
        d_tracked, d_plain_bin, d_others = inputs[3 * i: 3 * i + 3]
        at = first + 4 * i
        written, sums = out.buffers[at: at + 3], out.buffers[at + 3]
        band = half - lo
        # the lanes' bands take `width` times the local memory: a GPU made to run them
        # (the tests' variants) may not hold them, and runs the work-groups' kernel
        lane = 4 * rt.width
        if rt.lanes and lane * (2 * band + max(m, 1)) <= rt.device.local_mem_size:
            rt.kernel("survey", "hidden_lanes")(
                rt.queue, (-(-rows // rt.width),), (1,), plain.buffer, dechirped.buffer, np.int32(half),
                np.int32(lo), np.int32(rows), d_tracked, d_plain_bin, d_others, np.int32(m), *rules, *written,
                cl.LocalMemory(lane * band), cl.LocalMemory(lane * band), cl.LocalMemory(lane * max(m, 1)))
        else:
            rt.kernel("survey", "hidden")(
                rt.queue, (rows * lsz,), (lsz,), plain.buffer, dechirped.buffer, np.int32(half), np.int32(lo),
                d_tracked, d_plain_bin, d_others, np.int32(m), *rules, *written,
                cl.LocalMemory(4 * band), cl.LocalMemory(24 * lsz), cl.LocalMemory(8))
        (bins,), (group,) = rt.items(half)
        blocks = echoes.block_rows(rows).size
        rt.kernel("survey", "block_sums")(rt.queue, (bins, blocks), (group, 1), plain.buffer, np.int32(half),
                                          np.int32(rows), np.int32(echoes.MEAN_ROWS), sums)
    if deferred:
        return None
    if all(plain.shape[0] == 0 for plain, *_ in jobs):
        return [(np.zeros(0), np.zeros(0), np.zeros(0, bool), np.zeros((0, jobs[0][0].shape[1])))] * len(jobs)
    return results(out.download())


def results(views: list) -> list[tuple]:
    """`hidden_each`'s (ratio, centroid, found, block sums) of each job from the host
    views of its `parts`."""
    out = []
    for ratio, centroid, found, sums in zip(*(views[i::4] for i in range(4)), strict=True):
        blocks = echoes.block_rows(ratio.size).size
        out.append((ratio.astype(np.float64), centroid.astype(np.float64), found.astype(bool),
                    sums.astype(np.float64).reshape(blocks, -1) if blocks else np.zeros((0, 0))))
    return out
