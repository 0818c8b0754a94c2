"""Stage 1: low-pass of the beat channel, which keeps the laser intensity triangle.

Only the slow part is needed, so the stream is decimated first and the short stream
is then filtered by a zero-phase FIR. A plain block average is not enough: its sinc
response lets a chirped target beat alias to 0 Hz each time its frequency sweeps
past a multiple of the decimated rate, at the same place in every period, which
biases the sync delay. Three cascaded boxcars (a CIC decimator, sinc^3) fix that.
"""

from __future__ import annotations

import numpy as np

DECIMATION = 25      # 100 MS/s -> 4 MS/s
CIC_ORDER = 3
CUTOFF_HZ = 200e3    # keeps the 20 kHz triangle's first harmonics, rejects beats > 1 MHz
TAPS = 63


def boxcar(x: np.ndarray, length: int) -> np.ndarray:
    """Causal moving average: y[i] = mean(x[i : i + length]); len(y) = len(x) - length + 1."""
    c = np.concatenate([[0.0], np.cumsum(x, dtype=np.float64)])
    return (c[length:] - c[:-length]) / length


def cic_decimate(x: np.ndarray, factor: int = DECIMATION, order: int = CIC_ORDER) -> np.ndarray:
    """Decimate by `factor` with `order` cascaded boxcars of length `factor` (sinc^order).

    Output sample j represents input time j * factor + order * (factor - 1) / 2.
    """
    y = np.asarray(x, dtype=np.float64)
    for _ in range(order - 1):
        y = boxcar(y, factor)
    m = y.size // factor
    return y[: m * factor].reshape(m, factor).mean(axis=1)


def lowpass_taps(sample_rate_hz: float, cutoff_hz: float = CUTOFF_HZ, taps: int = TAPS) -> np.ndarray:
    """Symmetric (linear-phase) FIR taps, unit DC gain, for the decimated stream.

    scipy.signal.firwin's design (a Hamming-windowed sinc scaled to unit DC gain; equal
    to it, tests/test_stages.py), written out because importing scipy.signal costs a
    second, which `fmcw-cl info` would pay for 63 numbers.
    """
    c = 2 * cutoff_hz / sample_rate_hz               # cutoff over Nyquist
    m = np.arange(taps) - (taps - 1) / 2
    h = c * np.sinc(c * m) * (0.54 - 0.46 * np.cos(2 * np.pi * np.arange(taps) / (taps - 1)))
    return h / h.sum()


def lowpass(x: np.ndarray, taps: np.ndarray) -> np.ndarray:
    """Zero-phase FIR filter: symmetric taps applied centred ('same' length).

    The first and last len(taps)//2 outputs see a zero-padded input.
    """
    if x.size == 0:
        return np.zeros(0)
    h = taps.size // 2
    return np.convolve(x, taps)[h: h + x.size]


def intensity(beat: np.ndarray, sample_rate_hz: float, factor: int = DECIMATION
              ) -> tuple[np.ndarray, float, float]:
    """Low-passed beat channel at the decimated rate; of each row alone when `beat` is
    (rows, samples).

    Returns
    -------
    y : ndarray
        Low-passed beat (ADC codes) at sample_rate / factor, (m,) or (rows, m).
    t0 : float
        Input sample position of y[0] (samples).
    step : float
        Input samples between consecutive outputs.
    """
    t0 = CIC_ORDER * (factor - 1) / 2.0
    if np.ndim(beat) == 2:
        m = outputs(np.shape(beat)[1], factor)
        rows = [intensity(row, sample_rate_hz, factor)[0] for row in beat]
        return (np.stack(rows) if rows else np.zeros((0, m))), t0, float(factor)
    dec = cic_decimate(beat, factor)
    return lowpass(dec, lowpass_taps(sample_rate_hz / factor)), t0, float(factor)


def intensity_each(channels, sample_rate_hz: float) -> list[tuple[np.ndarray, float, float]]:
    """`intensity` of each array of `channels` (a backend's twin: one download)."""
    return [intensity(x, sample_rate_hz) for x in channels]


def outputs(samples: int, factor: int = DECIMATION) -> int:
    """Decimated samples from `samples` inputs (the CIC's whole outputs)."""
    return max(0, (samples - (CIC_ORDER - 1) * (factor - 1)) // factor)
