"""Small numerics of the host, in numpy alone.

Medians for the host's many small arrays, without np.median's per-call overhead (30-45
us, against 3-4 us for a partition of a few hundred values): the tracker and the echo
tables take them per chunk, per slice and per cluster. A running median and a
Savitzky-Golay derivative that equal scipy.ndimage.median_filter's and
scipy.signal.savgol_filter's: importing those two modules costs a second (scipy.signal
imports scipy.stats), which every fresh process converting a capture paid. Running
medians by bottleneck's double heap (O(log w) a value; a partition of every window was
O(w): 65 pairs over 20 000, 23 ms against 0.9 ms, the same values).
"""

from __future__ import annotations

import functools

import bottleneck as bn
import numpy as np


def median(x: np.ndarray) -> float:
    """np.median of a 1-D array (NaN when it holds a NaN or is empty)."""
    x = np.asarray(x, dtype=np.float64)
    n = x.size
    if n == 0 or np.isnan(x).any():
        return float("nan")
    s = np.partition(x, [(n - 1) // 2, n // 2])
    return 0.5 * float(s[(n - 1) // 2] + s[n // 2])


def group_median(group: np.ndarray, x: np.ndarray, groups: int) -> np.ndarray:
    """`median` of the values `x` of each group 0..`groups` - 1 (`group`: each value's):
    NaN for a group that is empty or holds a NaN. The groups are the rows of one table
    padded to the largest (`row_nanmedian`: a sort of many short rows is 8x faster than
    one of all values by group and value), or, where that table would be mostly padding,
    sorted by one such sort."""
    x = np.asarray(x, np.float64)
    n = np.bincount(group, minlength=groups)
    start = np.cumsum(n) - n
    out = np.full(groups, np.nan)
    if x.size == 0:
        return out
    has = np.flatnonzero((n > 0) & (np.bincount(group, np.isnan(x), minlength=groups) == 0))
    if groups * int(n.max()) > 4 * x.size + 4096:
        s = x[np.lexsort((x, group))]
        out[has] = 0.5 * (s[start[has] + (n[has] - 1) // 2] + s[start[has] + n[has] // 2])
        return out
    if np.any(np.diff(group) < 0):
        by = np.argsort(group, kind="stable")
        group, x = group[by], x[by]
    rows = np.full((groups, int(n.max())), np.nan)
    rows[group, np.arange(x.size) - start[group]] = x
    out[has] = row_nanmedian(rows[has])
    return out


def ragged(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The index ranges [lo, hi) laid end to end: each element's range (0, 1, ...) and
    its index."""
    n = np.maximum(np.asarray(hi) - lo, 0)
    which = np.repeat(np.arange(n.size), n)
    return which, np.arange(which.size) + np.repeat(lo - (np.cumsum(n) - n), n)


def segment_cumsum(x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """np.cumsum of each segment x[lo:hi] (int arrays), laid end to end: the same sums in
    the same order as a cumsum per segment (a cumsum of all, less each segment's start,
    would round otherwise), on rows of tables of segments of like lengths (within 2x)."""
    x = np.asarray(x, np.float64)
    n = np.maximum(np.asarray(hi) - lo, 0)
    out = np.empty(int(n.sum()))
    place = np.cumsum(n) - n
    size = np.ceil(np.log2(np.maximum(n, 1))).astype(np.int64)
    for b in np.unique(size[n > 0]):
        s = np.flatnonzero((size == b) & (n > 0))
        which, k = ragged(lo[s], lo[s] + n[s])
        col = k - np.repeat(lo[s], n[s])
        rows = np.zeros((s.size, int(n[s].max())))
        rows[which, col] = x[k]
        out[place[s][which] + col] = np.cumsum(rows, axis=1)[which, col]
    return out


def row_nanmedian(a: np.ndarray) -> np.ndarray:
    """np.nanmedian(a, axis=1) (NaN for a row of NaN only, without a warning), without
    its masked arrays (10x faster on the tracker's (pairs, 16) predictions): NaNs sort
    last."""
    s = np.sort(a, axis=1)
    n = np.sum(~np.isnan(a), axis=1)
    rows = np.arange(a.shape[0])
    return 0.5 * (s[rows, (n - 1) // 2] + s[rows, n // 2])


def padded(x: np.ndarray, n: int, fill=None) -> np.ndarray:
    """1-D `x` with `n` values more at each end: `fill`, or (None) the end values.
    np.pad(x, n, ...) for the host's many small arrays, without its 20-40 us a call."""
    out = np.empty(x.size + 2 * n, x.dtype)
    out[n: n + x.size] = x
    out[:n] = x[0] if fill is None else fill
    out[n + x.size:] = x[-1] if fill is None else fill
    return out


def neighbour_sums(h: np.ndarray) -> np.ndarray:
    """Each value of the rows of `h` plus its left and right neighbours' (none beyond
    a row's ends)."""
    out = h.copy()
    out[:, 1:] += h[:, :-1]
    out[:, :-1] += h[:, 1:]
    return out


def running_median(x: np.ndarray, size: int, ends: tuple | None = None) -> np.ndarray:
    """Median of each value's `size` (odd) neighbourhood, the ends extended with the end
    values: scipy.ndimage.median_filter(x, size, mode="nearest") for finite x. `ends`:
    each value's first and last index of its segment (int arrays; the segments laid end
    to end), each segment filtered on its own, in one call."""
    half = size // 2
    x = np.asarray(x, np.float64)
    if x.size == 0:
        return np.zeros(0)
    if not np.isfinite(x).all():        # NaN sorts last in a partition; bottleneck skips it
        windows = (np.lib.stride_tricks.sliding_window_view(padded(x, half), size) if ends is None
                   else x[window_index(x.size, half, ends)[0]])
        return np.partition(windows, half, axis=1)[:, half]
    if ends is None:
        return bn.move_median(padded(x, half), size)[size - 1:]
    # each segment padded with its own end values, all filtered in one pass
    first, last = (np.asarray(e, np.int64) for e in ends)
    start = np.flatnonzero(np.r_[True, first[1:] != first[:-1]])
    which, k = ragged(first[start] - half, last[start] + half + 1)
    at = np.arange(x.size) + 2 * half * np.searchsorted(start, np.arange(x.size), "right") - half
    return bn.move_median(x[np.clip(k, first[start][which], last[start][which])], size)[at + half]


def running_nanmedian(x: np.ndarray, size: int, segments: np.ndarray) -> np.ndarray:
    """Median of the finite values of each value's `size` (odd) neighbourhood within its
    segment (`segments`: (R, 2) start, stop; np.nanmedian of each window, NaN where it
    holds none); NaN outside the segments."""
    half = size // 2
    x = np.asarray(x, np.float64)
    out = np.full(x.size, np.nan)
    segments = np.asarray(segments, np.int64).reshape(-1, 2)
    if segments.size == 0:
        return out
    # the segments laid end to end, `half` NaN before each and after the last
    which, k = ragged(segments[:, 0], segments[:, 1])
    n = segments[:, 1] - segments[:, 0]
    at = np.arange(k.size) + half * (which + 1)
    pad = np.full(k.size + half * (n.size + 1), np.nan)
    pad[at] = x[k]
    out[k] = bn.move_median(pad, size, min_count=1)[at + half]
    return out


def window_index(n: int, half: int, ends: tuple, at=slice(None)) -> tuple[np.ndarray, np.ndarray]:
    """The neighbourhoods (2 half + 1 values, centred) of the values `at` of n (a slice or
    indices) within their segments (`ends`: each value's segment's first and last index):
    the (rows, 2 half + 1) indices clipped to the segment, and which lie in it."""
    first, last = (np.asarray(e)[at][:, None] for e in ends)
    idx = np.arange(n)[at][:, None] + np.arange(-half, half + 1)
    return np.clip(idx, first, last), (idx >= first) & (idx <= last)


def savgol_derivative(x: np.ndarray, window: int, order: int, delta: float,
                      spans: np.ndarray | None = None, out: np.ndarray | None = None) -> np.ndarray:
    """First derivative of x (spacing `delta`) by Savitzky-Golay smoothing: the slope of
    the least-squares polynomial of `order` over each centred `window` (odd, at most
    x.size); the first and last window // 2 values from the polynomial fitted to the
    first and last `window` values. scipy.signal.savgol_filter(x, window, order,
    deriv=1, delta=delta, mode="interp").

    `spans` ((R, 2) start, stop; each at least `window` long): each span of x
    differentiated on its own, all at once, into `out` (NaN elsewhere when None)."""
    x = np.asarray(x, np.float64)
    spans = np.array([[0, x.size]]) if spans is None else np.asarray(spans)
    out = np.full(x.size, np.nan) if out is None else out
    if spans.size == 0:
        return out
    half = window // 2
    rows = savgol_rows(window, order) / delta
    a, b = spans[:, 0], spans[:, 1]
    # the centred slopes: a correlation over the whole of x, not a matrix product (BLAS
    # threads: centred_slope), of which each span takes its points a whole window from
    # its ends (a window across a span's end reads values not its own: never taken)
    _, at = ragged(a + half, b - half)
    out[at] = np.correlate(x, rows[half], "valid")[at - half]
    taps = np.arange(window)
    out[a[:, None] + taps[:half]] = x[a[:, None] + taps] @ rows[:half].T
    out[(b - half)[:, None] + taps[:half]] = x[(b - window)[:, None] + taps] @ rows[half + 1:].T
    return out


@functools.lru_cache(maxsize=32)
def savgol_rows(window: int, order: int) -> np.ndarray:
    """(window, window): row j, the weights of a window's values that give the slope at
    its point j (spacing 1) of their least-squares polynomial of `order`."""
    t = np.arange(window, dtype=np.float64) - window // 2
    fit = np.linalg.pinv(np.vander(t, order + 1, increasing=True))      # coefficients of powers of t
    powers = np.arange(order + 1)
    slope = powers * t[:, None] ** np.maximum(powers - 1, 0)            # d/dt of each power at each t
    out = slope @ fit
    out[window // 2] = fit[1]               # the centre's exactly the linear coefficient's
    out.flags.writeable = False
    return out


def runs(mask: np.ndarray) -> np.ndarray:
    """(start, stop) of each run of consecutive True values of `mask`, as rows of an
    (R, 2) array (stop exclusive)."""
    edges = np.flatnonzero(np.diff(np.r_[0, np.asarray(mask, bool).astype(np.int8), 0]))
    return edges.reshape(-1, 2)


def steps(t: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The distance moved (m) from each time of t (s) to the next at velocities v (m/s):
    the trapezoid rule, t.size - 1 steps."""
    return 0.5 * (v[1:] + v[:-1]) * np.diff(t)


def travelled(t: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The distance travelled (m) from t[0] at velocities v (m/s) at times t (s): the
    trapezoidal integral."""
    return np.concatenate([[0.0], np.cumsum(steps(t, v))])


def follows(t: np.ndarray, d: np.ndarray, v: np.ndarray, floor_m: float) -> tuple[bool, float]:
    """Whether distances d (m) at times t (s) follow velocities v (m/s), first to last,
    within `floor_m` + 25 % of the velocities' integral (trapezoids); and that integral
    (m). At least one point."""
    ran = float(np.sum(steps(t, v)))
    return bool(abs(d[-1] - d[0] - ran) <= floor_m + 0.25 * abs(ran)), ran


def centred_slope(t: np.ndarray, r: np.ndarray) -> tuple[float, float, np.ndarray, np.ndarray]:
    """Least-squares slope of r over t; the sum of squares of t about its mean; t and r
    less their means."""
    # sums of products, not np.dot: OpenBLAS spreads a dot product of more than some 10 000
    # values over threads that then spin (a 16-core GPU host: 9 cores busy in a batch)
    tc, rc = t - t.mean(), r - r.mean()
    tt = float(np.sum(tc * tc))
    return float(np.sum(tc * rc)) / tt, tt, tc, rc


def drift(t: np.ndarray, d: np.ndarray, v: np.ndarray, blocks: int = 0) -> tuple[float, float]:
    """Least-squares slope (m/s) of the distances d (m) less the distance travelled at
    the velocities v (m/s) over one run of times t (s), and its standard error: the slope
    is zero for consistent kinematics, whatever the motion. The error is the white
    residuals'; with `blocks` > 1, the larger of it and a jackknife's that leaves each of
    that many blocks of the run out in turn (for distances correlated over pairs)."""
    slope, error = drifts(t, d, v, np.array([t.size]), blocks)
    return float(slope[0]), float(error[0])


def drifts(t: np.ndarray, d: np.ndarray, v: np.ndarray, sizes: np.ndarray, blocks: int = 0
           ) -> tuple[np.ndarray, np.ndarray]:
    """`drift` of each of several runs laid end to end in t, d, v (`sizes` values each,
    at least 2), all in one pass: their slopes (m/s) and errors."""
    sizes = np.asarray(sizes, np.int64)
    count = sizes.size
    label = np.repeat(np.arange(count), sizes)
    start = np.cumsum(sizes) - sizes
    # the distance travelled from each run's start (`steps`, those across runs left
    # out: a run's sums carry no other run's travel, so it is fitted as alone)
    step = np.zeros(t.size)
    step[1:] = steps(t, v)
    step[start] = 0.0
    total = np.cumsum(step)
    r = d - (total - total[start][label])

    def sums(w: np.ndarray) -> np.ndarray:
        return np.bincount(label, w, count)

    tc, rc = t - (sums(t) / sizes)[label], r - (sums(r) / sizes)[label]
    tt = sums(tc * tc)
    slope = sums(tc * rc) / tt
    resid = rc - slope[label] * tc
    error = np.sqrt(sums(resid * resid) / np.maximum(1, sizes - 2) / tt)
    if blocks < 2:
        return slope, error
    # each left-out fit from the sums of the blocks kept (np.array_split's blocks of each
    # run), about the whole run's means
    pos = np.arange(t.size) - start[label]
    q, rem = (sizes // blocks)[label], (sizes % blocks)[label]
    big = rem * (q + 1)                         # the values in the blocks one longer
    block = np.where(pos < big, pos // (q + 1), rem + (pos - big) // np.maximum(q, 1))
    key = label * blocks + block
    kept = [sums(w)[:, None] - np.bincount(key, w, count * blocks).reshape(count, blocks)
            for w in (np.ones(t.size), tc, rc, tc * tc, tc * rc)]
    m, st, sr, stt, str_ = kept
    with np.errstate(divide="ignore", invalid="ignore"):     # a run of fewer than 2 a block: NaN
        loo = (str_ - st * sr / m) / (stt - st * st / m)
        jack = np.sqrt((blocks - 1) / blocks * np.sum(np.square(loo - np.mean(loo, axis=1)[:, None]), axis=1))
    return slope, np.where(jack > error, jack, error)      # NaN: the white residuals'


def nearest_first(miss: np.ndarray) -> list[tuple[int, int]]:
    """(row, column) of `miss` (a cost matrix, inf: not allowed) matched nearest first,
    each row and each column at most once (`matched`)."""
    rows, cols = np.nonzero(np.isfinite(miss))
    return matched(list(zip(miss[rows, cols].tolist(), rows.tolist(), cols.tolist(), strict=True)))


def matched(near: list[tuple[float, int, int]]) -> list[tuple[int, int]]:
    """(row, column) of the candidates `near` ((cost, row, column)) taken nearest first,
    on a tie the lower row, then the lower column; each row and each column at most once."""
    rows: set[int] = set()
    cols: set[int] = set()
    out = []
    for _, i, n in sorted(near):
        if i not in rows and n not in cols:
            out.append((i, n))
            rows.add(i)
            cols.add(n)
    return out


def nearest(sorted_a: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Index of the element of `sorted_a` (ascending, not empty) nearest to each of
    `x`; on a tie the lower one."""
    j = np.searchsorted(sorted_a, x)
    below, above = np.clip(j - 1, 0, sorted_a.size - 1), np.clip(j, 0, sorted_a.size - 1)
    return np.where(np.abs(sorted_a[below] - x) <= np.abs(sorted_a[above] - x), below, above)
