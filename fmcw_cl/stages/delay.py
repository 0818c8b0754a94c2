"""Stage 2, the sync-to-optics delay: how far the sync channel lags the optics, per
modulation period (`period_delays`: the low-passed beat fitted on the low-passed sync,
`fit_periods`), and one delay from those periods (`combine_delays`).
"""

from __future__ import annotations

import numpy as np

from . import lpf

MAX_DELAY_SAMPLES = 400  # search range of the sync-to-optics delay


def period_delays(beat: np.ndarray, sync: np.ndarray, sample_rate_hz: float, half_period: float,
                  intensity_each=lpf.intensity_each, fit=None) -> tuple[np.ndarray, np.ndarray]:
    """Per-period estimates of how far the sync lags the optics (samples).

    The low-passed beat carries the laser intensity triangle, which has the optical
    timing. The sync is passed through the same decimation and low-pass, so both
    triangles have identically rounded corners; the beat is then regressed, one
    modulation period at a time, on the shifted template and its derivative
    (Gauss-Newton, `fit_periods`). The detector imbalance may have either sign: the
    regression's scale takes it.

    `beat` and `sync` are (samples,), or (stretches, samples): stretches of the capture,
    both channels low-passed by one call of `intensity_each` (lpf.intensity_each or a
    backend's kernels) and fitted each alone, all by one call of `fit` (fit_periods or
    a backend's kernel).

    Returns
    -------
    lags : (P,) samples, NaN where a period gives no triangle (the stretches' in turn).
    misfit : (P,) rms residual of each period's fit relative to the triangle's rms;
        large where a target beat near 0 Hz leaks into the low band.
    """
    (y, _, step), (z, _, _) = intensity_each((beat, sync), sample_rate_hz)
    y, z = np.atleast_2d(y), np.atleast_2d(z)
    got = delay_windows(y.shape, step, half_period)
    if got is None:
        return np.zeros(0), np.zeros(0)
    edge, span, period = got
    y, z = y[:, edge:-edge], z[:, edge:-edge]
    y = y - y.mean(axis=1, keepdims=True)
    z = z - z.mean(axis=1, keepdims=True)
    # coarse: integer lag (decimated samples) of the largest |cross-correlation|
    shift = np.array([np.argmax(np.abs(np.correlate(b, a[span:-span], "valid"))) - span   # lags -span..span
                      for a, b in zip(y, z, strict=True)], np.float64)
    lags, misfit = (fit or fit_periods)(y, z, shift, period, span)
    return (lags * step).ravel(), misfit.ravel()


def delay_windows(shape: tuple[int, int], step: float, half_period: float) -> tuple[int, int, int] | None:
    """Where `period_delays` looks in low-passed rows of `shape` (rows, samples at the
    decimated rate, `step` samples apart): the samples left out at each end (the
    low-pass's edge), the coarse lags' reach either way and the samples of a period, in
    decimated samples; None where the rows are too few or too short."""
    edge = lpf.TAPS // 2 + 1
    span = int(MAX_DELAY_SAMPLES / step) + 1
    period = int(round(2 * half_period / step))
    if shape[0] == 0 or shape[1] - 2 * edge < 2 * span + 2 * period:
        return None
    return edge, span, period


def fit_periods(y: np.ndarray, z: np.ndarray, shift: np.ndarray, period: int, span: int
                ) -> tuple[np.ndarray, np.ndarray]:
    """The Gauss-Newton fit of each period of each row: beat y on the sync template z
    moved by a lag (decimated samples), its derivative and a constant, three steps from
    the row's coarse `shift`.

    Parameters
    ----------
    y, z : (rows, n) low-passed beat and sync, each row's mean removed.
    shift : (rows,) coarse lag of each row (decimated samples).
    period : decimated samples of one period; the periods start at `span` and go on
        while `span` samples are left after them (`period_starts`).

    Returns
    -------
    lags : (rows, periods) decimated samples, NaN where a period gives no triangle.
    misfit : (rows, periods) rms residual relative to the fitted triangle's rms.
    """
    windows = period_starts(y.shape[1], period, span)[:, None] + np.arange(period)
    # a row at a time: the temporaries of all at once are large enough that the
    # allocator returns them to the system and faults them in again each time
    got = [_fit_row(a, b, np.full(1, float(s)), windows) for a, b, s in zip(y, z, shift, strict=True)]
    return tuple(np.stack([g[i] for g in got]) for i in (0, 1))


def period_starts(n: int, period: int, span: int) -> np.ndarray:
    """First samples of the periods fit_periods fits in a row of n: from `span` on, while
    `span` samples are left after a period."""
    return np.arange(span, n - span - period, period)


def _fit_row(y: np.ndarray, z: np.ndarray, shift: np.ndarray, windows: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
    """fit_periods of one row."""
    yw = y[windows]
    period = windows.shape[1]
    gram = np.zeros((windows.shape[0], 3, 3))
    gram[:, 0, 0] = period

    def dot(a, b):                    # per period
        return np.einsum("pk,pk->p", a, b)

    for _ in range(3):
        # shift the template period by period (one shift for all in the first pass)
        zs = _shifted(z, windows, shift)
        dz = np.empty_like(zs)                              # np.gradient along a period
        dz[:, 1:-1] = (zs[:, 2:] - zs[:, :-2]) / 2.0
        dz[:, 0], dz[:, -1] = zs[:, 1] - zs[:, 0], zs[:, -1] - zs[:, -2]
        # batched least squares on (1, zs, dz): the 3x3 normal equations of each period
        gram[:, 0, 1] = gram[:, 1, 0] = zs.sum(axis=1)
        gram[:, 0, 2] = gram[:, 2, 0] = dz.sum(axis=1)
        gram[:, 1, 2] = gram[:, 2, 1] = dot(zs, dz)
        gram[:, 1, 1], gram[:, 2, 2] = dot(zs, zs), dot(dz, dz)
        rhs = np.stack([yw.sum(axis=1), dot(zs, yw), dot(dz, yw)], 1)
        coef = np.linalg.solve(gram + 1e-12 * np.eye(3), rhs[..., None])[..., 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            step_lag = np.where(np.abs(coef[:, 1]) > 0, coef[:, 2] / coef[:, 1], np.nan)
        shift = shift + np.nan_to_num(step_lag)
    resid = yw - (coef[:, :1] + coef[:, 1:2] * zs + coef[:, 2:] * dz)
    with np.errstate(divide="ignore", invalid="ignore"):
        misfit = np.sqrt(np.mean(resid**2, axis=1) / np.mean((coef[:, 1:2] * zs) ** 2, axis=1))
    return np.where(np.isfinite(step_lag), shift, np.nan), misfit


def _shifted(z: np.ndarray, windows: np.ndarray, shift: np.ndarray) -> np.ndarray:
    """np.interp(windows + shift[:, None], arange(z.size), z): z at the samples of each
    row of `windows` moved by the row's shift, linear between samples, held at the
    ends. One shift a row has one fraction: two gathers, no search."""
    whole = np.floor(shift)
    i = windows + whole.astype(np.int64)[:, None]
    frac = (shift - whole)[:, None]
    if i.min() < 0 or i.max() > z.size - 2:       # a row off the stretch: clamp sample by sample
        x = windows + shift[:, None]
        i = np.clip(np.floor(x).astype(np.int64), 0, z.size - 2)
        frac = np.clip(x - i, 0.0, 1.0)
    a = z[i]
    return a + frac * (z[i + 1] - a)


CLEAN_MISFIT = 0.2  # a clean intensity triangle fits to a few percent rms


def combine_delays(lags: np.ndarray, misfit: np.ndarray) -> tuple[float, int, float, float]:
    """Median lag over the periods that fit well: misfit within 3x the best decile's.

    A stretch where a target's beat sweeps through 0 Hz in every period (a fast
    target near the lens) fits badly; gating on the best decile keeps the clean
    periods even when they are few.

    Returns (lag, periods used, misfit of the best decile, the median's standard
    error: 1.25 x the periods' robust spread / sqrt(periods), NaN under 3 periods);
    (nan, 0, nan, nan) if none. The estimate is unreliable when the misfit exceeds
    CLEAN_MISFIT.
    """
    ok = np.isfinite(lags) & np.isfinite(misfit)
    if not np.any(ok):
        return float("nan"), 0, float("nan"), float("nan")
    best = float(np.percentile(misfit[ok], 10))
    ok &= misfit <= 3.0 * best
    used = lags[ok]
    mid = float(np.median(used))
    spread = 1.4826 * float(np.median(np.abs(used - mid)))
    sigma = 1.2533 * spread / np.sqrt(used.size) if used.size >= 3 else float("nan")
    return mid, int(ok.sum()), best, sigma
