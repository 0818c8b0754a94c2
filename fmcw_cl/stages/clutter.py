"""Stage 4b: the still echoes taken out of the resampled half-sweeps (clutter removal).

A still echo (a wall, a window, a target at rest) gives every half-sweep of one
direction the same resampled tone; a moving one turns its phase by 2 pi every half
wavelength of travel (0.78 um at 1550 nm), so its rows average to nearly nothing over a
few milliseconds (at 1 mm/s over 5 ms: 6 turns, 1/20 of its amplitude left). Each row
less the mean of its direction's rows within `half` rows of it (fewer at a chunk's ends)
keeps the movers and takes the still echoes out, with their de-chirped images: radar's
moving-target indication. The tracker of an object that moves through or beside fixed
ones searches these rows in its whole band (fmcw_cl.scene). What rests
(a foot on the window's distance) leaves these rows too: its pairs there have no echo.
"""

from __future__ import annotations

import numpy as np

STILL_S = 5e-3   # the running mean's span (s): movers faster than about 0.3 mm/s keep their echo
TREMBLING_S = 0.5e-3   # ... where a fixed echo trembles (a micrometre turns its phase through
                       # radians in milliseconds): movers from about 3 mm/s keep theirs


def half_width(period_s: float, span_s: float = STILL_S) -> int:
    """The running mean's half-width (pairs) for pairs `period_s` apart."""
    return max(1, int(round(0.5 * span_s / period_s)))


def without_still(x: np.ndarray, half: int) -> np.ndarray:
    """Rows `x` (half-sweeps of one direction, in time order; float32) each less the
    mean of rows [i - half, i + half] that exist (float64 running sum, in the order of
    kernels/clutter.cl, whose twin this is)."""
    x = np.asarray(x, np.float32)
    rows = x.shape[0]
    out = np.empty_like(x)
    s = np.zeros(x.shape[1], np.float64)
    hi = min(half + 1, rows)
    for r in range(hi):
        s += x[r]
    lo = 0
    for i in range(rows):
        out[i] = x[i] - (s / (hi - lo)).astype(np.float32)
        if hi < rows:
            s += x[hi]
            hi += 1
        if i - half >= 0:
            s -= x[i - half]
            lo += 1
    return out
