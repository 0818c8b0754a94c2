"""Per-pair uncertainty, as GUM states it: each valid pair's expanded uncertainty
(k = 2) of its distance and of its velocity, from its sources, and the capture's
budget; and validity per quantity: a pair's velocity is verified against its
distances' own course, its acceleration where its smoothing window lies whole on
verified velocities.

Sources (standard uncertainties, combined in quadrature):

distance
    noise: the scatter of the pair's own distances about a smooth course, measured
    locally (second differences of neighbours and of pairs 4 apart, the motion taken
    off, robust: errors correlated over a few pairs included), never below the
    Cramer-Rao bound at its half-sweeps' SNR; scale: the G(I) table's (or calibration's) relative
    uncertainty times the distance; resampling: the cubic convolution's phase error at
    the beat's frequency (`resampling_m`); sync delay: the refined delay's uncertainty as a
    distance; model: a tenth of the acceleration's bias correction (its model weighs the
    half-sweep by the window alone, not by the beat's amplitude, which rises with the
    laser's power: 7 % too large where the power is proportional to I - 12 mA; and the
    smoothed acceleration it uses); integration: the motion within the half-sweeps summed
    for a weak echo, a (K T)^2 / 12.
velocity
    noise: its local scatter, or where larger that of its residuals about a smooth
    course (`course_scatter`: errors that wander over tens of pairs); sync delay: the
    refined delay's uncertainty as a velocity, and where the delay was refined on
    another echo (a wall, a wall's fold beyond the range), the pairs' own kinematic
    mismatch (`transferred_mps`); time base: the sync's measured period against the
    file's attributes, |ratio - 1| (|v| + the median |v|: the delay refined on the
    target moves with it); integration: a K T / sqrt(12) for K > 1 half-sweeps summed
    (K = 1: none, a pair's velocity is its half-sweeps' mean, the truth at its centre
    under a steady acceleration).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from .numeric import drifts, running_median, running_nanmedian, runs, savgol_rows
from .stages import kinematics
from .stages.resample import keys_weights

COVERAGE = 2.0          # k of the expanded uncertainties
SCATTER_PAIRS = 41      # window (pairs) of the local scatter
CORRELATED_PAIRS = 4    # second differences this many pairs apart see errors correlated over fewer
MODEL_SHARE = 0.1       # share of the acceleration bias correction taken as its uncertainty
SLOPE_PAIRS = 21        # window (pairs) of the distances' slope the velocity is checked against
SLOPE_MIN_PAIRS = 7     # a run shorter than this cannot check its velocities
SLOPE_SIGMAS = 5.0      # a velocity this many standard errors from the slope is not verified ...
SLOPE_FLOOR_MPS = 0.01  # ... plus this (the distances' correlated errors: the table's ripple
                        # passed at speed)
TRANSFER_APART_M = 0.02  # a delay refined this far outside the pairs' span was refined on another echo
CHI2_MEDIAN = 0.45494   # median of chi-squared, one degree of freedom: a median of squares over it
DISTANCE_SOURCES = ("noise", "scale", "resampling", "sync delay", "model", "integration")
VELOCITY_SOURCES = ("noise", "sync delay", "time base", "integration")


def check_said(window: int = SLOPE_PAIRS) -> str:
    """How `velocity_verified` checks a velocity, in words (a track's attribute)."""
    return (f"against the distances' slope (quadratic over {window} pairs) within {SLOPE_SIGMAS:g} "
            f"standard errors + {SLOPE_FLOOR_MPS:g} m/s")


@dataclass
class Uncertainty:
    """Per pair (NaN where the quantity is not valid): expanded uncertainties (k = 2)
    of distance (m) and velocity (m/s), and each source's standard uncertainty."""

    distance_m: np.ndarray
    velocity_mps: np.ndarray
    distance_sources: dict[str, np.ndarray]
    velocity_sources: dict[str, np.ndarray]

    def budget(self, quantity: str) -> list[tuple[str, float, float]]:
        """The capture's budget of `quantity` ("distance" or "velocity"): per source,
        its rms standard uncertainty over the valid pairs and its share of the combined
        variance; the last row the combined one (share 1)."""
        sources = self.distance_sources if quantity == "distance" else self.velocity_sources
        ms = {name: float(np.nanmean(u * u)) if np.isfinite(u).any() else float("nan")
              for name, u in sources.items()}
        total = float(np.nansum(list(ms.values())))
        rows = [(name, float(np.sqrt(m)), m / total if total > 0 else float("nan")) for name, m in ms.items()]
        return rows + [("combined", float(np.sqrt(total)), 1.0)]


def run_median(x: np.ndarray, valid: np.ndarray, window: int = SCATTER_PAIRS) -> np.ndarray:
    """Per valid pair, the median of the finite values of x over `window` pairs of its
    own run (NaN where there are none); NaN outside `valid`."""
    return running_nanmedian(x, window, runs(valid))


def local_scatter(x: np.ndarray, valid: np.ndarray, window: int = SCATTER_PAIRS, lag: int = 1,
                  motion: np.ndarray | None = None) -> np.ndarray:
    """Per valid pair, the standard deviation of x's white part near it: from its run's
    second differences of pairs `lag` apart (6 sigma^2 for white noise; a motion's smooth
    part, a (lag T)^2, lies far below at lag 1, and `motion`, where given, is that part
    taken off), robustly (1.4826 median |.| / sqrt 6) over `window` pairs of its run. NaN
    where its run has fewer than 2 lag + 1 pairs."""
    x = np.asarray(x, np.float64)
    d2 = np.full(x.size, np.nan)
    d2[lag:-lag] = x[:-2 * lag] - 2 * x[lag:-lag] + x[2 * lag:]
    if motion is not None:
        d2[lag:-lag] -= motion[lag:-lag]
    d2 = np.abs(d2)
    # only second differences whole within a run: not at its first and last `lag` pairs
    spans = runs(valid)
    for k in range(lag):
        first, last = spans[:, 0] + k, spans[:, 1] - 1 - k
        d2[first[first < spans[:, 1]]] = np.nan
        d2[last[last >= spans[:, 0]]] = np.nan
    return 1.4826 * run_median(d2, valid, window) / np.sqrt(6.0)


def correlated_scatter(x: np.ndarray, valid: np.ndarray, acceleration: np.ndarray, period_s: float,
                       lag: int = CORRELATED_PAIRS, window: int = SCATTER_PAIRS) -> np.ndarray:
    """Per valid pair, the standard deviation of x's errors near it, those correlated
    over a few pairs included: `local_scatter` of pairs `lag` apart, past the errors'
    correlation (the rail's distances: +0.30, +0.22, +0.08 at 1-3 pairs, which second
    differences of neighbours read 19 % low), less the motion's a (lag T)^2 from the
    pair's `acceleration` (m/s^2). NaN where its run has fewer than 2 lag + 1 pairs."""
    a = np.nan_to_num(np.asarray(acceleration, np.float64))
    return local_scatter(x, valid, window, lag, a * (lag * period_s) ** 2)


def weakness(crb: np.ndarray, valid: np.ndarray, window: int = SCATTER_PAIRS) -> np.ndarray:
    """Per valid pair, its Cramer-Rao bound over the median of its run's within `window`
    pairs, at least 1: how much noisier than the pairs its local scatter was measured on
    its own SNR makes it (a fade's edge, the pairs beside a gap). 1 elsewhere."""
    return np.fmax(1.0, np.nan_to_num(crb / run_median(crb, valid, window), nan=1.0))


def pair_crb(snr_db: tuple[np.ndarray, np.ndarray], points: int, bandwidth_hz: float,
             refractive_index: float) -> np.ndarray:
    """Cramer-Rao bound (m) of each pair's distance from its two half-sweeps' SNRs."""
    rise, fall = (crb_m(peak_eta(s, points), points, bandwidth_hz, refractive_index) for s in snr_db)
    return 0.5 * np.hypot(rise, fall)


def velocity_crb(snr_db: tuple[np.ndarray, np.ndarray], points: int, bandwidth_hz: float,
                 refractive_index: float, shift_s: np.ndarray | float) -> np.ndarray:
    """Cramer-Rao bound (m/s) of each pair's velocity: its two half-sweeps' peaks'
    (`pair_crb`) over `shift_s`, how far apart a m/s moves them (s: the time between
    their centres and the Doppler shifts, stages.doppler.solve_pair)."""
    return 2 * pair_crb(snr_db, points, bandwidth_hz, refractive_index) / np.abs(shift_s)


def distance_slope(distance: np.ndarray, valid: np.ndarray, period_s: float,
                   window: int = SLOPE_PAIRS) -> tuple[np.ndarray, np.ndarray]:
    """The slope (m/s) of the distances at each valid pair, by a quadratic
    least-squares fit over `window` pairs of its run (its own length where shorter,
    the first and last pairs from the run's end windows), and the gain (1/s) that turns
    the distances' white noise (m) into the slope's standard error. NaN in runs shorter
    than SLOPE_MIN_PAIRS."""
    slope = kinematics.derivative(distance, valid, period_s, window, SLOPE_MIN_PAIRS)
    gain = np.full(np.size(distance), np.nan)
    spans, own = kinematics.run_windows(valid, window, SLOPE_MIN_PAIRS)
    for (a, b), w in zip(spans, map(int, own), strict=True):
        norms = np.linalg.norm(savgol_rows(w, kinematics.POLYORDER), axis=1) / period_s
        half = w // 2
        gain[a:b] = norms[half]
        gain[a:a + half] = norms[:half]
        gain[b - half:b] = norms[half + 1:]
    return slope, gain


def velocity_verified(distance: np.ndarray, velocity: np.ndarray, valid: np.ndarray, period_s: float,
                      noise_m: np.ndarray, noise_mps: np.ndarray, window: int = SLOPE_PAIRS) -> np.ndarray:
    """The valid pairs whose velocity (m/s) agrees with the slope of their run's
    distances (m) within SLOPE_SIGMAS standard errors (from the local noises `noise_m`
    and `noise_mps`) plus SLOPE_FLOOR_MPS: the Doppler velocity and the distance's course
    are measured apart (a sync delay error, an echo beside a wall, a crossing move one
    and not the other). Runs shorter than SLOPE_MIN_PAIRS cannot be checked: not
    verified."""
    slope, gain = distance_slope(distance, valid, period_s, window)
    tol = SLOPE_SIGMAS * np.hypot(gain * noise_m, noise_mps) + SLOPE_FLOOR_MPS
    with np.errstate(invalid="ignore"):
        return np.asarray(valid, bool) & (np.abs(velocity - slope) <= tol)


def peak_eta(snr_db, points: int) -> np.ndarray:
    """Per-point SNR eta = A^2 / (2 sigma^2) of N resampled points from their peak's SNR
    (dB, peak over mean noise per bin, Hann window, zero-padded FFT): peak (A N / 4)^2
    over sigma^2 3N/8 is eta N / 3."""
    return 3 * 10 ** (np.asarray(snr_db, np.float64) / 10) / points


def crb_m(eta, points: int, bandwidth_hz: float, refractive_index: float = 1.0) -> np.ndarray:
    """Cramer-Rao bound (m, standard deviation) of one half-sweep's distance from N
    resampled points of per-point SNR eta: a tone in white noise has var(f) >= 12 /
    ((2 pi)^2 eta N (N^2 - 1)) cycles per point; a cycle per point is N c / (2 n B)
    metres."""
    var_f = 12 / ((2 * np.pi) ** 2 * np.asarray(eta, np.float64) * points * (points**2 - 1))
    return 299_792_458.0 * points / (2 * refractive_index * bandwidth_hz) * np.sqrt(var_f)


@functools.lru_cache(maxsize=1)
def _keys_phase_error() -> tuple[np.ndarray, np.ndarray]:
    """(f, the largest phase error (rad) of cubic convolution over the fractional
    positions) for tones of f cycles per sample, 0-0.5."""
    f = np.linspace(0.0, 0.5, 257)
    phi = np.linspace(0.0, 1.0, 129)
    w = keys_weights(phi)
    h = sum(wk[None, :] * np.exp(2j * np.pi * f[:, None] * (k - phi[None, :]))
            for k, wk in zip((-1, 0, 1, 2), w, strict=True))
    return f, np.max(np.abs(np.angle(h)), axis=1)


def resampling_m(distance: np.ndarray, cycles_per_sample_per_m: float, resolution_m: float) -> np.ndarray:
    """Standard uncertainty (m) the resampling's cubic convolution leaves in a distance:
    at the beat's frequency f (cycles per sample) its phase error reaches eps(f) at some
    fractional positions, and a phase ramp of up to 2 eps across the half-sweep moves
    the peak by eps / pi bins; a bound, as a rectangular distribution (/ sqrt 3). It
    does not average: with a period a whole number of samples every period has the
    same fractional positions (0.1 um at 0.1 m, 1.5 um at 0.3 m, 5 um at 0.45 m)."""
    f, eps = _keys_phase_error()
    at = np.clip(np.abs(np.nan_to_num(distance)) * cycles_per_sample_per_m, 0.0, 0.5)
    return np.interp(at, f, eps) / np.pi * resolution_m / np.sqrt(3.0)


def transferred_mps(time_s: np.ndarray, distance: np.ndarray, velocity: np.ndarray, valid: np.ndarray,
                    refined_at_m: float) -> float:
    """Standard uncertainty (m/s) of the velocity bias a sync delay refined on another
    echo leaves on these pairs: their own kinematic mismatch (the drift of the distance
    less the integrated velocity, refine's measure, which a delay error moves and a
    consistent track keeps at zero; its runs of refine.MIN_RUN valid pairs, weighted by
    their errors, jackknifed as refine's are) and its standard error, in quadrature. The delay moves to
    zero the mismatch of the echo it is refined on, whose own errors it then passes on:
    a wall's fold beyond the range, refined on, left a static target at 0.24 m -0.20 to
    -0.39 mm/s off. 0 where the delay was refined within TRANSFER_APART_M of the pairs'
    span (1st-99th percentile) or they hold no such run."""
    from .refine import JACKKNIFE_BLOCKS, MIN_RUN  # here: refine imports motion, which reads this module

    ok = np.asarray(valid, bool) & np.isfinite(distance) & np.isfinite(velocity)
    if not ok.any() or not np.isfinite(refined_at_m):
        return 0.0
    lo, hi = np.percentile(distance[ok], [1, 99])
    if lo - TRANSFER_APART_M <= refined_at_m <= hi + TRANSFER_APART_M:
        return 0.0
    spans = [(a, b) for a, b in runs(ok) if b - a >= MIN_RUN]
    if not spans:
        return 0.0
    idx = np.concatenate([np.arange(a, b) for a, b in spans])
    slope, error = drifts(time_s[idx], distance[idx], velocity[idx], np.array([b - a for a, b in spans]),
                           JACKKNIFE_BLOCKS)
    w = 1.0 / np.square(np.fmax(error, 1e-12))
    return float(np.hypot(np.sum(w * slope) / np.sum(w), 1.0 / np.sqrt(np.sum(w))))


def finite_or_zero(x: float) -> float:
    """x, or 0 where not finite (a source the capture could not measure)."""
    return float(x) if np.isfinite(x) else 0.0


def pair_uncertainty(distance: np.ndarray, velocity: np.ndarray, valid: np.ndarray,
                     velocity_valid: np.ndarray, noise_m: np.ndarray, noise_mps: np.ndarray,
                     crb: np.ndarray, acceleration: np.ndarray, bias_correction_m: np.ndarray,
                     integrated: np.ndarray, *, period_s: float, scale_ppm: float, delay_m: float,
                     delay_mps: float, period_ratio: float, cycles_per_sample_per_m: float = 0.0,
                     resolution_m: float = 0.0) -> Uncertainty:
    """Each valid pair's expanded uncertainties (k = COVERAGE) and their sources (see
    the module's text). `noise_m`, `noise_mps`: `local_scatter` of the distances and
    velocities (times the pair's `weakness`); `crb`: the pair's Cramer-Rao bound (m);
    `acceleration`: at every valid pair (m/s^2, kinematics.held); `bias_correction_m`:
    the acceleration bias taken off each distance; `integrated`: half-sweeps of a
    direction summed per pair. NaN where the quantity is not valid."""
    valid = np.asarray(valid, bool)
    noise = np.fmax(np.nan_to_num(noise_m, nan=-1.0), crb)
    noise = np.where(np.isfinite(noise_m), noise, 3 * crb)    # an isolated pair: no scatter measured
    span = np.asarray(integrated, np.float64) * period_s
    a = np.abs(np.nan_to_num(acceleration))
    d_src = {
        "noise": noise,
        "scale": 1e-6 * finite_or_zero(scale_ppm) * np.abs(distance),
        "resampling": resampling_m(distance, cycles_per_sample_per_m, resolution_m),
        "sync delay": np.full(distance.size, finite_or_zero(delay_m)),
        "model": MODEL_SHARE * np.abs(bias_correction_m),
        "integration": a * span**2 / 12,
    }
    known = np.isfinite(noise_mps)
    v_noise = np.where(known, noise_mps, np.median(noise_mps[known]) if known.any() else 0.0)
    typical = float(np.median(np.abs(velocity[valid]))) if valid.any() else 0.0
    v_src = {
        "noise": v_noise,
        "sync delay": np.full(distance.size, finite_or_zero(delay_mps)),
        # a wrong time base scales each Doppler velocity, and moves the delay refined on
        # the target by as much of its mean speed (the refinement balances the distances
        # against the integrated velocity, both on the wrong clock)
        "time base": abs(finite_or_zero(period_ratio) - 1.0) * (np.abs(velocity) + typical),
        # a pair's own two half-sweeps give their mean velocity, the truth at its centre
        # under a steady acceleration: only K > 1 summed along the tracked velocity smear
        "integration": np.where(np.asarray(integrated) > 1, a * span / np.sqrt(12), 0.0),
    }
    for src, ok in ((d_src, valid), (v_src, np.asarray(velocity_valid, bool))):
        for name in src:
            src[name] = np.where(ok, src[name], np.nan)

    def expanded(src):
        return COVERAGE * np.sqrt(sum(u * u for u in src.values()))

    return Uncertainty(expanded(d_src), expanded(v_src), d_src, v_src)


def budget_attrs(u: Uncertainty) -> dict:
    """The budgets as track attributes: per quantity, the sources' names, their rms
    standard uncertainties over the valid pairs (SI units) and shares of the variance."""
    out = {}
    for quantity, unit in (("distance", "m"), ("velocity", "mps")):
        rows = u.budget(quantity)[:-1]
        out[f"uncertainty_{quantity}_sources"] = ", ".join(name for name, _, _ in rows)
        out[f"uncertainty_{quantity}_rms_{unit}"] = np.array([r for _, r, _ in rows])
        out[f"uncertainty_{quantity}_share"] = np.array([s for _, _, s in rows])
    return out


def budget_from_attrs(attrs: dict, quantity: str) -> list[tuple[str, float, float]]:
    """`Uncertainty.budget` of a track file's attributes (`budget_attrs`); empty for a
    track written without it."""
    unit = "m" if quantity == "distance" else "mps"
    names = attrs.get(f"uncertainty_{quantity}_sources")
    if names is None:
        return []
    rms = np.atleast_1d(attrs[f"uncertainty_{quantity}_rms_{unit}"])
    share = np.atleast_1d(attrs[f"uncertainty_{quantity}_share"])
    rows = list(zip(str(names).split(", "), map(float, rms), map(float, share), strict=True))
    return rows + [("combined", float(np.sqrt(np.nansum(rms**2))), 1.0)]


def _course(window: int) -> np.ndarray:
    """The filter giving each pair's smooth course: the centre value of the quadratic
    least-squares fit over 4 `window` + 1 pairs (a shorter course takes in the wander it
    should leave)."""
    long = 2 * (2 * window) + 1
    offsets = np.arange(long, dtype=np.float64) - long // 2
    return np.linalg.pinv(np.vander(offsets, kinematics.POLYORDER + 1, increasing=True))[0]


def _robust_rms(x: np.ndarray, edge: int) -> np.ndarray:
    """The rms of x about each value over SCATTER_PAIRS, robustly (the median of
    squares over its chi-squared median), and `edge` values more at each end, held from
    the first and last."""
    inner = np.sqrt(running_median(x * x, SCATTER_PAIRS) / CHI2_MEDIAN)
    return np.concatenate([np.full(edge, inner[0]), inner, np.full(edge, inner[-1])])


def course_scatter(velocity: np.ndarray, valid: np.ndarray, window: int = kinematics.WINDOW_PAIRS
                   ) -> np.ndarray:
    """Per valid pair, the standard deviation of the velocities' errors, those that
    wander over tens of pairs included: their residuals about their smooth course
    (`_course`) over sqrt(1 - h) (h: the course's weight of the pair itself, what a fit
    takes in of a white error), robustly over SCATTER_PAIRS (`_robust_rms`), held from
    the nearest measured pair within half a course of the run's ends. A static target
    under speckle decorrelating in 3 ms: its velocity errors correlated +0.23..+0.45 at
    1-8 pairs and +0.11..+0.26 at 16, which second differences read 15-20 % low. NaN in
    runs shorter than the course."""
    v = np.asarray(velocity, np.float64)
    course = _course(window)
    half = course.size // 2
    out = np.full(v.size, np.nan)
    for a, b in runs(valid):
        if b - a < course.size:
            continue
        resid = v[a + half:b - half] - np.correlate(v[a:b], course, "valid")
        out[a:b] = _robust_rms(resid / np.sqrt(1.0 - course[half]), half)
    return out


def derivative_scatter(velocity: np.ndarray, valid: np.ndarray, period_s: float,
                       window: int = kinematics.WINDOW_PAIRS) -> np.ndarray:
    """Per valid pair, the standard deviation (m/s^2) of what the acceleration's
    derivative (quadratic over `window` pairs) passes of the velocities' errors,
    correlated ones included: the velocities less their smooth course (`_course`),
    differentiated as the acceleration is, robustly over SCATTER_PAIRS (`_robust_rms`),
    and held from the nearest measured pair within half a course and half a window of
    the run's ends. Second differences see only the white part of the velocities'
    noise; at speed their errors also wander over a few pairs (0.3 mm/s over 8 pairs of
    the jump: 0.5-0.8 m/s^2 where the white part stated 0.07). NaN in runs shorter than
    the course and a window."""
    v = np.asarray(velocity, np.float64)
    course = _course(window)
    half = course.size // 2
    slope = savgol_rows(window, kinematics.POLYORDER)[window // 2] / period_s
    edge = half + window // 2           # pairs at a run's ends with no whole course and window
    out = np.full(v.size, np.nan)
    for a, b in runs(valid):
        if b - a < 2 * edge + 1:
            continue
        resid = v[a + half:b - half] - np.correlate(v[a:b], course, "valid")
        out[a:b] = _robust_rms(np.correlate(resid, slope, "valid"), edge)
    return out


def acceleration_uncertainty(acceleration: np.ndarray, acceleration_valid: np.ndarray, noise_mps: np.ndarray,
                             period_s: float, window: int = kinematics.WINDOW_PAIRS,
                             period_ratio: float = 1.0, scatter_mps2: np.ndarray | None = None) -> np.ndarray:
    """Expanded uncertainty (k = COVERAGE, m/s^2) of each valid acceleration, a
    Savitzky-Golay derivative (quadratic over `window` pairs) of the velocities: their
    noise through the derivative's weights, sqrt(sum w_j^2 sigma_j^2); the smoothing's
    bias, which a quadratic leaves where the acceleration bends: the fitted slope is
    v' + v''' T^2 sum k^4 / (6 sum k^2), v''' = a'' taken over half a window either
    side; and the time base, 2 |period_ratio - 1| |a| (a clock off by r scales the
    time by r and the velocity by about 1 / r: the acceleration by 1 / r^2). NaN where
    the acceleration is not valid."""
    ok = np.asarray(acceleration_valid, bool)
    half = window // 2
    weights = savgol_rows(window, 2)[half] / period_s
    # each velocity's own noise through its weight: sum w_j^2 sigma_j^2 over the window
    var = np.zeros(ok.size)
    if ok.size >= window:
        var[half:-half] = np.correlate(np.nan_to_num(noise_mps) ** 2, weights**2, "valid")
    if scatter_mps2 is not None:
        var = np.fmax(var, np.nan_to_num(scatter_mps2) ** 2)
    k = np.arange(1, half + 1, dtype=np.float64)
    bend = period_s**2 * float(np.sum(k**4) / np.sum(k**2)) / 6
    a = np.where(ok, acceleration, np.nan)
    curve = np.full(a.size, np.nan)
    if a.size > 2 * half:
        curve[half:-half] = (a[2 * half:] - 2 * a[half:-half] + a[:-2 * half]) / (half * period_s) ** 2
    curve = np.abs(curve)
    # where a bend cannot be taken (within half a window of a stretch's end): its
    # stretch's largest
    for lo, hi in runs(ok):
        seen = curve[lo:hi][np.isfinite(curve[lo:hi])]
        curve[lo:hi] = np.where(np.isfinite(curve[lo:hi]), curve[lo:hi], seen.max() if seen.size else 0.0)
    clock = 2 * abs(finite_or_zero(period_ratio) - 1.0) * np.abs(np.nan_to_num(a))
    u = np.sqrt(var + (bend * curve) ** 2 + clock**2)
    return np.where(ok, COVERAGE * u, np.nan)
