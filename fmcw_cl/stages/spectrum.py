"""Stage 5: spectra of the resampled half-sweeps and their peaks.

A real FFT (or, after a Doppler de-chirp, a complex one) zero-padded to a power of
two at least twice the points; the peak is searched above a minimum range (DC, the
intensity ramp and the lens reflection sit below it) and located between bins by a
parabola through the log power of three bins (Gaussian interpolation; with a Hann
window and 2x padding its bias is below 0.01 bin, see tests). The noise floor is the
mean power of the band outside +-GUARD_BINS of the peak (for white noise an unbiased
level; a median would need a selection the OpenCL peak kernel cannot do cheaply).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

GUARD_BINS = 32  # padded bins either side of the peak left out of the noise floor


@dataclass(frozen=True)
class Search:
    """Where and how the tracked peak is searched in a spectrum of nfft/2 bins.

    Attributes
    ----------
    lo, hi : the band [lo, hi) of padded bins (--min-range, --max-range); the tracked
        peak is the band's strongest.
    echoes : also list every CFAR echo from lo to the spectrum's end (stages.cfar; the
        plain first pass).
    reach : the half-width (pairs) of the tracker's velocity median, its continuity
        prior (stages.pairing; fmcw_cl.motion chooses it).
    bands : each pair's own band, (2, pairs, 2) int: [lo, hi) of its rising (0) and
        falling (1) half-sweep, inside [lo, hi) (fmcw_cl.course: an object's band that
        follows it in time); None: [lo, hi) for every pair.
    velocity : each pair's first de-chirp velocity (m/s, float32 values), where its
        course says how fast its object moves (fmcw_cl.course); None: the plain pass's
        (0 m/s) for every pair.
    """

    lo: int
    hi: int
    echoes: bool = False
    reach: int = 8
    bands: np.ndarray | None = field(default=None, compare=False, repr=False)
    velocity: np.ndarray | None = field(default=None, compare=False, repr=False)

    def band(self, direction: int, rows: np.ndarray | None = None) -> tuple:
        """The band [lo, hi) of the pairs `rows` (all when None) in `direction` (0:
        rising, 1: falling): ints, or an int array each where the pairs have bands."""
        if self.bands is None:
            return self.lo, self.hi
        own = self.bands[direction] if rows is None else self.bands[direction][rows]
        return own[:, 0], own[:, 1]


def fft_length(points: int) -> int:
    """Zero-padded FFT length: the power of two >= 2 * points."""
    return 1 << int(np.ceil(np.log2(2 * points)))


def power_spectra(x: np.ndarray, nfft: int) -> np.ndarray:
    """|FFT|^2 of each row over the non-negative frequencies 0 .. nfft/2 - 1.

    Real rows use a real FFT; complex rows (de-chirped) keep only the positive side,
    where the de-chirped range tone lies.
    """
    import scipy.fft  # imported where used: the command line starts fast

    if np.iscomplexobj(x):
        spec = scipy.fft.fft(x, nfft, axis=1, workers=-1)[:, : nfft // 2]
    else:
        spec = scipy.fft.rfft(x, nfft, axis=1, workers=-1)[:, : nfft // 2]
    return spec.real**2 + spec.imag**2


@dataclass(frozen=True)
class Peaks:
    """Per half-sweep: peak position (fractional bin of the padded FFT), SNR (dB)."""

    bin: np.ndarray
    snr_db: np.ndarray


def interpolate(power: np.ndarray, rows: np.ndarray, kk: np.ndarray) -> np.ndarray:
    """Fractional bin of the peaks at bins kk of `rows`: a parabola through the log
    power of three bins (kk clipped to the spectrum's inner bins)."""
    kk = np.clip(kk, 1, power.shape[1] - 2)
    tiny = np.finfo(np.float64).tiny
    a = np.log(power[rows, kk - 1] + tiny)
    b = np.log(power[rows, kk] + tiny)
    c = np.log(power[rows, kk + 1] + tiny)
    den = a - 2 * b + c
    with np.errstate(divide="ignore", invalid="ignore"):
        delta = np.where(den < 0, 0.5 * (a - c) / den, 0.0)
    return kk + np.clip(delta, -0.5, 0.5)


def find_peaks(power: np.ndarray, lo, hi=None) -> Peaks:
    """Largest peak of each row in bins [lo, hi), interpolated, with its SNR; `lo` and
    `hi` ints, or int arrays of each row's own band [lo[i], hi[i]) (hi > lo).

    The SNR is the peak power over the noise floor: the mean power of the band
    outside +-GUARD_BINS of the peak.
    """
    rows = np.arange(power.shape[0])
    own = bool(np.ndim(lo) or np.ndim(hi))
    if own and rows.size == 0:
        return Peaks(np.zeros(0), np.zeros(0, np.float32))
    if own:
        lo, hi = np.asarray(lo), np.asarray(hi)
        a, b = int(lo.min()), int(hi.max())          # the rows' bands' union
    else:
        a, b = lo, power.shape[1] if hi is None else hi
    band = power[:, a:b]
    cols = np.arange(a, b)
    inside = (cols[None, :] >= lo[:, None]) & (cols[None, :] < hi[:, None]) if own else None
    # power is never negative: -1 outside a row's band never wins, ties go to the lowest bin
    k = np.argmax(band if inside is None else np.where(inside, band, -1.0), axis=1) + a
    kk = np.clip(k, 1, power.shape[1] - 2)
    outside = np.abs(cols[None, :] - kk[:, None]) > GUARD_BINS
    if inside is not None:
        outside &= inside
    count = outside.sum(axis=1)
    # a band narrower than the guard has no outside: use the whole band's mean
    whole = band.mean(axis=1) if inside is None else np.sum(band * inside, axis=1) / inside.sum(axis=1)
    floor = np.where(count > 0, np.sum(band * outside, axis=1) / np.maximum(count, 1), whole)
    with np.errstate(divide="ignore"):
        snr = 10 * np.log10(power[rows, kk] / np.maximum(floor, np.finfo(np.float64).tiny))
    return Peaks(interpolate(power, rows, kk), snr.astype(np.float32))
