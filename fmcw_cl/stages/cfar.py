"""Stage 5c: every echo of a half-sweep's spectrum, by a cell-averaging CFAR detector.

A bin k of the power spectrum (the zero-padded one of stage 5) is an echo when it is
a peak, the largest of bins k - GUARD .. k + GUARD (ties: the lowest bin), and it
stands above `scale(n)` times the mean of its n training cells: TRAIN bins on each side
beyond the guard, only bins at or above the search band's first bin (DC, the
intensity ramp and the lens sit below it and would raise the level).

For white noise the power of a bin is exponential, and the cell-averaging threshold
alpha = m (PFA^(-1/m) - 1) over m independent training cells gives a false-alarm
probability PFA per cell. With the 2x zero padding neighbouring bins are correlated,
so m = n / 2 is used; the false-alarm rate measured on pure noise (tests/test_cfar.py)
is below 1e-5 per bin, about one false echo in 200 half-sweeps at N = 1000.

Only the first MAX_ECHOES echoes of a half-sweep (nearest first) are kept. Twin of
kernels/cfar.cl (`local_cfar`, run inside fft.cl's spectrum_peak).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .spectrum import interpolate

GUARD = 8           # padded bins either side of the cell (Hann main lobe: +-4 at 2x padding)
TRAIN = 16          # training cells on each side beyond the guard
PFA = 1e-6          # false-alarm probability per independent cell
MAX_ECHOES = 8      # echoes kept per half-sweep, nearest first


def scales(pfa: float = PFA) -> np.ndarray:
    """Threshold factor for each count n = 0 .. 2 TRAIN of training cells (n / 2 of
    them independent at 2x padding); n = 0 never detects."""
    n = np.arange(2 * TRAIN + 1, dtype=np.float64)
    m = np.maximum(n / 2, 1e-9)
    with np.errstate(over="ignore"):
        alpha = m * (pfa ** (-1.0 / m) - 1.0)
    alpha[0] = np.inf
    return alpha


@dataclass(frozen=True)
class Detections:
    """Per half-sweep, the first MAX_ECHOES echoes in bin order.

    Attributes
    ----------
    bin : (S, MAX_ECHOES) fractional bin of the padded FFT (NaN past `count`).
    snr_db : (S, MAX_ECHOES) float32 peak power over the mean of its training cells (dB).
    count : (S,) int32 echoes kept.
    """

    bin: np.ndarray
    snr_db: np.ndarray
    count: np.ndarray

    @classmethod
    def empty(cls, sweeps: int = 0) -> Detections:
        return cls(np.full((sweeps, MAX_ECHOES), np.nan), np.full((sweeps, MAX_ECHOES), np.nan, np.float32),
                   np.zeros(sweeps, np.int32))

    def take(self, rows: np.ndarray) -> Detections:
        return Detections(self.bin[rows], self.snr_db[rows], self.count[rows])

    @classmethod
    def interleave(cls, a: Detections, b: Detections) -> Detections:
        """Rows a0, b0, a1, b1, ... (a pair's rising and falling half-sweeps)."""
        return cls(*(np.stack([getattr(a, k), getattr(b, k)], axis=1).reshape(-1, *getattr(a, k).shape[1:])
                     for k in ("bin", "snr_db", "count")))

    @classmethod
    def concat(cls, parts: list[Detections]) -> Detections:
        if not parts:
            return cls.empty()
        return cls(*(np.concatenate([getattr(p, k) for p in parts]) for k in ("bin", "snr_db", "count")))


def detect_mask(power: np.ndarray, lo: int, hi: int) -> tuple[np.ndarray, np.ndarray]:
    """Which bins of [lo, hi) are echoes, and their power over the training mean.

    Returns (mask, ratio), both (S, hi - lo).
    """
    s, half = power.shape
    k = np.arange(lo, hi)
    p = power[:, lo:hi]
    # training sums from a cumulative sum over the cells eligible for training, [lo, half),
    # padded so that every window, clipped to [lo, half), is a contiguous slice
    reach = GUARD + TRAIN + 1
    c = np.zeros((s, half + 1 + 2 * reach))
    np.cumsum(power[:, lo:], axis=1, out=c[:, reach + lo + 1: reach + half + 1])
    c[:, reach + half + 1:] = c[:, reach + half: reach + half + 1]

    def window(a: int, b: int):          # sums over bins [k + a, k + b) for all k of the band
        return window_sums(c, reach + lo, reach + hi, a, b)

    def count(a: int, b: int):
        return np.clip(k + b, lo, half) - np.clip(k + a, lo, half)

    n = count(-GUARD - TRAIN, -GUARD) + count(GUARD + 1, GUARD + TRAIN + 1)
    mean = (window(-GUARD - TRAIN, -GUARD) + window(GUARD + 1, GUARD + TRAIN + 1)) / np.maximum(n, 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = p / mean
    mask = p > scales()[n] * mean
    # the peak test on the few bins above threshold
    rows, cols = np.nonzero(mask)
    peak = is_peak(power, rows, cols + lo)
    mask[rows[~peak], cols[~peak]] = False
    return mask, ratio


def window_sums(c: np.ndarray, start: int, stop: int, a: int, b: int) -> np.ndarray:
    """Each row's sums over bins [k + a, k + b) for the columns k of [start, stop) of its
    cumulative sum `c` (c[:, j + 1] - c[:, j] the bin at column j): slices, no copies
    of `c`."""
    return c[:, start + b: stop + b] - c[:, start + a: stop + a]


def is_peak(power: np.ndarray, rows: np.ndarray, k: np.ndarray) -> np.ndarray:
    """Whether bin k[i] of row rows[i] of `power` is the largest of its +-GUARD bins
    (ties: the lowest; bins beyond the spectrum's ends do not count)."""
    half = power.shape[1]
    p = power[rows, k]
    peak = np.ones(rows.size, bool)
    for d in range(1, GUARD + 1):
        left, right = k - d, k + d
        peak &= (left < 0) | (p > power[rows, np.maximum(left, 0)])
        peak &= (right >= half) | (p >= power[rows, np.minimum(right, half - 1)])
    return peak


def detect(power: np.ndarray, lo: int, hi: int | None = None) -> Detections:
    """The echoes of each row of `power` (S, nfft/2) in bins [lo, hi), nearest first."""
    hi = power.shape[1] if hi is None else hi
    out = Detections.empty(power.shape[0])
    if hi <= lo or power.shape[0] == 0:
        return out
    mask, ratio = detect_mask(power, lo, hi)
    rank = np.cumsum(mask, axis=1) - 1
    rows, cols = np.nonzero(mask & (rank < MAX_ECHOES))
    slot = rank[rows, cols]
    kk = cols + lo
    out.bin[rows, slot] = interpolate(power, rows, kk)
    with np.errstate(divide="ignore"):
        out.snr_db[rows, slot] = 10 * np.log10(ratio[rows, cols])
    out.count[:] = np.minimum(mask.sum(axis=1), MAX_ECHOES)
    return out

