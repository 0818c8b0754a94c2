"""Stage 4: resample each half-sweep at the instants of uniform optical frequency.

Cubic convolution (Keys, a = -0.5) straight from the int16 ADC codes, then mean
removal and a Hann window, for a batch of half-sweeps of one direction.
"""

from __future__ import annotations

import functools

import numpy as np


def keys_weights(frac: np.ndarray) -> tuple[np.ndarray, ...]:
    """Cubic-convolution weights of samples i-1, i, i+1, i+2 for x = i + frac."""
    f = frac
    f2 = f * f
    f3 = f2 * f
    return (-0.5 * f3 + f2 - 0.5 * f,
            1.5 * f3 - 2.5 * f2 + 1.0,
            -1.5 * f3 + 2.0 * f2 + 0.5 * f,
            0.5 * f3 - 0.5 * f2)


@functools.lru_cache(maxsize=8)
def window(points: int) -> np.ndarray:
    """Periodic-free symmetric Hann window of `points` samples (float64), read-only:
    one object per length, so that a device uploads it once (opencl.Buffers.constant)."""
    win = 0.5 - 0.5 * np.cos(2 * np.pi * (np.arange(points) + 0.5) / points)
    win.flags.writeable = False
    return win


def positions(starts: np.ndarray, lengths: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Sample positions starts + u * lengths, shape (sweeps, points), float64."""
    return np.asarray(starts, np.float64)[:, None] + np.outer(lengths, u)


def inside(starts: np.ndarray, lengths: np.ndarray, lut, size: int) -> np.ndarray:
    """Half-sweeps whose every resampling position, in either direction of `lut`, keeps
    the cubic kernel's four samples inside `size` codes (with a sample of margin). A
    calibrated LUT may reach past the half-sweep's ends (u < 0 or u > 1)."""
    lo = min(lut.u_rise.min(), lut.u_fall.min(), 0.0)
    hi = max(lut.u_rise.max(), lut.u_fall.max(), 1.0)
    return (starts + lo * lengths >= 2) & (starts + hi * lengths < size - 3)


def resample(codes: np.ndarray, starts: np.ndarray, lengths: np.ndarray, u: np.ndarray,
             win: np.ndarray | None = None) -> np.ndarray:
    """Resampled, mean-removed, windowed half-sweeps.

    Parameters
    ----------
    codes : (n,) int16
        Beat channel ADC codes of the chunk.
    starts : (S,) float64
        Position (samples into `codes`) of each half-sweep's first optical turning point.
    lengths : (S,) float64
        Half-sweep durations in samples.
    u : (N,) float64
        LUT: fractions of the half-sweep at which to sample.
    win : (N,) float64, optional
        Window applied after mean removal (default Hann).

    Returns
    -------
    (S, N) float64. Positions must satisfy 1 <= p < n - 2.
    """
    p = positions(starts, lengths, u)
    i = np.floor(p).astype(np.int64)
    w = keys_weights(p - i)
    x = codes.astype(np.float64, copy=False)
    y = w[0] * x[i - 1] + w[1] * x[i] + w[2] * x[i + 1] + w[3] * x[i + 2]
    y -= y.mean(axis=1, keepdims=True)
    y *= window(u.size) if win is None else win
    return y
