"""Per-capture refinement of the sync delay when a chirp calibration is used.

A calibrated LUT is tied to the timing of its calibration capture. In another capture
the sync may sit a few samples differently against the optics (cables, and the paper's
intensity-based estimate is biased when a beat passes 0 Hz at the late optical turning
points). A delay error shifts the resampling instants along a nonlinear chirp, which
moves the rising and falling peaks in opposite directions: a velocity appears that the
distance does not show. So the delay is chosen where the velocity integrates to the
change of distance (kinematic consistency), over a few stretches of the capture, by
secant steps.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .capture import Capture
from .numeric import runs

STRETCHES = 3
STRETCH_PERIODS = 240
STEP_SAMPLES = 2.0        # first secant step
MAX_SHIFT_SAMPLES = 200.0
TOLERANCE_SAMPLES = 0.02
MAX_EVALUATIONS = 6
MIN_RUN = 60              # pairs of a valid run used


def mismatch(cap: Capture, plan, lag: float, backend=None) -> float:
    """Mean over stretches of (integral of velocity - change of distance) / duration (m/s);
    NaN when no stretch has a long valid run. `backend`: the stages' (default numpy)."""
    from .engine import NumpyBackend, capture_parts

    backend = backend or NumpyBackend()
    info = cap.info
    p = replace(plan, lag=lag, check=None)
    length = int(STRETCH_PERIODS * info.samples_per_period)
    starts = np.linspace(0, max(0, info.samples - length), STRETCHES).astype(np.int64)
    out = []
    for a in np.unique(starts):
        parts = capture_parts(cap, p, backend, int(a), int(a) + length)
        if not parts:
            continue
        t = np.concatenate([0.5 * (q.t_rise + q.t_fall) for q in parts])
        d = np.concatenate([q.result.distance for q in parts])
        v = np.concatenate([q.result.velocity for q in parts])
        ok = np.concatenate([q.reason == 0 for q in parts])
        i, j = max(runs(ok), key=lambda r: r[1] - r[0], default=(0, 0))
        if j - i < MIN_RUN:
            continue
        tt, dd, vv = t[i:j], d[i:j], v[i:j]
        # the trapezoid rule (scipy.integrate's costs half a second to import)
        travelled = float(np.sum(0.5 * (vv[1:] + vv[:-1]) * np.diff(tt)))
        out.append((travelled - (dd[-1] - dd[0])) / (tt[-1] - tt[0]))
    return float(np.mean(out)) if out else float("nan")


def refine_lag(cap: Capture, plan, backend=None):
    """The plan with its lag moved to where the track is kinematically consistent
    (trial stretches converted by `backend`, default numpy).

    Keeps the estimate (and marks it unreliable through lag_misfit = inf) when no
    stretch can be measured."""
    lag0 = plan.lag
    xs = [lag0, lag0 + STEP_SAMPLES]
    ms = [mismatch(cap, plan, x, backend) for x in xs]
    while len(xs) < MAX_EVALUATIONS and np.isfinite(ms[-1]) and np.isfinite(ms[-2]):
        slope = (ms[-1] - ms[-2]) / (xs[-1] - xs[-2])
        if slope == 0:
            break
        nxt = float(np.clip(xs[-1] - ms[-1] / slope, lag0 - MAX_SHIFT_SAMPLES, lag0 + MAX_SHIFT_SAMPLES))
        done = abs(nxt - xs[-1]) < TOLERANCE_SAMPLES
        xs.append(nxt)
        ms.append(mismatch(cap, plan, nxt, backend))
        if done:
            break
    good = [k for k, m in enumerate(ms) if np.isfinite(m)]
    if not good:
        return replace(plan, lag_misfit=float("inf"))
    best = min(good, key=lambda k: abs(ms[k]))
    return replace(plan, lag=xs[best], lag_refined=True, lag_mismatch_mps=abs(ms[best]))


WIDTH_PERIODS = 100       # periods whose peaks are measured by the tuning check
WIDTH_LIMIT = 1.1         # peaks this much wider than the window's own say: tuning mismatch
STILL_MPS = 0.05          # a stretch this slow is measured from plain peaks


def _widths(power: np.ndarray, lo: int) -> np.ndarray:
    """Width (bins) of each row's highest peak beyond `lo` at half its power, the
    crossings interpolated linearly between bins (NaN where a side never falls below)."""
    band = power[:, lo:]
    rows, cols = np.arange(band.shape[0]), np.arange(band.shape[1])
    k = np.argmax(band, axis=1)
    half = 0.5 * band[rows, k]
    below = band < half[:, None]
    a = np.where(below & (cols < k[:, None]), cols, -1).max(axis=1, initial=-1)    # last below, left
    b = np.where(below & (cols > k[:, None]), cols, cols.size).min(axis=1, initial=cols.size)
    ok = (a >= 0) & (b < cols.size)
    out = np.full(band.shape[0], np.nan)
    a, b, r, h = a[ok], b[ok], rows[ok], half[ok]
    xa = a + (h - band[r, a]) / (band[r, a + 1] - band[r, a])
    xb = b - (h - band[r, b]) / (band[r, b - 1] - band[r, b])
    out[ok] = xb - xa
    return out


def stillest(time_s: np.ndarray, velocity_mps: np.ndarray, pairs: int = WIDTH_PERIODS) -> float:
    """Start time (s) of the `pairs` consecutive pairs with the smallest mean |velocity|
    (plain spectra of a moving target smear through the Doppler term); the middle of
    the track when no velocity is known."""
    speed = np.nan_to_num(np.abs(velocity_mps), nan=1e3)
    if time_s.size <= pairs or speed.min() >= 1e3:
        return float(time_s[time_s.size // 2]) if time_s.size else 0.0
    run = np.convolve(speed, np.ones(pairs) / pairs, mode="valid")
    return float(time_s[int(np.argmin(run))])


def peak_width_ratio(cap: Capture, plan, t0_s: float, time_s: np.ndarray | None = None,
                     velocity_mps: np.ndarray | None = None, backend=None) -> float:
    """Median half-power width of the peaks of WIDTH_PERIODS periods from `t0_s`, over
    that of the window's own peak: about 1 when the LUT matches the laser's real chirp,
    more when the tuning has moved away from the table or calibration.

    Plain peaks of a still stretch are the most sensitive. Where even the stillest
    stretch moves (median |v| over STILL_MPS in the track given by `time_s`,
    `velocity_mps`: a capture of a take-off alone), each half-sweep is de-chirped at its
    pair's velocity first, so that the Doppler term does not widen its peak; a tuning
    error still does, a little less where it has biased the velocity itself.
    `backend`: the stages' (default numpy).
    """
    from .engine import NumpyBackend
    from .stages import resample, sync

    backend = backend or NumpyBackend()
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
    widths = []
    for rising in (True, False):
        sel = fits & (hs.rising == rising)
        if not sel.any():
            continue
        x = backend.resample(beat, hs.start[sel], hs.length[sel], plan.lut.u(rising), plan.window)
        beta = v = None
        if known is not None and known.any():
            t = (a + hs.centre[sel]) / info.sample_rate_hz
            v = np.interp(t, time_s[known], velocity_mps[known])
            beta = plan.model.beta_rise if rising else plan.model.beta_fall
        widths.append(_widths(backend.power(x, beta, v, nfft), plan.search.lo))
    if not widths:
        return float("nan")
    j = np.arange(plan.lut.points)
    tones = np.array([plan.window * np.cos(2 * np.pi * (0.2 + f) * j / 8) for f in (0.0, 0.25, 0.5)])
    reference = float(np.nanmedian(_widths(backend.power(tones, None, None, nfft), 1)))
    return float(np.nanmedian(np.concatenate(widths)) / reference)
