"""The real chirp, measured from a capture of a static target at a known distance.

A DFB under 20 kHz modulation does not follow its static G(I): the thermal part of the
tuning lags the current, so the sweep is narrower, rising and falling differ, and the
optical turning points come late. As swept-source OCT does with a reference arm, the
beat of a known delay tau = 2 R n / c gives the optical frequency: its phase is
2 pi tau nu(t). Per half-sweep of the sync (the pipeline's own segmentation):
band-pass the beat around the target's beat frequencies (found from G(I), with room),
take the analytic signal, unwrap its phase, divide by 2 pi tau; then average over many
periods on a grid of the half-sweep's time fraction s, each sweep's unknown phase
constant removed. Where the beat frequency nears 0 Hz (the optical turning points) the
phase is unusable, so each direction keeps the stretch where the chirp is steep.
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.fft

from . import __version__
from .capture import Capture
from .chirp import Chirp, Direction
from .engine import Options, make_plan
from .errors import CaptureError
from .physics import C
from .stages import sync

GRID = 2048              # points of the s grid over [S_LO, S_HI]
S_LO, S_HI = -0.2, 1.2   # the optics may lag the sync: look past the sync's turning points
STEEP = 0.35             # keep s where the chirp is at least this share of its median slope
MIN_SHARE = 0.5          # ... and where at least this share of the sweeps was measured


def _analytic(x: np.ndarray, fs: float, f_lo: float, f_hi: float) -> np.ndarray:
    """Analytic signal of x restricted to [f_lo, f_hi] (Hz)."""
    n = x.size
    spec = scipy.fft.fft(x - x.mean(), workers=-1)
    f = scipy.fft.fftfreq(n, 1 / fs)
    spec[(f < f_lo) | (f > f_hi)] = 0
    return scipy.fft.ifft(2 * spec, workers=-1)


def measure_chirp(path, distance_m: float, periods: int = 2000) -> Chirp:
    """Calibrate the chirp from `periods` periods in the middle of a static capture.

    Parameters
    ----------
    path : capture of a static target.
    distance_m : its distance R (m); sets the frequency scale through tau = 2 R n / c.
    periods : modulation periods averaged.
    """
    with Capture(path) as cap:
        info = cap.info
        plan = make_plan(cap, Options(range_check=False))      # its LUT and delay only
        spp = info.samples_per_period
        n = int(min(info.samples, periods * spp + 4 * spp))
        a = max(0, (info.samples - n) // 2)
        beat, sy = cap.read(a, a + n)
    fs, nidx = info.sample_rate_hz, info.refractive_index
    tau = 2 * distance_m * nidx / C
    if not 0.02 < distance_m < 0.9 * plan.lut.unambiguous_range_m * 4:
        raise CaptureError(info.path, f"--distance {distance_m:g} m is implausible for this capture")
    # beat frequencies the static G(I) predicts, with room for a narrower real sweep
    half_s = info.modulation.period_s / 2
    rate = plan.lut.bandwidth_hz / half_s
    f_lo, f_hi = 0.15 * tau * rate, min(0.49 * fs, 4.0 * tau * rate)
    z = _analytic(beat.astype(np.float64), fs, f_lo, f_hi)
    hs = sync.half_sweeps(sync.sync_turning_points(sy, spp / 2), plan.lag)
    grid = np.linspace(S_LO, S_HI, GRID)
    level = np.median(np.abs(z))
    curves = {True: [], False: []}
    for start, length, rising in zip(hs.start, hs.length, hs.rising, strict=True):
        i0, i1 = int(np.floor(start + S_LO * length)), int(np.ceil(start + S_HI * length))
        if i0 < 0 or i1 >= z.size:
            continue
        zz = z[i0:i1 + 1]
        phase = np.unwrap(np.angle(zz))
        freq = np.gradient(phase) * fs / (2 * np.pi)
        good = (freq > 1.5 * f_lo) & (np.abs(zz) > 0.3 * level)
        s = (np.arange(i0, i1 + 1) - start) / length
        nu = phase / (2 * np.pi * tau)           # optical frequency up to sign and a constant
        row = np.interp(grid, s, np.where(good, nu, np.nan))
        core = (grid > 0.35) & (grid < 0.65)
        if np.isnan(row[core]).any():
            continue
        curves[bool(rising)].append(row - np.mean(row[core]))
    if min(len(c) for c in curves.values()) < 10:
        raise CaptureError(info.path, "too few clean half-sweeps to calibrate (is the target static, "
                                      "at the given distance, with a clear echo?)")
    sign = np.sign(plan.lut.u_rise[-1] - plan.lut.u_rise[0])   # +1: frequency rises with the current
    dirs, residual = [], []
    for rising in (True, False):
        rows = np.array(curves[rising])
        share = np.mean(np.isfinite(rows), axis=0)
        with warnings.catch_warnings():         # columns never measured stay NaN
            warnings.simplefilter("ignore", RuntimeWarning)
            mean = np.nanmean(np.where(share >= MIN_SHARE, rows, np.nan), axis=0)
        keep = _steep_stretch(grid, mean)
        residual.append(float(np.sqrt(np.nanmean((rows[:, keep] - mean[keep]) ** 2)) * 2 * np.pi * tau))
        direction = sign if rising else -sign
        dirs.append(Direction(grid[keep], direction * mean[keep]))
    chirp = Chirp(*dirs)
    attrs = {
        "distance_m": float(distance_m), "refractive_index": nidx,
        "periods_used": int(min(len(c) for c in curves.values())),
        "residual_phase_rad": float(max(residual)),
        "bandwidth_rising_hz": dirs[0].bandwidth_hz, "bandwidth_falling_hz": dirs[1].bandwidth_hz,
        "bandwidth_hz": chirp.bandwidth_hz, "static_bandwidth_hz": plan.lut.bandwidth_hz,
        "sync_delay_samples": float(plan.lag), "modulation_frequency_hz": info.modulation.frequency_hz,
        "sample_rate_hz": fs, "source": str(info.path), "software": f"fmcw-cl {__version__}",
    }
    return Chirp(chirp.rising, chirp.falling, attrs)


def _steep_stretch(grid: np.ndarray, nu: np.ndarray) -> np.ndarray:
    """Mask of the contiguous stretch around s = 0.5 where nu is measured and steep."""
    slope = np.abs(np.gradient(nu, grid))
    ok = np.isfinite(slope) & (slope >= STEEP * np.nanmedian(slope[(grid > 0.2) & (grid < 0.8)]))
    mid = int(np.argmin(np.abs(grid - 0.5)))
    lo = mid
    while lo > 0 and ok[lo - 1]:
        lo -= 1
    hi = mid
    while hi < grid.size - 1 and ok[hi + 1]:
        hi += 1
    keep = np.zeros(grid.size, bool)
    keep[lo:hi + 1] = True
    return keep
