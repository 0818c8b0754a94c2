"""The tuning check: how much wider than the window's own a track's peaks are.

A LUT that matches the laser's real chirp gives peaks as wide as the window's own; a
chirp that has left its G(I) table or calibration (thermal lag) widens them. The track's
stillest stretch is measured (plain peaks, or de-chirped at its pairs' velocities where
even that stretch moves), each row's own peak (docs/pipeline.md, Tuning check).
"""

from __future__ import annotations

import functools

import numpy as np

from .capture import Capture
from .stages import resample, sync

WIDTH_PERIODS = 100       # periods whose peaks are measured by the tuning check
WIDTH_LIMIT = 1.1         # peaks this much wider than the window's own say: tuning mismatch
STILL_MPS = 0.05          # a stretch this slow is measured from plain peaks
WIDTH_SNR = 10 ** 1.5     # a peak measured by the tuning check stands 15 dB over the band's median
WIDTH_HEARD = 0.5         # ... in this share of the rows, else the check says nothing (NaN)
# plain peaks that move this far (interquartile, m) in the stretch, and farther than
# they are wide: a target moving at no known velocity (a vibration no pair follows),
# whose Doppler terms widen its peaks (a 50 um 1 kHz vibration: 27 bins against 4 wide;
# a still target 5 us of thermal lag off its table: 13 bins against 120)
MOVING_SPREAD_M = 1e-3


WIDTH_REACH = 32          # bins either side of a peak searched first for its half-power points
OWN_BINS = 24             # bins either side of the track's own peak its width is measured in (another
                          # mover's smeared peak in the band read 2.2x: no pair kept, movers.py seed 10 #12)


def _widths(power: np.ndarray, lo: int, hi: int | None = None) -> np.ndarray:
    """Width (bins) of each row's highest peak in bins [lo, hi) at half its power, the
    crossings interpolated linearly between bins (NaN where a side never falls below)."""
    band = power[:, lo:hi]
    rows, n = np.arange(band.shape[0]), band.shape[1]
    k = np.argmax(band, axis=1)
    half = 0.5 * band[rows, k]
    # the last bin below half left of the peak and the first right of it: among the
    # WIDTH_REACH bins either side (a peak is a few bins wide), else in the whole band
    near = np.clip(k[:, None] + np.arange(-WIDTH_REACH, WIDTH_REACH + 1), 0, n - 1)
    a, b = _sides(band[rows[:, None], near] < half[:, None], near, k)
    far = (a < 0) & (k > WIDTH_REACH) | (b >= n) & (k < n - 1 - WIDTH_REACH)
    if far.any():
        cols = np.arange(n)
        a[far], b[far] = _sides(band[far] < half[far, None], np.broadcast_to(cols, (far.sum(), n)), k[far])
    ok = (a >= 0) & (b < n)
    out = np.full(band.shape[0], np.nan)
    a, b, r, h = a[ok], b[ok], rows[ok], half[ok]
    xa = a + (h - band[r, a]) / (band[r, a + 1] - band[r, a])
    xb = b - (h - band[r, b]) / (band[r, b - 1] - band[r, b])
    out[ok] = xb - xa
    return out


def _sides(below: np.ndarray, cols: np.ndarray, k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each row's last column of `cols` left of k whose `below` is set (-1: none) and its
    first right of k (past the band's end: none)."""
    n = np.iinfo(np.int64).max
    a = np.where(below & (cols < k[:, None]), cols, -1).max(axis=1, initial=-1)
    b = np.where(below & (cols > k[:, None]), cols, n).min(axis=1, initial=n)
    return a, b


def stillest(time_s: np.ndarray, velocity_mps: np.ndarray, pairs: int = WIDTH_PERIODS) -> float:
    """Start time (s) of the `pairs` consecutive pairs with the smallest mean |velocity|
    (plain spectra of a moving target smear through the Doppler term); the middle of
    the track when no velocity is known."""
    speed = np.nan_to_num(np.abs(velocity_mps), nan=1e3)
    if time_s.size <= pairs or speed.min() >= 1e3:
        return float(time_s[time_s.size // 2]) if time_s.size else 0.0
    run = np.convolve(speed, np.ones(pairs) / pairs, mode="valid")
    return float(time_s[int(np.argmin(run))])


def peak_width_ratio(cap: Capture, plan, t0_s: float, time_s: np.ndarray | None,
                     velocity_mps: np.ndarray | None, backend, distance_m: np.ndarray | None = None) -> float:
    """Median half-power width of the peaks of WIDTH_PERIODS periods from `t0_s`, over
    that of the window's own peak: about 1 when the LUT matches the laser's real chirp,
    more when the tuning has moved away from the table or calibration.

    Plain peaks of a still stretch are the most sensitive. Where even the stillest
    stretch moves (median |v| over STILL_MPS in the track given by `time_s`,
    `velocity_mps`: a capture of a take-off alone), each half-sweep is de-chirped at its
    pair's velocity first, so that the Doppler term does not widen its peak; a tuning
    error still does, a little less where it has biased the velocity itself. Where the
    track's `distance_m` is given, each row's peak is its own, within OWN_BINS of where
    the track puts it (its distance, plus k v in plain spectra): not another echo's in
    the band (another mover's, smeared by its Doppler term, is no sign of the tuning).
    `backend`: the stages'.
    """
    info = cap.info
    spp = info.samples_per_period
    a = max(0, int(t0_s * info.sample_rate_hz - spp))
    beat, sy = cap.read(a, a + int((WIDTH_PERIODS + 2) * spp))
    hs = sync.half_sweeps(backend.turning_points(sy, spp / 2), plan.lag)
    fits = resample.inside(hs.start, hs.length, plan.lut, beat.size)
    known = None
    if time_s is not None and velocity_mps is not None:
        known = np.isfinite(velocity_mps)
        span = known & (time_s >= a / info.sample_rate_hz) & (time_s < (a + beat.size) / info.sample_rate_hz)
        if not span.any() or np.median(np.abs(velocity_mps[span])) <= STILL_MPS:
            known = None
    nfft = plan.model.nfft
    jobs, own = [], []
    directions = (True, False)
    sels = [fits & (hs.rising == rising) for rising in directions]
    rows = backend.resample_each(beat, [(hs.start[s], hs.length[s], plan.lut.u(up))
                                        for s, up in zip(sels, directions, strict=True)], plan.window)
    for sel, rising, x in zip(sels, directions, rows, strict=True):
        if not sel.any():
            continue
        beta = v = None
        t = (a + hs.centre[sel]) / info.sample_rate_hz
        if known is not None and known.any():
            v = np.interp(t, time_s[known], velocity_mps[known])
            beta = plan.model.beta_rise if rising else plan.model.beta_fall
        jobs.append((x, beta, v))
        own.append(_own_peak(plan.model, rising, t, time_s, distance_m, velocity_mps, v is None))
    if not jobs:
        return float("nan")
    # in the target's band: a wall left out of it is not the target's peak
    powers = backend.power_each(jobs, nfft)
    each = [_strong_widths(_around(power, c), plan.search.lo, plan.search.hi, power)
            for power, c in zip(powers, own, strict=True)]
    widths = np.concatenate(each)
    if not np.isfinite(widths).sum() >= WIDTH_HEARD * widths.size:
        return float("nan")             # noise's peaks (no target in the band) say nothing of the tuning
    if known is None:
        spread = max(_spread(p[:, plan.search.lo: plan.search.hi]) for p in powers)
        if spread * plan.model.metres_per_bin > MOVING_SPREAD_M and spread > np.nanmedian(widths):
            return float("nan")         # plain peaks of a target moving at no known velocity: smeared
    # a tuning error widens the peaks of both directions; an echo's image beside a
    # de-chirped peak lies in one (its Doppler term moves it opposite ways in the two):
    # the narrower direction's (a foot at rest 3 mm from a hand's peaks de-chirped at
    # -0.5 m/s read 1.6x, movers.py seed 8, capture 37)
    heard = [w for w in each if np.isfinite(w).sum() >= WIDTH_HEARD * w.size] if known is not None else []
    return float(min((np.nanmedian(w) for w in heard), default=np.nanmedian(widths))
                 / own_width(plan.lut.points, nfft))


def _spread(band: np.ndarray) -> float:
    """The interquartile range (bins) of the rows' highest peaks."""
    q1, q3 = np.percentile(np.argmax(band, axis=1), [25, 75]) if band.shape[0] else (0.0, 0.0)
    return float(q3 - q1)


def _strong_widths(power: np.ndarray, lo: int, hi: int | None, whole: np.ndarray | None = None
                   ) -> np.ndarray:
    """`_widths` of the rows whose highest peak stands WIDTH_SNR over the band's median
    power (NaN elsewhere; the median of `whole`'s band where given: `power` is its
    peaks' surroundings alone): the highest of a thousand bins of noise reaches about 10
    times their median, and its width is the noise's."""
    band = power[:, lo:hi]
    floor = np.median((power if whole is None else whole)[:, lo:hi], axis=1)
    strong = band.max(axis=1, initial=0.0) >= WIDTH_SNR * floor
    return np.where(strong, _widths(power, lo, hi), np.nan)


def _own_peak(model, rising: bool, t: np.ndarray, time_s: np.ndarray | None, distance_m: np.ndarray | None,
              velocity_mps: np.ndarray | None, plain: bool) -> np.ndarray | None:
    """The padded bin of the track's peak at each half-sweep's time `t` (s): its
    distance (m, interpolated over its finite ones), in `plain` spectra shifted by its
    Doppler term k v; None without a track's distances."""
    if time_s is None or distance_m is None or velocity_mps is None:
        return None
    ok = np.isfinite(distance_m) & np.isfinite(velocity_mps)
    if not ok.any():
        return None
    d = np.interp(t, time_s[ok], distance_m[ok])
    if plain:
        d = d + (model.k_rise if rising else model.k_fall) * np.interp(t, time_s[ok], velocity_mps[ok])
    return d / model.metres_per_bin


def _around(power: np.ndarray, centre: np.ndarray | None) -> np.ndarray:
    """`power` with each row's bins beyond OWN_BINS of its `centre` (bin) set to 0 (as
    it is without one)."""
    if centre is None:
        return power
    cols = np.arange(power.shape[1])
    return np.where(np.abs(cols[None, :] - centre[:, None]) <= OWN_BINS, power, 0.0)


@functools.lru_cache(maxsize=8)
def own_width(points: int, nfft: int) -> float:
    """The median half-power width (bins) of the window's own peak (resample.window of
    `points`, the plans' window; `nfft`-point transforms): tones a few fractions of a bin
    apart, once per size (numpy's FFT: the device path imports no scipy)."""
    j, win = np.arange(points), resample.window(points)
    tones = np.array([win * np.cos(2 * np.pi * (0.2 + f) * j / 8) for f in (0.0, 0.25, 0.5)])
    return float(np.nanmedian(_widths(np.abs(np.fft.rfft(tones, nfft)[:, : nfft // 2]) ** 2, 1)))
