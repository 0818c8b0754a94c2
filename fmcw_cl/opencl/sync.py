"""Launchers of kernels/sync.cl (twins: fmcw_cl.stages.sync.block_sums, levels,
changes, coarse_from_codes and line_fits)."""

from __future__ import annotations

import numpy as np

from ..stages import sync
from .buffers import Buffers, Packed
from .context import Runtime, cl


def _codes(bufs: Buffers, x: np.ndarray):
    if x.dtype != np.int16:
        raise TypeError("the sync kernels take int16 ADC codes")
    return bufs.upload_once("sync_codes", x)


SPAN = 512     # blocks a work-item of the span kernels (CPU devices)


def capacities(blocks: int) -> tuple[int, int]:
    """Entries kept of the band and side changes: a triangle of at least 40 blocks a
    half-period changes band twice and side once per crossing, well within these."""
    return blocks // 8 + 64, blocks // 16 + 64


HEADER = 8      # ints before the lists of crossing_changes' output (kernels/sync.cl)
LEVEL_LOCAL = 4 * (2048 + 2)    # sync_levels' histogram


def levels(rt: Runtime, d_sampled, n: int, d_out) -> None:
    """Launch sync_levels: 20 factor times the 5 and 95 percentiles of the n >= 1 sampled
    sums and the band's thresholds into out[2:7] (twin: sync.percentile_sums, levels)."""
    lsz = 1 if rt.lanes else rt.group_size(16, 256)    # PoCL: one item loops without barriers' cost
    rt.kernel("sync", "sync_levels")(rt.queue, (lsz,), (lsz,), d_sampled, np.int32(n), d_out,
                                     cl.LocalMemory(LEVEL_LOCAL))


def coarse(rt: Runtime, bufs: Buffers, x: np.ndarray, factor: int, riders: tuple = ()) -> sync.Coarse:
    """sync.coarse_from_codes with the block sums, the level and their changes on the
    device: what comes back, by one copy, is the level's percentiles and the sparse
    changes, and `riders` (buffers.Rider: another step's small results, such as the
    chunk's clipping counts; not launched where x holds no block)."""
    m = x.size // factor
    if m == 0:
        return sync.coarse_from_sums(np.zeros(0), factor)
    stride = sync.level_stride(m)
    n = -(-m // stride)
    cap_e, cap_s = capacities(m)
    packed = Packed(bufs, "crossing_changes", [(np.int32, HEADER + 2 * cap_e + 3 * cap_s)], riders)
    d_out = packed.buffers[0]                               # its counters zeroed by block_sum
    d_sums, d_sampled = bufs.get("block_sums", 4 * m), bufs.get("block_sampled", 4 * n)
    if rt.lanes:                        # CPUs: a work-item a span of blocks (the span an argument)
        suffix, sizes, span = "_span", ((-(-m // SPAN),), (1,)), (np.int32(SPAN),)
    else:
        suffix, sizes, span = "", rt.items(m), ()
    rt.kernel("sync", "block_sum" + suffix)(rt.queue, *sizes, _codes(bufs, x), np.int32(factor), np.int32(m),
                                            np.int32(stride), *span, d_sums, d_sampled, d_out)
    levels(rt, d_sampled, n, d_out)
    rt.kernel("sync", "crossing_changes" + suffix)(rt.queue, *sizes, d_sums, np.int32(m), np.int32(cap_e),
                                                   np.int32(cap_s), *span, d_out)
    out = packed.download()[0]
    n_e, n_s = int(out[0]), int(out[1])
    lv = sync.levels_of(int(out[2]), int(out[3]), factor)
    if n_e > cap_e or n_s > cap_s:      # not a triangle's changes: the host redoes them
        sums = np.empty(m, np.int32)
        rt.copy(sums, d_sums)
        return sync.coarse_crossings(sync.changes(sums.astype(np.float64), lv), lv, factor)
    events = out[HEADER: HEADER + 2 * n_e].reshape(n_e, 2)
    sides = out[HEADER + 2 * cap_e: HEADER + 2 * cap_e + 3 * n_s].reshape(n_s, 3)
    # appended in any order, nearly sorted (a block each, blocks run in order): merge sort
    # of the runs is twice as fast as quicksort
    events = events[np.argsort(events[:, 0], kind="stable")]
    sides = sides[np.argsort(sides[:, 0], kind="stable")].astype(np.float64)
    ch = sync.Changes(events[:, 0].astype(np.int64), events[:, 1].astype(np.int8),
                      sides[:, 0].astype(np.int64), sides[:, 1], sides[:, 2])
    return sync.coarse_crossings(ch, lv, factor)


def line_fits(rt: Runtime, bufs: Buffers, x: np.ndarray, centre: np.ndarray, half: int, spike: float,
              level: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Both line fits of each crossing in one launch: the last fit's centre (-1:
    dropped) and its sums of x and (i - c) x, spikes replaced (see the twin; codes are
    integers, so `|d| > spike` is `|d| > floor(spike)`)."""
    n = centre.size
    out = np.empty((n, 3), np.int64)
    if n:
        d = bufs.get("fit_sums", out.nbytes)
        real = np.float64 if rt.fp64 else np.float32
        args = (_codes(bufs, x), bufs.upload("fit_centre", centre.astype(np.int32)), np.int32(half),
                np.int32(np.floor(spike)), np.int32(max(1, (2**31 - 1) // (max(half, 1) * 32768 + 32768))),
                real(level), np.int32(x.size), d)
        if rt.lanes:
            rt.kernel("sync", "line_fit_lanes")(rt.queue, (n,), (1,), *args)   # a work-item a crossing
        else:
            lsz = rt.group_size(16, 128)
            rt.kernel("sync", "line_fit")(rt.queue, (n * lsz,), (lsz,), *args, cl.LocalMemory(8 * lsz),
                                          cl.LocalMemory(8 * lsz))
        rt.copy(out, d)
    return out[:, 0], out[:, 1].astype(np.float64), out[:, 2].astype(np.float64)
