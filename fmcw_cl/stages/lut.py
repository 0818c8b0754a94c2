"""Stage 3: the look-up table of instants of uniform optical frequency.

G(I) is fitted from the capture's offline table; within a half-sweep the current is
linear in time, so the instants where the optical frequency is uniformly spaced are
fractions u of the half-sweep. Both directions are ordered by increasing optical
frequency, so that the range tone has the same sign in both: the rising-current
sweep (frequency falling in time) is read backwards, u_rise = 1 - u_fall.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.polynomial import Polynomial

from ..errors import FmcwError
from ..physics import C, range_resolution, unambiguous_range

MAX_DEGREE = 7


def fit_tuning(current_a: np.ndarray, frequency_hz: np.ndarray):
    """Least-squares polynomial fit of the offline G(I) table.

    The degree (2 to 7, at most M - 3) minimises the leave-one-out prediction error,
    computed exactly from the hat matrix; a smoothing spline was rejected because its
    curvature penalty shrinks a DFB's (real) curvature and biases the bandwidth.
    Returns a callable nu(I) in Hz.
    """
    x = np.asarray(current_a, float)
    y = np.asarray(frequency_hz, float)
    ref = float(np.mean(y))
    best, best_cv = None, np.inf
    for deg in range(2, min(MAX_DEGREE, x.size - 3) + 1):
        poly = Polynomial.fit(x, y - ref, deg)
        design = np.vander(poly.mapparms()[0] + poly.mapparms()[1] * x, deg + 1)
        hat = design @ np.linalg.pinv(design)
        resid = (y - ref) - poly(x)
        cv = np.mean((resid / np.clip(1 - np.diag(hat), 1e-9, None)) ** 2)
        if cv < best_cv * (1 - 1e-6):   # a higher degree must really predict better
            best, best_cv = poly, cv

    def g(current):
        return ref + best(current)

    return g


@dataclass(frozen=True)
class Lut:
    """Resampling table for one modulation set-up.

    Attributes
    ----------
    points : N, resampled points per half-sweep.
    u_rise, u_fall : (N,) fractions of the half-sweep (0 = its first turning point) at
        which the optical frequency is nu_hz[j]; ordered by increasing frequency.
    nu_hz : (N,) absolute optical frequencies (Hz), uniformly spaced.
    bandwidth_hz : |G(I_max) - G(I_min)| (Hz).
    refractive_index : n of the medium.
    """

    points: int
    u_rise: np.ndarray
    u_fall: np.ndarray
    nu_hz: np.ndarray
    bandwidth_hz: float
    refractive_index: float = 1.0

    @property
    def range_resolution_m(self) -> float:
        return range_resolution(self.bandwidth_hz, self.refractive_index)

    @property
    def unambiguous_range_m(self) -> float:
        return unambiguous_range(self.points, self.bandwidth_hz, self.refractive_index)

    @property
    def wavelength_m(self) -> float:
        return C / float(np.mean(self.nu_hz))

    def u(self, rising: bool) -> np.ndarray:
        return self.u_rise if rising else self.u_fall


def build_lut(current_a: np.ndarray, frequency_hz: np.ndarray, current_min_a: float,
              current_max_a: float, points: int = 1000, refractive_index: float = 1.0) -> Lut:
    """Instants of uniform optical frequency over a half-sweep of the current.

    Parameters
    ----------
    current_a, frequency_hz : the offline G(I) table (A, Hz).
    current_min_a, current_max_a : the modulation's turning currents (A).
    points : number N of resampling intervals; sample j sits in the middle of interval j.

    Raises
    ------
    FmcwError
        if the fitted G(I) is not monotonic over the modulation range.
    """
    if points < 16:
        raise FmcwError(f"--points {points} is too small (at least 16)")
    g = fit_tuning(np.asarray(current_a, float), np.asarray(frequency_hz, float))
    dense_i = np.linspace(current_min_a, current_max_a, 64 * points + 1)
    dense_nu = g(dense_i)
    slope = np.diff(dense_nu)
    if not (np.all(slope < 0) or np.all(slope > 0)):
        raise FmcwError("the fitted G(I) is not monotonic over the modulation range")
    bandwidth = abs(dense_nu[-1] - dense_nu[0])
    lo = min(dense_nu[0], dense_nu[-1])
    nu = lo + (np.arange(points) + 0.5) * bandwidth / points
    order = np.argsort(dense_nu)
    # invert G on the dense grid, then polish with Newton steps on the spline
    cur = np.interp(nu, dense_nu[order], dense_i[order])
    h = 1e-7
    for _ in range(3):
        d = (g(cur + h) - g(cur - h)) / (2 * h)
        cur = cur - (g(cur) - nu) / d
    u_rise = (cur - current_min_a) / (current_max_a - current_min_a)
    return Lut(points, u_rise, 1.0 - u_rise, nu, float(bandwidth), float(refractive_index))
