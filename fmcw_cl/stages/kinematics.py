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
    return derivative(velocity, valid, period_s, window)


def run_windows(valid: np.ndarray, window: int, min_pairs: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """The runs of `valid` of at least `min_pairs` ((R, 2) start, stop) and each one's
    window: `window`, or the run's own length made odd where shorter."""
    spans = runs(valid)
    n = spans[:, 1] - spans[:, 0]
    own = np.where(n >= window, window, n - 1 + n % 2)
    keep = n >= min_pairs
    return spans[keep], own[keep]


def derivative(x: np.ndarray, valid: np.ndarray, period_s: float, window: int = WINDOW_PAIRS,
               min_pairs: int = 3) -> np.ndarray:
    """Savitzky-Golay derivative (order POLYORDER) of x sampled every `period_s`, each
    run of `valid` (of at least `min_pairs`) on its own (`run_windows`), the runs of
    one window at once; NaN elsewhere."""
    out = np.full(np.shape(x), np.nan)
    spans, own = run_windows(valid, window, min_pairs)
    for w in map(int, np.unique(own)):
        savgol_derivative(x, w, min(POLYORDER, w - 1), period_s, spans[own == w], out)
    return out


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


def held_acceleration(velocity: np.ndarray, valid: np.ndarray, period_s: float,
                      window: int = WINDOW_PAIRS, hold: bool = True) -> np.ndarray:
    """The acceleration of `velocity`'s valid runs over `window` pairs at every valid
    pair (0 elsewhere): what the acceleration's bias correction of a distance needs
    (doppler.acceleration_bias). Near a run's ends `held` (a leg's, smooth over the
    window), or without `hold` the fit's own (a vibration's turns within its window:
    held over 2 pairs, a 1 kHz swing's acceleration moves by 60 % and its end pairs'
    distances by 0.3 mm)."""
    acc = acceleration(velocity, valid, period_s, window)
    return held(acc, valid, window) if hold else np.where(np.asarray(valid, bool), np.nan_to_num(acc), 0.0)
