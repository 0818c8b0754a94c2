"""Stage 2: turning points of the modulation, aligned to the optics, and segmentation.

Mid-level crossings of a triangle are where its slope is steepest, so they are the
noise-robust timing marks: each is located to a small fraction of a sample by a
straight-line fit over most of the half-sweep, and a turning point is the midpoint
of the two crossings around it (exact for a symmetric triangle, whatever the level).
The turning times of one unbroken stretch are then fitted by a uniform grid (the
period refined from the data); a gap or jump in the grid (dropped samples, a flat
sync) splits the stream into segments. The delay by which the sync lags the optics
is stages.delay's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from ..numeric import centred_slope, median

FIT_FRACTION = 0.10   # half-width of the crossing line fit, as a share of the half-period (a
# crossing to about 0.1 sample at 4 codes of sync noise; the uniform grid fitted to a segment's
# turning points averages them: 0.35 gave the same tracks at 3.5x the cost)
SPACING_TOLERANCE = 0.25  # two crossings' spacing off the nominal half-period, share: the period
# (plan.PERIOD_TOLERANCE: 3 %) and a level off the middle by up to 10 % of the swing (spacings
# alternating +-20 %: the level's sampled blocks may hold few of a period's phases)
JUMP_SAMPLES = 0.5     # smallest timing jump (samples) that splits the stream
SPIKE = 0.05           # a sample this far (share of the swing) off its 5-sample median is a spike
MAX_BLOCK = 64         # longest block (samples) of the coarse crossing search


@dataclass(frozen=True)
class Crossings:
    """Sub-sample times (samples) of mid-level crossings and their direction (+1 up, -1 down)."""

    time: np.ndarray
    direction: np.ndarray


def block_length(half_period: float) -> int:
    """Samples per block of the coarse crossing search: at least 40 blocks a half-period."""
    return int(np.clip(half_period // 40, 1, MAX_BLOCK))


def block_sums(x: np.ndarray, factor: int) -> np.ndarray:
    """Sums of the whole blocks of `factor` samples (float64; integers for ADC codes):
    the coarse stream in which crossings are found. The numpy twin of the `block_sum`
    kernel (kernels/sync.cl)."""
    m = x.size // factor
    return np.asarray(x[: m * factor]).reshape(m, factor).sum(axis=1, dtype=np.float64)


LEVEL_SAMPLES = 4096   # block sums (at most, evenly spaced) that the level and swing come from


def level_stride(blocks: int) -> int:
    """Every how many blocks one is kept for the level's percentiles."""
    return max(1, blocks // LEVEL_SAMPLES)


@dataclass(frozen=True)
class Levels:
    """The crossing level and the swing (codes), and the integer thresholds on a block
    sum S of `factor` codes that decide the band: S >= high is above the hysteresis
    band, S < low below it, S >= mid above the level. Integers, so that a kernel's
    comparisons of integer sums are exactly numpy's."""

    level: float
    swing: float
    high: int
    low: int
    mid: int


def percentile_sums(sampled: np.ndarray) -> tuple[int, int]:
    """20 times the 5 and 95 percentiles of integer block sums (numpy's linear
    percentile at rank q (n - 1) / 100, in integers: exact). The numpy twin of the
    `sync_levels` kernel's first step (kernels/sync.cl)."""
    last = sampled.size - 1
    i, r = divmod(last, 20)
    j, t = divmod(19 * last, 20)
    ranks = [i, min(i + 1, last), j, min(j + 1, last)]
    s = np.partition(np.asarray(sampled, np.int64), sorted(set(ranks)))[ranks]
    return int(s[0] * (20 - r) + s[1] * r), int(s[2] * (20 - t) + s[3] * t)


def levels(sampled: np.ndarray, factor: int) -> Levels:
    """The middle of the swing, the swing and a hysteresis of 10 % of it, from a sample
    of integer block sums.

    A triangle's values are uniform between its extremes: the 5 and 95 percentiles give
    its middle and swing, and unlike the extremes they are not rounded off by the block
    averaging at the corners; a few thousand evenly spaced blocks estimate them to a
    fraction of a percent (the turning points, midpoints of two crossings, do not depend
    on the level). With a = 20 factor lo and b = 20 factor hi (`percentile_sums`), the
    thresholds factor (level +- swing / 10) are (7a + 11b) / 360 and (11a + 7b) / 360, and
    factor level is (a + b) / 40: integer divisions, as the `sync_levels` kernel does.
    """
    if sampled.size == 0:
        return Levels(0.0, 0.0, 1, 0, 1)
    return levels_of(*percentile_sums(sampled), factor)


def levels_of(a: int, b: int, factor: int) -> Levels:
    """`levels` from a = 20 factor lo and b = 20 factor hi."""
    return Levels((a + b) / (40 * factor), (b - a) / (18 * factor), (7 * a + 11 * b) // 360 + 1,
                  -((-11 * a - 7 * b) // 360), (a + b) // 40 + 1)


@dataclass(frozen=True)
class Changes:
    """Where the 3-block median of the block sums changes its band (event: +1 above the
    hysteresis band, -1 below, 0 inside; the first block always listed) and where it
    crosses the level (the block j whose side differs from block j - 1's, with both
    filtered sums). Sparse: a few per half-period."""

    event_at: np.ndarray
    event: np.ndarray
    sign_at: np.ndarray
    before: np.ndarray
    after: np.ndarray


def median3(sums: np.ndarray) -> np.ndarray:
    """3-block median (the ends unfiltered): removes what averaging left of a glitch."""
    b = np.array(sums, dtype=np.float64)
    if b.size >= 3:
        p, q, r = sums[:-2], sums[1:-1], sums[2:]
        b[1:-1] = np.maximum(np.minimum(p, q), np.minimum(np.maximum(p, q), r))
    return b


def changes(sums: np.ndarray, lv: Levels) -> Changes:
    """The band and level changes of block sums; with `coarse_crossings`, the numpy twin
    of the span_ends, span_carries and span_crossings kernels (kernels/sync.cl)."""
    b = median3(sums)
    event = np.where(b >= lv.high, 1, np.where(b < lv.low, -1, 0)).astype(np.int8)
    i = np.flatnonzero(np.r_[b.size > 0, event[1:] != event[:-1]])
    side = b >= lv.mid
    j = np.flatnonzero(side[1:] != side[:-1]) + 1
    return Changes(i, event[i], j, b[j - 1], b[j])


@dataclass(frozen=True)
class Coarse:
    """Crossings found in the block sums: where each crossed the level (blocks,
    interpolated), the direction, the crossing level and the swing (peak to peak),
    in codes."""

    block: np.ndarray
    direction: np.ndarray
    level: float
    swing: float


def coarse_crossings(ch: Changes, lv: Levels, factor: int) -> Coarse:
    """Crossings of the level with a hysteresis: the band's state (the last event
    outside it) flips when the filtered stream leaves the band on the side opposite to
    the one it last left; the crossing is the last change of side at or before the
    flip, interpolated between the two blocks around it."""
    nz = ch.event != 0
    at, val = ch.event_at[nz], ch.event[nz]
    flip = np.flatnonzero(val[1:] != val[:-1]) + 1
    flips, state = at[flip], val[flip]
    # from one side of the band to the other, the stream changed sides: at the last
    # change at or before the flip
    k = np.searchsorted(ch.sign_at, flips, side="right") - 1
    ok = k >= 0
    k, state = k[ok], state[ok]
    xa = ch.before[k] / factor - lv.level
    xb = ch.after[k] / factor - lv.level
    with np.errstate(divide="ignore", invalid="ignore"):
        frac = np.clip(xa / (xa - xb), 0.0, 1.0)
    return Coarse(ch.sign_at[k] - 1 + np.nan_to_num(frac), state, lv.level, lv.swing)


def coarse_from_sums(sums: np.ndarray, factor: int) -> Coarse:
    """coarse_crossings of integer block sums, all in numpy: the reference of the
    device's steps."""
    lv = levels(sums[:: level_stride(sums.size)], factor)
    return coarse_crossings(changes(sums, lv), lv, factor)


def coarse_from_codes(x: np.ndarray, factor: int) -> Coarse:
    """coarse_from_sums of the blocks of `factor` samples of x."""
    return coarse_from_sums(block_sums(x, factor), factor)


def fit_half_width(half_period: float) -> int:
    """Half-width (samples) of the crossing line fits."""
    return max(2, int(FIT_FRACTION * half_period))


def line_fit_sums(x: np.ndarray, centre: np.ndarray, half: int, spike: float
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Sums of x and (i - c) x over x[c - half : c + half + 1] for each centre c,
    spikes (samples more than `spike` codes off the median of their 5-sample
    neighbourhood) replaced by that median first. Exact for integer codes.

    Requires 2 <= c - half and c + half < x.size - 2.
    """
    w = sliding_window_view(np.asarray(x), 2 * half + 5)[centre - half - 2].astype(np.float64)
    # a spike is more than `spike` off at least 3 of its 4 neighbours, so off one of
    # the two adjacent ones: only those candidates need the median
    jump = np.abs(np.diff(w, axis=1)) > spike
    cand = np.zeros(w.shape, bool)
    cand[:, 2:-2] = jump[:, 1:-2] | jump[:, 2:-1]
    if cand.any():
        r, c = np.nonzero(cand)
        med = np.median(w[r[:, None], c[:, None] + np.arange(-2, 3)], axis=1)
        bad = np.abs(w[r, c] - med) > spike
        w[r[bad], c[bad]] = med[bad]
    w = w[:, 2:-2]
    return w.sum(axis=1), np.sum(w * np.arange(-half, half + 1, dtype=np.float64), axis=1)   # no BLAS threads


def line_fit_crossing(s0: np.ndarray, s1: np.ndarray, centre: np.ndarray, half: int,
                      level: float) -> np.ndarray:
    """Where the least-squares line of each window (sums from `line_fit_sums`)
    reaches `level`."""
    m = 2 * half + 1
    s2 = half * (half + 1) * (2 * half + 1) / 3.0   # sum (i - c)^2 over the window
    with np.errstate(divide="ignore", invalid="ignore"):
        return centre - (s0 / m - level) / (s1 / s2)


def reaches(centre: np.ndarray, half: int, size: int) -> np.ndarray:
    """Whether the fit window of each centre lies within codes [0, size) with the two
    codes either side that the despiking reads."""
    return (centre - half >= 2) & (centre + half < size - 2)


def rounded(guess: np.ndarray, size: int) -> np.ndarray:
    """Crossing times (samples; NaN: none) rounded to fit centres, -1 or `size` where
    none or beyond the codes."""
    return np.rint(np.clip(np.nan_to_num(guess, nan=-1.0), -1, size)).astype(np.int64)


def line_fits(x: np.ndarray, centre: np.ndarray, half: int, spike: float, level: float
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Both line fits of each crossing: `line_fit_sums` at `centre` (within reach),
    then, where that fit's crossing rounds to another centre, at that one.

    Returns the last fit's centre (-1 where the first fit's crossing is not finite or
    its window would leave x: the crossing is dropped) and its two sums. The numpy
    twin of the `line_fit` kernel (kernels/sync.cl).
    """
    s0, s1 = line_fit_sums(x, centre, half, spike)
    c2 = rounded(line_fit_crossing(s0, s1, centre, half, level), x.size)
    ok = reaches(c2, half, x.size)           # NaN and inf round to -1 or x.size: out of reach
    redo = ok & (c2 != centre)
    if np.any(redo):
        s0[redo], s1[redo] = line_fit_sums(x, c2[redo], half, spike)
    return np.where(ok, c2, -1), s0, s1


@dataclass(frozen=True)
class Fitted:
    """The line fits of a signal's coarse crossings, in order: each last fit's centre
    (samples; -1: dropped) and its sums of x and (i - c) x (`line_fits`), the crossing's
    direction (+1 up, -1 down), and the crossing level (codes)."""

    centre: np.ndarray
    s0: np.ndarray
    s1: np.ndarray
    direction: np.ndarray
    level: float


def fitted(x: np.ndarray, half_period: float, coarse=coarse_from_codes, fits=line_fits) -> Fitted:
    """The coarse crossings of x in blocks (`block_length`, `coarse`), each then fitted
    twice (`fits`) within FIT_FRACTION of a half-period around it; crossings whose first
    window would leave x are left out. Requires x.size >= 2 fit_half_width + 6."""
    half = fit_half_width(half_period)
    factor = block_length(half_period)
    co = coarse(x, factor)
    centre = rounded(co.block * factor + 0.5 * (factor - 1), x.size)
    first = np.flatnonzero(reaches(centre, half, x.size))
    c, s0, s1 = fits(x, centre[first], half, SPIKE * co.swing, co.level)
    return Fitted(c, s0, s1, co.direction[first], co.level)


def crossings(x: np.ndarray, half_period: float, fit=fitted) -> Crossings:
    """Mid-level crossings of a triangle-like signal.

    Found in block sums (`coarse_from_sums`), then each timed by a straight-line fit to
    the full-rate samples within FIT_FRACTION of a half-period around it, twice (the
    second fit centred on the first one's crossing): `fitted`.

    Parameters
    ----------
    x : ndarray
        The signal (ADC codes).
    half_period : float
        Nominal half-period in samples of `x`.
    fit : `fitted`, or a twin of it (the OpenCL processor's runs on its device).

    Returns
    -------
    Crossings with times in samples of `x`; crossings whose fit window would leave
    the array are dropped.
    """
    half = fit_half_width(half_period)
    if x.size < 2 * half + 6:          # too short for a single crossing fit
        return Crossings(np.zeros(0), np.zeros(0, np.int8))
    f = fit(x, half_period)
    guess = line_fit_crossing(f.s0, f.s1, f.centre, half, f.level)
    keep = (f.centre >= 0) & np.isfinite(guess)
    return Crossings(guess[keep], f.direction[keep])


@dataclass(frozen=True)
class TurningPoints:
    """Turning points of the current: time (samples), whether a maximum, segment id."""

    time: np.ndarray
    is_max: np.ndarray
    segment: np.ndarray


def turning_points(cr: Crossings, half_period: float) -> TurningPoints:
    """Turning points between consecutive opposite crossings, refined on a uniform grid.

    A turning point is kept when the crossings around it alternate and lie one
    half-period apart: within SPACING_TOLERANCE of the nominal value (the period and the
    level may be off), and within a robust bound (JUMP_SAMPLES or 6 sigma of the
    spacing noise) of the measured one of their direction, so that even a few dropped
    samples split the stream. Each unbroken run of turning
    points is a segment; its times are replaced by a least-squares uniform grid.
    """
    t, d = cr.time, cr.direction
    if t.size < 3:
        return TurningPoints(np.zeros(0), np.zeros(0, bool), np.zeros(0, np.int64))
    gap = np.diff(t)
    alternate = d[1:] != d[:-1]
    near = alternate & (np.abs(gap - half_period) < SPACING_TOLERANCE * half_period)
    if not np.any(near):
        return TurningPoints(np.zeros(0), np.zeros(0, bool), np.zeros(0, np.int64))
    # a level off the middle makes the rising and falling spacings differ: compare
    # each with the typical spacing of its own direction
    up = d[:-1] > 0
    typical = np.zeros(gap.size)
    for side in (up, ~up):
        if np.any(near & side):
            typical[side] = median(gap[near & side])
    dev = gap - typical
    spread = 1.4826 * median(np.abs(dev[near]))
    good = near & (np.abs(dev) < max(JUMP_SAMPLES, 6.0 * spread))
    # turning point i sits between crossings i and i+1; it is trusted when both
    # of its neighbouring spacings are good (a jump spoils the points on both sides)
    tp = 0.5 * (t[:-1] + t[1:])
    is_max = d[:-1] > 0
    ok = good.copy()
    ok[1:] &= good[:-1]
    ok[:-1] &= good[1:]
    idx = np.flatnonzero(ok)
    first = np.concatenate([[True], np.diff(idx) != 1])
    seg = np.cumsum(first) - 1
    fitted = tp[idx]
    edges = [*np.flatnonzero(first), idx.size]
    for a, b in zip(edges[:-1], edges[1:], strict=True):     # each segment: a run of consecutive idx
        if b - a >= 3:
            fitted[a:b] = uniform_grid(fitted[a:b])
    return TurningPoints(fitted, is_max[idx], seg.astype(np.int64))


def uniform_grid(t: np.ndarray) -> np.ndarray:
    """The least-squares straight line through t[0], t[1], ... at 0, 1, ...: in closed
    form about the centres of both (numeric.centred_slope; np.polyfit's lstsq costs some
    10 times as much on a chunk's 16 384 turning points)."""
    slope, _, k, _ = centred_slope(np.arange(t.size, dtype=np.float64), t)
    return t.mean() + k * slope


def sync_turning_points(sync: np.ndarray, half_period: float, fit=fitted) -> TurningPoints:
    """Turning points of the sync channel (higher code = higher current); `fit` as in
    `crossings`."""
    return turning_points(crossings(sync, half_period, fit), half_period)


@dataclass(frozen=True)
class HalfSweeps:
    """Half-sweeps on the optical timeline (samples): start, length, direction, segment."""

    start: np.ndarray
    length: np.ndarray
    rising: np.ndarray
    segment: np.ndarray

    @property
    def centre(self) -> np.ndarray:
        return self.start + 0.5 * self.length


def half_sweeps(tp: TurningPoints, lag: float) -> HalfSweeps:
    """Half-sweeps between consecutive turning points of one segment, moved onto the
    optical timeline by the sync lag (optical time = sync time - lag).

    A half-sweep starting at a current minimum is current-rising.
    """
    same = tp.segment[1:] == tp.segment[:-1]
    start = tp.time[:-1][same] - lag
    length = np.diff(tp.time)[same]
    return HalfSweeps(start, length, ~tp.is_max[:-1][same], tp.segment[:-1][same])
