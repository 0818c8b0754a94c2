"""Half-sweep spectra of a stretch of a capture, before and after the correction.

"Before" is the paper's Fig. 5: a plain FFT of the half-sweep as sampled in time,
read on a distance axis as if the chirp were linear (f_b = (B/T) 2Rn/c). "After" is
its Fig. 6(a): the same half-sweep resampled at uniform optical frequency by the LUT.
Both use the numpy stages and the track's own parameters, recomputed from the source
capture for the stretch that is shown only (the full spectra are never stored).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..capture import Capture
from ..chirp import Chirp
from ..options import Options
from ..physics import C
from ..plan import CALIBRATION, make_plan
from ..stages import delay, resample, spectrum, sync


@dataclass(frozen=True)
class Spectra:
    """Power spectra (dB) of consecutive half-sweeps of one stretch.

    Attributes
    ----------
    time_s : (S,) half-sweep centre times.
    rising : (S,) current-rising half-sweeps.
    distance_m : (K,) distance axis of the corrected spectra.
    corrected_db : (S, K) spectra after resampling at uniform optical frequency.
    raw_distance_m : (L,) distance axis of the uncorrected spectra (linear-chirp reading).
    raw_db : (S, L) plain FFT of the time samples.
    """

    time_s: np.ndarray
    rising: np.ndarray
    distance_m: np.ndarray
    corrected_db: np.ndarray
    raw_distance_m: np.ndarray
    raw_db: np.ndarray


def _db(power: np.ndarray, axis_m: np.ndarray, min_range_m: float) -> np.ndarray:
    """Power in dB relative to each row's peak beyond `min_range_m` (DC and the
    intensity ramp below it would set the scale otherwise)."""
    p = np.maximum(power, np.finfo(np.float64).tiny)
    return 10 * np.log10(p / p[:, axis_m >= min_range_m].max(axis=1, keepdims=True))


def stretch_spectra(path, t0_s: float, t1_s: float, points: int = 1000,
                    lag: float | None = None, min_range_m: float = 0.03,
                    chirp: Chirp | None = None) -> Spectra:
    """Spectra of every half-sweep whose centre lies in [t0_s, t1_s) (s).

    Parameters
    ----------
    path : the capture.
    t0_s, t1_s : the stretch (s); clipped to the capture.
    points : resampling intervals (the track's ``points``).
    lag : samples the sync lags the optics (the track's ``sync_delay_samples``);
        estimated from the capture when None.
    min_range_m : the dB scale of each spectrum is its peak beyond this distance (m).
    chirp : the chirp the track was made with, if one replaced the G(I) table (the
        "after" spectra use the LUT the track used).
    """
    with Capture(path) as cap:
        info = cap.info
        plan = make_plan(cap, Options(points=points), lag)
        if chirp is not None:
            plan = plan.with_chirp(chirp, CALIBRATION)
        fs = info.sample_rate_hz
        hp = info.samples_per_period / 2
        margin = int(2 * info.samples_per_period + delay.MAX_DELAY_SAMPLES)
        a = max(0, int(t0_s * fs) - margin)
        b = min(info.samples, int(t1_s * fs) + margin)
        beat, sy = cap.read(a, b)
    hs = sync.half_sweeps(sync.sync_turning_points(sy, hp), plan.lag)
    centre = (a + hs.centre) / fs
    keep = (centre >= t0_s) & (centre < t1_s) & resample.inside(hs.start, hs.length, plan.lut, beat.size)
    if not keep.any():
        raise ValueError(f"{path}: no complete half-sweep between {t0_s:g} and {t1_s:g} s")
    start, length, rising = hs.start[keep], hs.length[keep], hs.rising[keep]
    nfft = plan.model.nfft
    corrected = np.empty((start.size, nfft // 2))
    for direction in (True, False):
        sel = rising == direction
        if sel.any():
            x = resample.resample(beat, start[sel], length[sel], plan.lut.u(direction), plan.window)
            corrected[sel] = spectrum.power_spectra(x, nfft)
    # plain FFT of the time samples: same count of points per half-sweep (whole samples)
    n_raw = int(np.floor(length.min()))
    first = np.ceil(start).astype(np.int64)
    raw = beat[first[:, None] + np.arange(n_raw)].astype(np.float64)
    raw -= raw.mean(axis=1, keepdims=True)
    raw *= resample.window(n_raw)
    nfft_raw = spectrum.fft_length(n_raw)
    raw_power = spectrum.power_spectra(raw, nfft_raw)
    lut = plan.lut
    # linear-chirp reading: a beat f is at R = f c T / (2 n B), T = n_raw / fs
    raw_axis = np.arange(nfft_raw // 2) * fs / nfft_raw * C * (n_raw / fs) / (
        2 * info.refractive_index * lut.bandwidth_hz)
    axis = np.arange(nfft // 2) * plan.model.metres_per_bin
    return Spectra(centre[keep], rising, axis, _db(corrected, axis, min_range_m), raw_axis,
                   _db(raw_power, raw_axis, min_range_m))
