"""Stage 7: acceleration from the pairs' velocities.

Savitzky-Golay derivative (quadratic, 21 pairs = 1.05 ms at 20 kHz) over each run of
valid pairs; runs shorter than the window get a quadratic fit over the run, runs of
fewer than 3 pairs get NaN.
"""

from __future__ import annotations

import numpy as np

from ..numeric import runs, savgol_derivative

WINDOW_PAIRS = 21
POLYORDER = 2


def acceleration(velocity: np.ndarray, valid: np.ndarray, period_s: float,
                 window: int = WINDOW_PAIRS) -> np.ndarray:
    """Radial acceleration (m/s^2) from velocities sampled every `period_s` seconds.

    Invalid pairs are skipped: each run of consecutive valid pairs is differentiated
    on its own, so no value is invented across a gap. Invalid pairs get NaN.
    """
    acc = np.full(velocity.shape, np.nan)
    spans = runs(valid)
    n = spans[:, 1] - spans[:, 0]
    # a run's window: `window`, or its own length (odd) where shorter; the runs of each
    # window at once
    own = np.where(n >= window, window, n - 1 + n % 2)
    for w in map(int, np.unique(own[n >= 3])):
        savgol_derivative(velocity, w, min(POLYORDER, w - 1), period_s, spans[(own == w) & (n >= 3)], acc)
    return acc


def centred(valid: np.ndarray, window: int = WINDOW_PAIRS) -> np.ndarray:
    """The valid pairs whose acceleration window of `window` pairs lies whole within
    their run of valid pairs: within half a window of a run's end the derivative is an
    extrapolation of the fitted quadratic (a still target's first pair: -0.6 m/s^2)."""
    out = np.zeros(np.size(valid), bool)
    half = window // 2
    for a, b in runs(valid):
        if b - a > 2 * half:         # (a shorter run near the start: b - half < 0 would wrap)
            out[a + half: b - half] = True
    return out


def held(acceleration: np.ndarray, valid: np.ndarray, window: int = WINDOW_PAIRS) -> np.ndarray:
    """`acceleration` (computed over `window` pairs) where it is `centred`, each other
    valid pair of a run taking the nearest centred value (not the run end's
    extrapolation); 0 in runs shorter than the window, and where not valid. For a
    correction that needs the acceleration at every valid pair."""
    out = np.zeros(np.size(valid))
    half = window // 2
    for a, b in runs(valid):
        if b - a > 2 * half:
            out[a:b] = acceleration[np.clip(np.arange(a, b), a + half, b - half - 1)]
    return np.nan_to_num(out)
