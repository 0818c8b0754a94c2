"""Stage 6: Doppler-paired distance and velocity from rising + falling half-sweeps.

Resampled at uniform optical frequency nu_j, a half-sweep of a target at distance
R(t) = R_c + v (t - t_c) has the beat phase 2 pi nu_j tau(t_j), tau = 2 n R / c:
a tone at R_c plus a Doppler term 2 pi v beta_j, beta_j = (2n/c) nu_j (t_j - t_c),
which is itself chirped because t_j is not linear in j. Multiplying the half-sweep
by exp(-2 pi i v beta_j) ("de-chirp") leaves a clean tone at R_c on the positive
side of the spectrum, even where the raw real beat folds through 0 Hz.

The tracker iterates: de-chirp every half-sweep with the current velocity of its
pair, measure both apparent distances, correct the velocity from their difference,
and regularise the velocities by continuity (outliers and unmeasured pairs are
filled from trusted neighbours). The first pass uses v = 0, which is the paper's
method (plain FFT of each half-sweep).

The Doppler model and the solve of a pair are in stages.doppler, the verification of
the pairs in stages.verification, the groups of pairs in stages.groups, and the
spectrum steps a backend swaps in in fmcw_cl.spectrum_ops.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .. import numeric
from ..numeric import median
from ..spectrum_ops import NUMPY, SpectrumOps
from . import cfar, integrate
from .doppler import DopplerModel, solve_pair
from .groups import NEIGHBOURS, _each, group_bounds, group_ends, regularise, running_median
from .spectrum import Search
from .verification import CONSISTENT_MPS, _residuals, agreeing

SNR_MIN_DB = 10.0     # a half-sweep's peak must stand this far above the floor
PLAIN_SHARE = 0.2     # verification.CONSISTENT_MPS plus this share of |median| after the plain pass
                      # (its peaks smear)
CONVERGED_MPS = 0.05  # final velocity correction must be below this (peak not smeared)
STOP_MPS = 1e-3       # a pair is re-measured when its de-chirp velocity moves this much (at
                      # 1e-2 hunted take-offs beside walls got wrong valid pairs)


@dataclass(frozen=True)
class PairResult:
    """Per pair: Doppler-free distance (m), velocity (m/s), and the half-sweeps' view.

    ``dist_*``/``snr_*`` are each half-sweep's own apparent distance and SNR from its
    plain spectrum (Doppler shift included, folds folded); ``dechirped_*`` are the
    same after the final de-chirp (equal to the plain ones without de-chirp).
    """

    distance: np.ndarray
    velocity: np.ndarray
    valid: np.ndarray
    dist_rise: np.ndarray
    dist_fall: np.ndarray
    snr_rise: np.ndarray
    snr_fall: np.ndarray
    dechirped_rise: np.ndarray
    dechirped_fall: np.ndarray
    dechirped_snr_rise: np.ndarray
    dechirped_snr_fall: np.ndarray
    heard: np.ndarray           # both final peaks at least SNR_MIN_DB over their floors
    continuous: np.ndarray      # the distance agrees with its neighbours' (see `continuity`)
    integrated: np.ndarray | None = None          # half-sweeps of a direction summed per pair
    echoes_rise: cfar.Detections | None = None   # every echo of the plain spectra
    echoes_fall: cfar.Detections | None = None
    phasor_rise: np.ndarray | None = None    # the beat's phasor at each final peak (stages.phase)
    phasor_fall: np.ndarray | None = None

    def take(self, rows: np.ndarray) -> PairResult:
        """The pairs `rows` (a boolean mask or indices)."""
        return PairResult(*(None if x is None else x.take(rows) if isinstance(x, cfar.Detections) else x[rows]
                            for x in (getattr(self, k) for k in self.__dataclass_fields__)))

    @classmethod
    def concat(cls, parts: list[PairResult]) -> PairResult:
        """The pairs of `parts`, in order."""
        def join(xs):
            if xs[0] is None:
                return None
            return cfar.Detections.concat(xs) if isinstance(xs[0], cfar.Detections) else np.concatenate(xs)
        return cls(*(join([getattr(p, k) for p in parts]) for k in cls.__dataclass_fields__))


class _Windows:
    """Both directions measured on K-window integrated spectra (stages.integrate); the
    spectra are kept between the tracker's passes, re-made only for the rows whose
    de-chirp velocity moved."""

    def __init__(self, ops, rows: tuple, model: DopplerModel, search: Search, k: int, times: Times,
                 vd: np.ndarray | None = None):
        self.ops, self.rows, self.model, self.search, self.k = ops, rows, model, search, k
        self.t, self.groups = times.mid, times.groups
        # each group's windows end at its ends, its displacement starts at its start
        self.bounds = None if times.groups is None else times.bounds
        self.betas = (model.beta_rise, model.beta_fall)
        # plain, or de-chirped at the first velocities `vd` where given
        self.stores = [ops.spectra(x, None if vd is None else beta, vd, model.nfft)
                       for x, beta in zip(rows, self.betas, strict=True)]

    def measure(self, vd: np.ndarray, moved: np.ndarray | None = None) -> tuple:
        """(d_r, s_r, d_f, s_f, count) of every pair, after re-making the spectra of the
        rows `moved` (all when None) de-chirped at vd; aligned along vd."""
        m = self.model
        if moved is not None:
            every = None if moved.size == vd.size else moved
            self.stores = [self.ops.spectra(x, beta, vd[moved], m.nfft, every, store)
                           for x, beta, store in zip(self.rows, self.betas, self.stores, strict=True)]
        disp = displacement_bins(self.t, self.groups, vd, m.metres_per_bin)
        out = []
        for j, store in enumerate(self.stores):
            b, snr, count = self.ops.integrated_peaks(store, disp, self.k, self.search, self.bounds, j)
            out += [b * m.metres_per_bin, snr]
        return (*out, count)


def displacement_bins(t: np.ndarray, groups: np.ndarray | None, vd: np.ndarray, metres_per_bin: float
                      ) -> np.ndarray:
    """The target's displacement (bins) at the pairs' centres `t` (s) from its group's
    first pair (`groups`: Times.groups), at the de-chirp velocities `vd` (m/s): where
    the K-window integration reads each spectrum (twin: kernels/track.cl `displace`)."""
    if groups is None:
        disp = numeric.travelled(t, vd)
    else:
        disp = _each(groups, lambda g: numeric.travelled(t[g], vd[g]), vd.size)
    return disp / metres_per_bin


def track_pairs(xr: np.ndarray, xf: np.ndarray, times: Times, model: DopplerModel, search: Search,
                iterations: int = 6, dechirp: bool = True, ops: SpectrumOps | None = None,
                integrate_k: int | None = 1) -> PairResult:
    """Doppler-free distance and velocity of consecutive rising/falling half-sweeps.

    Parameters
    ----------
    xr, xf : (P, N) resampled, windowed rising and falling half-sweeps of each pair
        (or a backend's device-resident equivalent).
    times : the centre times of those half-sweeps (s).
    model : the LUT's Doppler model.
    search : the band and rule of the peak search; with `search.echoes` the plain
        pass also lists every echo.
    iterations : de-chirp passes after the plain first pass, at most. A pass re-measures
        only the pairs whose de-chirp velocity moved by STOP_MPS or more since they were
        last measured (the others would repeat their measurement), and the passes end
        when none did: a still or slow target needs one.
    dechirp : False gives the paper's method (one plain pass, no fold handling).
    ops : the spectrum steps (numpy's by default; a backend's).
    integrate_k : half-sweeps of a direction integrated per measurement (1: none; see
        stages.integrate); None chooses it from the pairs' SNR: 1 when at least
        integrate.AUTO_SHARE of the single pairs are heard. Pairs in groups
        (`times.groups`) take a given K, whose windows end at their group's ends.
    """
    ops = ops or NUMPY
    if times.groups is not None and integrate_k is None:
        raise ValueError("pairs tracked in groups apart take a given integration, not one chosen "
                         "for them all")
    iterations = iterations if dechirp else 0
    # the plain pass (with every echo) does not depend on the integration: made once
    first, single = ops.track((xr, xf), times, model, search, iterations, integrate_k in (1, None))

    def tracked(k: int, state: Passes | None = None) -> PairResult:
        if state is None:
            state = ops.integrated((xr, xf), times, model, replace(search, echoes=False), iterations, k)
        return result(first, state, times, model, dechirp, search.reach)

    def chosen() -> PairResult:
        if integrate_k is not None and integrate_k > 1:
            return tracked(integrate_k)
        one = tracked(1, single)
        if integrate_k is not None or one.heard.size == 0 or one.heard.mean() >= integrate.AUTO_SHARE:
            return one
        probe = tracked(integrate.PROBE)
        k = integrate.choose(measured_snr(probe), SNR_MIN_DB)
        if k == 1:                  # the probe heard more than the single pairs: `one` it is
            return one
        return probe if k == integrate.PROBE else tracked(k)

    res = chosen()
    # the paper's method (no de-chirp) is reported as the paper did: without the phase
    return res if res.phasor_rise is not None or not dechirp else with_phases(res, (xr, xf), model, ops)


def with_phases(res: PairResult, rows: tuple, model: DopplerModel, ops: SpectrumOps) -> PairResult:
    """`res` with the beat's phase at each half-sweep's final peak (stages.phase), each
    de-chirped at its pair's velocity (a device whose passes ran there made them with
    its state: Passes.phasors)."""
    v = np.nan_to_num(res.velocity)
    bins = [np.nan_to_num(d / model.metres_per_bin) for d in (res.dechirped_rise, res.dechirped_fall)]
    z_r, z_f = ops.phasors_each(rows, (model.beta_rise, model.beta_fall), v, bins, model.nfft)
    return replace(res, phasor_rise=z_r, phasor_fall=z_f)


def measured_snr(res: PairResult) -> float:
    """Per-sweep SNR (linear) of the target from an integrated tracking: the mean
    spectrum's peak over its floor is 1 + SNR; the median over the heard pairs' sweeps
    (0 when fewer than half are heard)."""
    if not res.heard.size or res.heard.mean() < 0.5:
        return 0.0
    db = np.concatenate([res.dechirped_snr_rise[res.heard], res.dechirped_snr_fall[res.heard]])
    return median(10 ** (db.astype(np.float64) / 10) - 1)


@dataclass(frozen=True)
class Times:
    """A chunk's pairs in time (s): each half-sweep's centre, the pair's centre and half
    the time between its sweeps' centres; `groups`: the first pair of each group of pairs
    tracked apart from the others (`group_slices`; None: one group); `device`: copies of
    (mid, half_gap, bounds, groups or None) on a device, where a processor took them up
    with the pairs' resampling positions."""

    rise: np.ndarray
    fall: np.ndarray
    groups: np.ndarray | None = None
    device: tuple | None = None

    @property
    def mid(self) -> np.ndarray:
        return 0.5 * (self.fall + self.rise)

    @property
    def half_gap(self) -> np.ndarray:
        return 0.5 * (self.fall - self.rise)

    @property
    def bounds(self) -> np.ndarray:
        """group_bounds of these pairs (kernels/track.cl)."""
        return group_bounds(self.groups, self.rise.size)


@dataclass
class Passes:
    """The tracker's state after its de-chirp passes: each pair's last apparent
    distances (m) and SNRs (dB), the velocity it was de-chirped with (m/s), and how many
    half-sweeps of a direction each measurement integrated (`k` at most)."""

    d_r: np.ndarray
    s_r: np.ndarray
    d_f: np.ndarray
    s_f: np.ndarray
    vd: np.ndarray
    count: np.ndarray
    k: int = 1
    verdict: tuple | None = None      # (valid, residuals) where a device made them (`verdict`)
    phasors: tuple | None = None      # (rising, falling) stages.phase.phasors where a device made them

    @property
    def snr_min(self) -> np.ndarray | float:
        return snr_floor(self.count, self.k)

    @property
    def heard(self) -> np.ndarray:
        """Both of a pair's peaks at least `snr_min`."""
        return (self.s_r >= self.snr_min) & (self.s_f >= self.snr_min)


def snr_floor(count: np.ndarray, k: int) -> np.ndarray | float:
    """The SNR (dB) a pair's peaks must reach, integrated over `count` half-sweeps of the
    K = k windows (stages.integrate): SNR_MIN_DB without integration."""
    return SNR_MIN_DB if k == 1 else integrate.threshold_db(count, SNR_MIN_DB)


def passes(rows: tuple, times: Times, model: DopplerModel, search: Search, iterations: int,
           ops: SpectrumOps, first: tuple, k: int) -> Passes:
    """The tracker's de-chirp passes (integrating k half-sweeps a measurement) from the
    plain pass `first` (k = 1; with k > 1, from the integrated plain spectra, `first`
    unused): de-chirp every pair at its regularised velocity (`regularise`), measure,
    solve, until no pair's velocity moves by STOP_MPS or `iterations` are done."""
    xr, xf = rows
    half_gap, t_mid = times.half_gap, times.mid
    seeded = search.velocity is not None
    # the velocity each pair was last de-chirped with: its course's where it has one (Search.velocity)
    vd = search.velocity.copy() if seeded else np.zeros(t_mid.size)
    windows = _Windows(ops, rows, model, search, k, times, vd if seeded else None) if k > 1 else None
    if windows is not None:
        d_r, s_r, d_f, s_f, count = windows.measure(vd)
    elif seeded:
        (d_r, s_r), (d_f, s_f) = ops.measure_each((xr, xf), (model.beta_rise, model.beta_fall), vd, model,
                                                  search)
        count = np.ones(t_mid.size, np.int32)
    else:
        (d_r, s_r, *_), (d_f, s_f, *_) = first
        d_r, d_f, s_r, s_f = (a.copy() for a in (d_r, d_f, s_r, s_f))   # updated in place
        count = np.ones(t_mid.size, np.int32)
    snr_min = snr_floor(count, k)
    for it in range(iterations):
        _, vel, _ = solve_pair(d_r, d_f, vd, half_gap, model)
        heard = (s_r >= snr_min) & (s_f >= snr_min)
        # the plain first pass smears fast targets: allow PLAIN_SHARE there, not later
        med = running_median(vel, times.groups, search.reach)
        tol = CONSISTENT_MPS + (PLAIN_SHARE * np.abs(med) if it == 0 else 0.0)
        v_next = regularise(vel, heard & (np.abs(vel - med) < tol), t_mid, med, times.groups)
        # the plain pass is the de-chirp at 0 m/s: a still pair is not measured again
        moved = np.flatnonzero(np.abs(v_next - vd) >= STOP_MPS)
        if moved.size == 0:
            break
        vd[moved] = v_next[moved]
        if windows is not None:
            d_r, s_r, d_f, s_f, count = windows.measure(vd, moved)
        else:
            every = None if moved.size == vd.size else moved
            (d_r[moved], s_r[moved]), (d_f[moved], s_f[moved]) = ops.measure_each(
                (xr, xf), (model.beta_rise, model.beta_fall), vd[moved], model, search, every)
    return Passes(d_r, s_r, d_f, s_f, vd, count, k)


def verdict(state: Passes, times: Times, model: DopplerModel, reach: int = NEIGHBOURS
            ) -> tuple[np.ndarray, np.ndarray]:
    """Which pairs of the tracker's `state` are valid (both peaks heard, the last
    velocity correction below CONVERGED_MPS, the velocity within CONSISTENT_MPS of its
    running median over `reach`) and their continuity residuals (m) against the valid pairs
    (`_residuals`); each group on its own (twin: kernels/track.cl)."""
    dist, vel, dv = solve_pair(state.d_r, state.d_f, state.vd, times.half_gap, model)
    med = running_median(vel, times.groups, reach)
    valid = state.heard & (np.abs(dv) < CONVERGED_MPS) & (np.abs(vel - med) < CONSISTENT_MPS)
    resid, _ = _residuals(times.mid, dist, vel, valid, ends=group_ends(times.groups, valid.size))
    return valid, resid


def result(first: tuple, state: Passes, times: Times, model: DopplerModel, dechirp: bool,
           reach: int = NEIGHBOURS) -> PairResult:
    """The pairs' distances, velocities and validity from the plain pass `first` and
    the state after the de-chirp passes (`verdict` over `reach`)."""
    (d_r, s_r, *e_r), (d_f, s_f, *e_f) = first
    dist, vel, _ = solve_pair(state.d_r, state.d_f, state.vd, times.half_gap, model)
    heard = state.heard
    valid, continuous = heard, np.ones(heard.size, bool)
    if dechirp:
        valid, resid = state.verdict or verdict(state, times, model, reach)
        continuous = agreeing(resid, valid, times.groups)
    phases = [None, None] if state.phasors is None else list(state.phasors)
    return PairResult(dist, vel, valid, d_r.copy(), d_f.copy(), s_r.copy(), s_f.copy(), state.d_r, state.d_f,
                      state.s_r, state.s_f, heard, continuous, state.count,
                      *(e_r or [None]), *(e_f or [None]), *phases)
