"""Stage 3: the look-up table of instants of uniform optical frequency.

G(I) is fitted from the capture's offline table; within a half-sweep the current is
linear in time, so the instants where the optical frequency is uniformly spaced are
fractions u of the half-sweep. Both directions are ordered by increasing optical
frequency, so that the range tone has the same sign in both: the rising-current
sweep (frequency falling in time) is read backwards, u_rise = 1 - u_fall.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from numpy.polynomial import Polynomial
from numpy.polynomial.polynomial import polyvander
from numpy.polynomial.polyutils import mapdomain

from ..errors import FmcwError
from ..physics import C, range_resolution, unambiguous_range
from .resample import window

MAX_DEGREE = 7
BIC_MARGIN = 6.0     # a higher degree must lower the BIC by this much ("strong" evidence)


@dataclass(frozen=True)
class TuningFit:
    """The fitted G(I) (callable: nu(I) in Hz) and what the table's scatter leaves of it.

    Attributes
    ----------
    poly : the polynomial of nu - ref (its own domain mapping).
    ref : the table's mean frequency (Hz).
    degree : the polynomial's degree.
    scatter_hz : rms of the table about the fit (residuals over n - k).
    cov : covariance of the coefficients (scatter^2 (X'X)^-1).
    dof : the residuals' degrees of freedom, n - k.
    leave_one_out : the fits of the table less each point in turn, the degree chosen anew
        (the jackknife of the whole fit).
    """

    poly: Polynomial
    ref: float
    degree: int
    scatter_hz: float
    cov: np.ndarray
    dof: int
    leave_one_out: tuple[TuningFit, ...] = ()

    def __call__(self, current):
        return self.ref + self.poly(current)

    def _basis(self, current) -> np.ndarray:
        off, scl = self.poly.mapparms()
        return polyvander(off + scl * np.atleast_1d(np.asarray(current, float)), self.degree)

    def span_std_hz(self, i0: float, i1: float) -> float:
        """Standard deviation (Hz) of G(i1) - G(i0): the bandwidth's, from the scatter."""
        d = (self._basis(i1) - self._basis(i0))[0]
        return float(np.sqrt(max(d @ self.cov @ d, 0.0)))

    def scale_std(self, current: np.ndarray, weights: np.ndarray, bandwidth_hz: float) -> float:
        """Relative standard deviation of the distance scale that the fit's errors leave,
        shape included.

        The resampled beat's phase follows the true G at the LUT's `current` instants, so
        the fit's error dG_j there adds a phase slope; the peak (a weighted least-squares
        slope of the phase over the points, `weights` the window's power) moves by
        -slope(dG) N / B of itself, a linear functional a of the coefficients. Two
        estimates of its spread, the larger stated:

        - the covariance, a C a', times dof / (dof - 2): the scatter is itself estimated
          from the table, so the error over the stated sigma is Student's t, whose
          variance that is (GUM Supplement 1, 6.4.9);
        - the leave-one-out jackknife of the same functional, the degree chosen anew each
          time: the covariance assumes the degree was given, and a degree chosen because
          the scatter happened to look like a higher term errs far beyond it.

        NaN (unknown) under 3 degrees of freedom: Student's t has no variance there.
        """
        if self.dof <= 2:
            return float("nan")
        n = current.size
        j = np.arange(n) - np.sum(weights * np.arange(n)) / np.sum(weights)
        slope = -(weights * j) / np.sum(weights * j * j) * n / bandwidth_hz
        a = slope @ self._basis(current)
        var = max(a @ self.cov @ a, 0.0) * self.dof / (self.dof - 2)
        here = self(current)
        moved = np.array([slope @ (g(current) - here) for g in self.leave_one_out])
        if moved.size:
            var = max(var, (moved.size - 1) / moved.size * np.sum((moved - moved.mean()) ** 2))
        return float(np.sqrt(var))


def _frozen(*arrays: np.ndarray) -> tuple[bytes, ...]:
    """Hashable keys of float arrays (the cache of fits and LUTs below)."""
    return tuple(np.ascontiguousarray(a, float).tobytes() for a in arrays)


def _read_only(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False         # shared by every capture with the same table
    return a


def fit_tuning(current_a: np.ndarray, frequency_hz: np.ndarray) -> TuningFit:
    """Least-squares polynomial fit of the offline G(I) table (one fit per table: the
    N- and 2N-point LUTs and a batch of captures with one table share it).

    The degree (2 to 7, at most M - 3) is the lowest whose Bayesian information
    criterion, M ln(RSS / M) + (degree + 1) ln M, lies within BIC_MARGIN of the least:
    a higher degree must earn its terms. An overfitted polynomial errs most at the
    curve's ends and in its shape, beyond what its covariance states: on 300 tables of
    25 points with 20 MHz rms scatter the plain minimum chose degrees 4-7 for 26 of them,
    whose distance scale erred 2-3x their stated uncertainty (rms 121 ppm); within 6 it
    chose 2 for 295 (rms 84 ppm), and a laser with a cubic term still got degree 3 in 98
    of 100, where a fixed quadratic errs by 1000 ppm. The few degrees still chosen too
    high are what the leave-one-out fits (TuningFit.scale_std) are for. A smoothing
    spline was rejected because its curvature penalty shrinks a DFB's (real) curvature
    and biases the bandwidth.
    """
    return _fit_tuning(*_frozen(current_a, frequency_hz))


@functools.lru_cache(maxsize=16)
def _fit_tuning(current: bytes, frequency: bytes) -> TuningFit:
    x = np.frombuffer(current)
    y = np.frombuffer(frequency)
    keep = ~np.eye(x.size, dtype=bool)
    return _fit(x, y, tuple(_fit(x[k], y[k]) for k in keep))


def _fit(x: np.ndarray, y: np.ndarray, leave_one_out: tuple[TuningFit, ...] = ()) -> TuningFit:
    """The polynomial of the degree the BIC margin chooses (fit_tuning), with its covariance."""
    ref = float(np.mean(y))
    top = max(2, min(MAX_DEGREE, x.size - 3))
    # Polynomial.fit's own steps (its domain, column scaling and rcond), its Vandermonde
    # matrix made once for every degree: the same coefficients, a new table 58 ms not 80
    domain = np.array([x.min(), x.max()])
    van = polyvander(mapdomain(x, domain, Polynomial.window), top)
    fits = []
    for deg in range(2, top + 1):
        lhs = van[:, :deg + 1]
        scl = np.sqrt(np.square(lhs).sum(0))
        scl[scl == 0] = 1
        coef = np.linalg.lstsq(lhs / scl, y - ref, x.size * np.finfo(float).eps)[0] / scl
        poly = Polynomial(coef, domain=domain)
        rss = float(np.sum(((y - ref) - poly(x)) ** 2))
        fits.append((x.size * np.log(max(rss, 1e-300) / x.size) + (deg + 1) * np.log(x.size), poly))
    least = min(bic for bic, _ in fits)
    best = next(poly for bic, poly in fits if bic <= least + BIC_MARGIN)
    deg = best.degree()
    dof = x.size - deg - 1
    scatter = float(np.sqrt(np.sum(((y - ref) - best(x)) ** 2) / max(dof, 1)))
    off, scl = best.mapparms()
    design = polyvander(off + scl * x, deg)
    cov = scatter**2 * np.linalg.pinv(design.T @ design)
    return TuningFit(best, ref, deg, scatter, _read_only(cov), dof, leave_one_out)


@dataclass(frozen=True, eq=False)   # identity: a LUT is cached (build_lut), and what is made from it
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
    bandwidth_std_hz : the bandwidth's standard deviation from the table's scatter (Hz;
        NaN when unknown).
    scale_std : the distance scale's relative standard deviation from the fit's errors,
        their shape between the table's points included and the degree's choice
        (TuningFit.scale_std; NaN when unknown).
    fit_degree, table_scatter_hz : the G(I) fit's degree and the table's rms scatter.
    """

    points: int
    u_rise: np.ndarray
    u_fall: np.ndarray
    nu_hz: np.ndarray
    bandwidth_hz: float
    refractive_index: float = 1.0
    bandwidth_std_hz: float = float("nan")
    fit_degree: int = 0
    table_scatter_hz: float = float("nan")
    scale_std: float = float("nan")

    @property
    def scale_ppm(self) -> float:
        """Relative uncertainty of the distance scale (ppm, 1 sigma) from the G(I) table."""
        return 1e6 * self.scale_std

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
    return _build_lut(*_frozen(current_a, frequency_hz), float(current_min_a), float(current_max_a),
                      int(points), float(refractive_index))


@functools.lru_cache(maxsize=16)
def _build_lut(current: bytes, frequency: bytes, current_min_a: float, current_max_a: float, points: int,
               refractive_index: float) -> Lut:
    g = _fit_tuning(current, frequency)
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
    power = window(points) ** 2              # the peak weighs each point's phase by its power
    return Lut(points, _read_only(u_rise), _read_only(1.0 - u_rise), _read_only(nu), float(bandwidth),
               refractive_index, g.span_std_hz(current_min_a, current_max_a), g.degree, g.scatter_hz,
               g.scale_std(cur, power, bandwidth))
