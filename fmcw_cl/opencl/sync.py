"""Launchers of kernels/sync.cl (twins: fmcw_cl.stages.sync.block_sums, levels,
changes and coarse_crossings, line_fits: together sync.fitted)."""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np

from ..stages import sync
from .buffers import Buffers, Packed
from .context import Runtime, cl


def _codes(bufs: Buffers, x: np.ndarray):
    if x.dtype != np.int16:
        raise TypeError("the sync kernels take int16 ADC codes")
    return bufs.upload_once("sync_codes", x)


SPAN = 512      # blocks a work-item of the span kernels
HEADER = 8      # ints of the search's header (kernels/sync.cl)
LEVEL_LOCAL = 4 * (2048 + 2)    # sync_levels' histogram


def slots(factor: int, half_period: float) -> int:
    """Crossings kept per span of SPAN blocks: a triangle crosses its level once a
    half-period, twice the most a span can hold and some (more: the host redoes the
    search)."""
    return 2 * int(np.ceil(SPAN * factor / half_period)) + 8


def levels(rt: Runtime, d_sampled, n: int, d_head) -> None:
    """Launch sync_levels: 20 factor times the 5 and 95 percentiles of the n >= 1 sampled
    sums and the band's thresholds into head[0:5] (twin: sync.percentile_sums, levels)."""
    lsz = 1 if rt.lanes else rt.group_size(16, 256)    # PoCL: one item loops without barriers' cost
    rt.kernel("sync", "sync_levels")(rt.queue, (lsz,), (lsz,), d_sampled, np.int32(n), d_head,
                                     cl.LocalMemory(LEVEL_LOCAL))


def fitted(rt: Runtime, bufs: Buffers, x: np.ndarray, half_period: float) -> sync.Fitted:
    """sync.fitted on the device, from the codes to both line fits of every crossing
    (`launch_fits`), by one copy: the level's percentiles and each span's crossings."""
    launched = launch_fits(rt, bufs, x, half_period)
    if launched is None:
        return sync.fitted(x, half_period, fits=functools.partial(line_fits, rt, bufs))
    packed, finish = launched
    return finish(packed.download())


def launch_fits(rt: Runtime, bufs: Buffers, x: np.ndarray, half_period: float, riders: tuple = ()
                ) -> tuple[Packed, Callable[[list], sync.Fitted]] | None:
    """The launches of sync.fitted: the block sums, the level, the hysteresis (three
    launches over spans of SPAN blocks), the fits, writing into a Packed (with `riders`)
    that is not yet downloaded; and `finish(views)`, the Fitted from its parts once down
    (None: x holds no block, the host searches it). A span with more crossings than its
    slots (no triangle) makes `finish` redo the search from the sums (sync.changes,
    coarse_crossings) and fit its centres (`line_fits`)."""
    half = sync.fit_half_width(half_period)
    factor = sync.block_length(half_period)
    m = x.size // factor
    if m == 0:
        return None
    stride = sync.level_stride(m)
    n = -(-m // stride)
    spans = -(-m // SPAN)
    cap = slots(factor, half_period)
    packed = Packed(bufs, "sync_fitted", [(np.int32, HEADER), (np.int32, spans * (cap + 1)),
                                          (np.int64, 3 * spans * cap)], riders)
    d_head, d_direction, d_fits = packed.buffers
    d_sums, d_sampled = bufs.get("block_sums", 4 * m), bufs.get("block_sampled", 4 * n)
    d_ends, d_centre = bufs.get("sync_ends", 16 * spans), bufs.get("sync_centres", 4 * spans * cap)
    d_params = bufs.get("fit_params", 16)
    codes = _codes(bufs, x)
    if rt.lanes:                        # CPUs: a work-item a span of blocks
        rt.kernel("sync", "block_sum_span")(rt.queue, (spans,), (1,), codes, np.int32(factor), np.int32(m),
                                            np.int32(stride), np.int32(SPAN), d_sums, d_sampled)
    else:
        rt.kernel("sync", "block_sum")(rt.queue, *rt.items(m), codes, np.int32(factor), np.int32(m),
                                       np.int32(stride), d_sums, d_sampled)
    levels(rt, d_sampled, n, d_head)
    each = ((spans,), (1,)) if rt.lanes else rt.items(spans)
    rt.kernel("sync", "span_ends")(rt.queue, *each, d_sums, np.int32(m), np.int32(SPAN), d_head, d_ends)
    rt.kernel("sync", "span_carries")(rt.queue, (1,), (1,), d_ends, np.int32(spans), d_head, np.int32(factor),
                                      rt.real(sync.SPIKE), d_params)
    rt.kernel("sync", "span_crossings")(rt.queue, *each, d_sums, np.int32(m), np.int32(SPAN), d_head, d_ends,
                                        np.int32(factor), np.int32(half), np.int32(x.size), np.int32(cap),
                                        d_centre, d_direction)
    _launch_fits(rt, codes, d_centre, spans * cap, half, d_params, x.size, d_fits)

    def finish(views: list) -> sync.Fitted:
        head, direction, fits = views
        lv = sync.levels_of(int(head[0]), int(head[1]), factor)
        direction = direction.reshape(spans, cap + 1)
        count = direction[:, cap]
        if count.max(initial=0) > cap:      # not a triangle's crossings: the host redoes them
            sums = np.empty(m, np.int32)
            rt.copy(sums, d_sums)
            co = sync.coarse_crossings(sync.changes(sums.astype(np.float64), lv), lv, factor)
            return sync.fitted(x, half_period, coarse=lambda *_: co,
                               fits=functools.partial(line_fits, rt, bufs))
        used = (np.arange(cap) < count[:, None]).ravel()
        fits = fits.reshape(-1, 3)[used]
        return sync.Fitted(fits[:, 0], fits[:, 1].astype(np.float64), fits[:, 2].astype(np.float64),
                           direction[:, :cap].ravel()[used].astype(np.int8), lv.level)

    return packed, finish


def _launch_fits(rt: Runtime, codes, d_centre, n: int, half: int, d_params, size: int, d_out) -> None:
    """Both line fits of the n centres of d_centre (-1: none), into d_out (n, 3) int64."""
    flush = np.int32(max(1, (2**31 - 1) // (max(half, 1) * 32768 + 32768)))
    args = (codes, d_centre, np.int32(half), d_params, flush, np.int32(size), d_out)
    if rt.lanes:
        rt.kernel("sync", "line_fit_lanes")(rt.queue, (n,), (1,), *args)   # a work-item a crossing
    else:
        lsz = rt.group_size(16, 128)
        rt.kernel("sync", "line_fit")(rt.queue, (n * lsz,), (lsz,), *args, cl.LocalMemory(8 * lsz),
                                      cl.LocalMemory(8 * lsz))


def line_fits(rt: Runtime, bufs: Buffers, x: np.ndarray, centre: np.ndarray, half: int, spike: float,
              level: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Both line fits of each of the given centres in one launch (twin: sync.line_fits;
    codes are integers, so `|d| > spike` is `|d| > floor(spike)`): the centres, level and
    spike threshold up in one copy, the last fit's centre (-1: dropped) and sums down in
    one."""
    n = centre.size
    out = np.empty((n, 3), np.int64)
    if n:
        d = bufs.get("fit_sums", out.nbytes)
        parts = [(np.int32, n), (rt.real, 2)]
        d_centre, d_params = Packed(bufs, "fit_in", parts).upload(centre, [level, spike])
        _launch_fits(rt, _codes(bufs, x), d_centre, n, half, d_params, x.size, d)
        rt.copy(out, d)
    return out[:, 0], out[:, 1].astype(np.float64), out[:, 2].astype(np.float64)
