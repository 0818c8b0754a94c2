"""Stage 2: turning points of the modulation, aligned to the optics, and segmentation.

Mid-level crossings of a triangle are where its slope is steepest, so they are the
noise-robust timing marks: each is located to a small fraction of a sample by a
straight-line fit over most of the half-sweep, and a turning point is the midpoint
of the two crossings around it (exact for a symmetric triangle, whatever the level).
The turning times of one unbroken stretch are then fitted by a uniform grid (the
period refined from the data); a gap or jump in the grid (dropped samples, a flat
sync) splits the stream into segments.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import uniform_filter1d

from . import lpf

FIT_FRACTION = 0.35   # half-width of the crossing line fit, as a share of the half-period
GRID_TOLERANCE = 0.02  # allowed deviation of a half-period from the nominal, share
JUMP_SAMPLES = 0.5     # smallest timing jump (samples) that splits the stream
SPIKE = 0.05           # a sample this far (share of the swing) off its moving average is a spike


@dataclass(frozen=True)
class Crossings:
    """Sub-sample times (samples) of mid-level crossings and their direction (+1 up, -1 down)."""

    time: np.ndarray
    direction: np.ndarray


def _prefix_sums(x: np.ndarray, level: float) -> tuple[np.ndarray, np.ndarray]:
    """Prefix sums of (x - level) and i (x - level): any window's line fit in O(1)."""
    y = x - level
    cx = np.zeros(x.size + 1)
    np.cumsum(y, out=cx[1:])
    y *= np.arange(x.size, dtype=np.float64)
    cix = np.zeros(x.size + 1)
    np.cumsum(y, out=cix[1:])
    return cx, cix


def _line_fit_crossing(sums: tuple[np.ndarray, np.ndarray], centre: np.ndarray, half: int) -> np.ndarray:
    """Where a straight line fitted to x[centre-half : centre+half] reaches the level of
    `sums` (from _prefix_sums)."""
    cx, cix = sums
    a = centre - half
    b = centre + half + 1
    m = float(b[0] - a[0]) if a.size else 1.0
    sx = cx[b] - cx[a]
    sixc = (cix[b] - cix[a]) - centre * sx          # sum (i - c) x
    s2 = half * (half + 1) * (2 * half + 1) / 3.0   # sum (i - c)^2 over the window
    slope = sixc / s2
    intercept = sx / m                               # value at i = c (sum (i - c) = 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        return centre - intercept / slope


def _despike(x: np.ndarray, near: np.ndarray, threshold: float) -> np.ndarray:
    """x with the samples at `near` that stand out of their 5-sample median replaced
    by it (glitches of one or two samples); a copy."""
    idx = np.clip(near[:, None] + np.arange(-2, 3), 0, x.size - 1)
    med = np.median(x[idx], axis=1)
    bad = np.abs(x[near] - med) > threshold
    out = x.copy()
    out[near[bad]] = med[bad]
    return out


def crossings(x: np.ndarray, half_period: float, level: float | None = None,
              smooth: int = 1) -> Crossings:
    """Mid-level crossings of a triangle-like signal.

    Parameters
    ----------
    x : ndarray
        The signal (ADC codes).
    half_period : float
        Nominal half-period in samples of `x`.
    level : float, optional
        Crossing level; default the middle of the 0.5 and 99.5 percentiles.
    smooth : int
        Moving-average length used to find crossings (not to time them) and, when
        above 1, to replace isolated spikes (more than SPIKE of the swing off the
        moving average) before the timing fits.

    Returns
    -------
    Crossings with times in samples of `x`; crossings whose fit window would leave
    the array are dropped.
    """
    x = np.asarray(x, dtype=np.float64)
    if x.size < 4:
        return Crossings(np.zeros(0), np.zeros(0, np.int8))
    lo, hi = np.percentile(x, [0.5, 99.5])
    if level is None:
        level = 0.5 * (lo + hi)
    hyst = 0.1 * (hi - lo)
    if smooth > 1:
        m = uniform_filter1d(x, smooth)
        near = np.flatnonzero(np.abs(x - m) > SPIKE * (hi - lo))
        if near.size:              # a glitch would pull the line fits by samples
            x = _despike(x, near, SPIKE * (hi - lo))
            m = uniform_filter1d(x, smooth)
        xs = m - level
    else:
        xs = x - level
    event = np.where(xs > hyst, 1, np.where(xs < -hyst, -1, 0)).astype(np.int8)
    pos = np.where(event != 0, np.arange(x.size), 0)
    np.maximum.accumulate(pos, out=pos)
    state = event[pos]
    flips = np.flatnonzero((state[1:] != state[:-1]) & (state[:-1] != 0)) + 1
    if flips.size == 0:
        return Crossings(np.zeros(0), np.zeros(0, np.int8))
    direction = state[flips]
    half = max(2, int(FIT_FRACTION * half_period))
    if x.size < 2 * half + 2:          # too short for a single crossing fit
        return Crossings(np.zeros(0), np.zeros(0, np.int8))
    guess = flips.astype(np.float64)
    sums = _prefix_sums(x, level)
    for _ in range(2):
        centre = np.rint(np.nan_to_num(guess, nan=-1.0)).astype(np.int64)
        ok = np.isfinite(guess) & (centre - half >= 0) & (centre + half < x.size)
        guess = np.where(ok, _line_fit_crossing(sums, np.clip(centre, half, x.size - half - 1), half),
                         np.nan)
    keep = np.isfinite(guess)
    return Crossings(guess[keep], direction[keep])


@dataclass(frozen=True)
class TurningPoints:
    """Turning points of the current: time (samples), whether a maximum, segment id."""

    time: np.ndarray
    is_max: np.ndarray
    segment: np.ndarray


def turning_points(cr: Crossings, half_period: float) -> TurningPoints:
    """Turning points between consecutive opposite crossings, refined on a uniform grid.

    A turning point is kept when the crossings around it alternate and lie one
    half-period apart: within GRID_TOLERANCE of the nominal value, and within a
    robust bound (JUMP_SAMPLES or 6 sigma of the spacing noise) of the measured one,
    so that even a few dropped samples split the stream. Each unbroken run of turning
    points is a segment; its times are replaced by a least-squares uniform grid.
    """
    t, d = cr.time, cr.direction
    if t.size < 3:
        return TurningPoints(np.zeros(0), np.zeros(0, bool), np.zeros(0, np.int64))
    gap = np.diff(t)
    alternate = d[1:] != d[:-1]
    near = alternate & (np.abs(gap - half_period) < GRID_TOLERANCE * half_period)
    if not np.any(near):
        return TurningPoints(np.zeros(0), np.zeros(0, bool), np.zeros(0, np.int64))
    typical = np.median(gap[near])
    spread = 1.4826 * np.median(np.abs(gap[near] - typical))
    good = near & (np.abs(gap - typical) < max(JUMP_SAMPLES, 6.0 * spread))
    # turning point i sits between crossings i and i+1; it is trusted when both
    # of its neighbouring spacings are good (a jump spoils the points on both sides)
    tp = 0.5 * (t[:-1] + t[1:])
    is_max = d[:-1] > 0
    ok = good.copy()
    ok[1:] &= good[:-1]
    ok[:-1] &= good[1:]
    idx = np.flatnonzero(ok)
    seg = np.cumsum(np.concatenate([[True], np.diff(idx) != 1])) - 1
    fitted = tp[idx].copy()
    for s in range(int(seg[-1]) + 1 if seg.size else 0):
        m = seg == s
        if m.sum() >= 3:
            k = np.arange(m.sum(), dtype=np.float64)
            fitted[m] = np.polyval(np.polyfit(k, tp[idx][m], 1), k)
    return TurningPoints(fitted, is_max[idx], seg.astype(np.int64))


def sync_turning_points(sync: np.ndarray, half_period: float) -> TurningPoints:
    """Turning points of the sync channel (higher code = higher current)."""
    return turning_points(crossings(sync, half_period, smooth=33), half_period)


MAX_DELAY_SAMPLES = 400  # search range of the sync-to-optics delay


def period_delays(beat: np.ndarray, sync: np.ndarray, sample_rate_hz: float,
                  half_period: float) -> tuple[np.ndarray, np.ndarray]:
    """Per-period estimates of how far the sync lags the optics (samples).

    The low-passed beat carries the laser intensity triangle, which has the optical
    timing. The sync is passed through the same decimation and low-pass, so both
    triangles have identically rounded corners; the beat is then regressed, one
    modulation period at a time, on the shifted template and its derivative
    (Gauss-Newton). The detector imbalance may have either sign: the regression's
    scale takes it.

    Returns
    -------
    lags : (P,) samples, NaN where a period gives no triangle.
    misfit : (P,) rms residual of each period's fit relative to the triangle's rms;
        large where a target beat near 0 Hz leaks into the low band.
    """
    y, _, step = lpf.intensity(beat, sample_rate_hz)
    z, _, _ = lpf.intensity(sync, sample_rate_hz)
    edge = lpf.TAPS // 2 + 1
    y, z = y[edge:-edge] - y[edge:-edge].mean(), z[edge:-edge] - z[edge:-edge].mean()
    span = int(MAX_DELAY_SAMPLES / step) + 1
    period = int(round(2 * half_period / step))
    if y.size < 2 * span + 2 * period:
        return np.zeros(0), np.zeros(0)
    # coarse: integer lag (decimated samples) of the largest |cross-correlation|
    core = slice(span, y.size - span)
    corr = [np.dot(y[core], z[span + k: y.size - span + k]) for k in range(-span, span + 1)]
    shift = np.full(1, float(np.argmax(np.abs(corr)) - span))
    j = np.arange(y.size, dtype=np.float64)
    starts = np.arange(span, y.size - span - period, period)
    windows = starts[:, None] + np.arange(period)
    yw = y[windows]
    for _ in range(3):
        # shift the template period by period (one shift for all in the first pass)
        zs = np.interp(j[windows] + shift[:, None], j, z)
        dz = np.gradient(zs, axis=1)
        design = np.stack([np.ones_like(zs), zs, dz], axis=2)
        # batched least squares through the 3x3 normal equations of each period
        gram = np.einsum("pki,pkj->pij", design, design)
        rhs = np.einsum("pki,pk->pi", design, yw)
        coef = np.linalg.solve(gram + 1e-12 * np.eye(3), rhs[..., None])[..., 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            step_lag = np.where(np.abs(coef[:, 1]) > 0, coef[:, 2] / coef[:, 1], np.nan)
        shift = shift + np.nan_to_num(step_lag)
    resid = yw - np.einsum("pkc,pc->pk", design, coef)
    with np.errstate(divide="ignore", invalid="ignore"):
        misfit = np.sqrt(np.mean(resid**2, axis=1) / np.mean((coef[:, 1:2] * zs) ** 2, axis=1))
    lags = np.where(np.isfinite(step_lag), shift * step, np.nan)
    return lags, misfit


CLEAN_MISFIT = 0.2  # a clean intensity triangle fits to a few percent rms


def combine_delays(lags: np.ndarray, misfit: np.ndarray) -> tuple[float, int, float]:
    """Median lag over the periods that fit well: misfit within 3x the best decile's.

    A stretch where a target's beat sweeps through 0 Hz in every period (a fast
    target near the lens) fits badly; gating on the best decile keeps the clean
    periods even when they are few.

    Returns (lag, periods used, misfit of the best decile); (nan, 0, nan) if none.
    The estimate is unreliable when the last exceeds CLEAN_MISFIT.
    """
    ok = np.isfinite(lags) & np.isfinite(misfit)
    if not np.any(ok):
        return float("nan"), 0, float("nan")
    best = float(np.percentile(misfit[ok], 10))
    ok &= misfit <= 3.0 * best
    return float(np.median(lags[ok])), int(ok.sum()), best


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
