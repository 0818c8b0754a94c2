"""Medians for the host's many small arrays, without np.median's per-call overhead
(30-45 us, against 3-4 us for a partition of a few hundred values): the tracker and the
echo tables take them per chunk, per slice and per cluster."""

from __future__ import annotations

import numpy as np


def median(x: np.ndarray) -> float:
    """np.median of a 1-D array (NaN when it holds a NaN or is empty)."""
    x = np.asarray(x, dtype=np.float64)
    n = x.size
    if n == 0 or np.isnan(x).any():
        return float("nan")
    s = np.partition(x, [(n - 1) // 2, n // 2])
    return 0.5 * float(s[(n - 1) // 2] + s[n // 2])


def row_nanmedian(a: np.ndarray) -> np.ndarray:
    """np.nanmedian(a, axis=1) for rows with at least one number, without its masked
    arrays (10x faster on the tracker's (pairs, 16) predictions): NaNs sort last."""
    s = np.sort(a, axis=1)
    n = np.sum(~np.isnan(a), axis=1)
    rows = np.arange(a.shape[0])
    return 0.5 * (s[rows, (n - 1) // 2] + s[rows, n // 2])
