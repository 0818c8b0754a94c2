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
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .. import numeric
from ..numeric import median, padded, row_nanmedian
from ..physics import C
from . import cfar, integrate, phase
from .lut import Lut
from .spectrum import Search, find_peaks, power_spectra

SNR_MIN_DB = 10.0     # a half-sweep's peak must stand this far above the floor
CONSISTENT_MPS = 0.1  # a velocity this far from its neighbours' median is an outlier
PLAIN_SHARE = 0.2     # ... plus this share of |median| after the plain pass (its peaks smear)
CONVERGED_MPS = 0.05  # final velocity correction must be below this (peak not smeared)
NEIGHBOURS = Search.reach   # half-width (pairs) of the continuity median (a leg's; fmcw_cl.motion)
STOP_MPS = 1e-3       # a pair is re-measured when its de-chirp velocity moves this much (at
                      # 1e-2 hunted take-offs beside walls got wrong valid pairs)
JUMP_M = 0.25e-3      # a distance this far from its neighbours' prediction is discontinuous
JUMP_SIGMAS = 6.0     # ... or this many robust standard deviations of the chunk's residuals
JUMP_MAX_M = 1e-3     # ... but never more than this
RESIDUAL_BLOCK = 4096      # pairs whose neighbours' predictions are taken at once
SUPPORT = 2           # trusted neighbours needed to vouch for a pair
ANCHOR_PAIRS = 2 * NEIGHBOURS + 1   # a run of valid pairs this long stands on its own
ACCEL_MAX = 500.0     # m/s^2: how far a shorter run may stray from an anchor across its gap
ANCHOR_GAP_S = 5e-3   # ... a gap at most this long (over 5 ms the bound exceeds 2.6 mm and grows as dt^2)
KINEMATIC_S = 2e-3    # pairs this close in time must agree as one body's motion (`_kinematic`)
KINEMATIC_PAIRS = 48  # half-width (pairs) of the window searched for them (2.4 ms at 50 us)
DRIFT_S = 5e-3        # a run of valid pairs this long ...
DRIFT_MPS = 0.3       # ... whose distance leaves its integrated velocity this fast is dropped (a sync
                      # delay's error leaves at most ~0.1 m/s; a wrong echo held 25 ms: 0.94 m/s)
DRIFT_PAIRS = ANCHOR_PAIRS  # a shorter run down to this many pairs (one that stands on its own) is
                      # dropped where its drift is also ...
DRIFT_SIGMAS = 5.0    # ... this many standard errors (a jackknife's over DRIFT_BLOCKS blocks: the
DRIFT_BLOCKS = 6      # distances are correlated over pairs)
REST_MPS = 0.3        # a run this slow (its median) between runs in motion ...
BRIDGE_S = 0.015      # ... that join across it, over at most this long, and joins neither, is dropped
END_PAIRS = 8         # a run's end: the medians of this many of its pairs


@dataclass(frozen=True)
class DopplerModel:
    """What the LUT and the window imply for the Doppler term.

    Attributes
    ----------
    beta_rise, beta_fall : (N,) Doppler phase in cycles per (m/s) at each resampled point.
    k_rise, k_fall : apparent-distance shift per m/s of uncorrected velocity (s);
        the window-weighted slope of beta, i.e. the effective sweep time.
    metres_per_bin : distance of one bin of the padded FFT (m).
    nfft : padded FFT length.
    q_rise, q_fall : apparent-distance shift per m/s^2 of acceleration about the
        half-sweep's own centre (s^2): the window-weighted slope of the displacement
        a (t - t_c)^2 / 2 as a phase (`acceleration_bias`).
    """

    beta_rise: np.ndarray
    beta_fall: np.ndarray
    k_rise: float
    k_fall: float
    metres_per_bin: float
    nfft: int
    q_rise: float = 0.0
    q_fall: float = 0.0


def doppler_model(lut: Lut, half_sweep_s: float, nfft: int, win: np.ndarray) -> DopplerModel:
    """Build the de-chirp bases and effective times for a LUT and window."""
    n, nidx = lut.points, lut.refractive_index
    dnu = lut.bandwidth_hz / n
    j = np.arange(n) - (n - 1) / 2
    metres_per_cycle = C / (2 * nidx * dnu)   # distance of a tone of 1 cycle per point

    def basis(u):
        return (2 * nidx / C) * lut.nu_hz * (u - 0.5) * half_sweep_s

    def k_eff(beta):
        # a small phase error eps_j moves the peak by the window-weighted LS slope
        return metres_per_cycle * np.sum(win * j * beta) / np.sum(win * j * j)

    def q_eff(u):
        # the phase of the displacement a (t - t_c)^2 / 2, per m/s^2, in cycles
        return k_eff((nidx / C) * lut.nu_hz * np.square((u - 0.5) * half_sweep_s))

    br, bf = basis(lut.u_rise), basis(lut.u_fall)
    for beta in (br, bf):
        beta.flags.writeable = False       # a device keeps its first upload (Buffers.constant)
    return DopplerModel(br, bf, float(k_eff(br)), float(k_eff(bf)),
                        metres_per_cycle / nfft, nfft, float(q_eff(lut.u_rise)), float(q_eff(lut.u_fall)))


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


def power(x: np.ndarray, beta: np.ndarray | None, v: np.ndarray | None, nfft: int,
          rows: np.ndarray | None = None) -> np.ndarray:
    """Power spectra (sweeps, nfft/2) of half-sweeps de-chirped at velocities v (plain
    when v is None), of the rows `rows` of x only when given."""
    if rows is not None:
        x = x[rows]
    if v is not None:
        x = x * np.exp(-2j * np.pi * np.outer(v, beta))
    return power_spectra(x, nfft)


def measure(x: np.ndarray, beta: np.ndarray, v: np.ndarray | None, model: DopplerModel,
            search: Search, rows: np.ndarray | None = None) -> tuple:
    """Apparent distance (m) and SNR (dB) of half-sweeps de-chirped at velocities v
    (plain spectra when v is None), of the rows `rows` of x only when given; with
    `search.echoes`, every echo above the band's start (cfar.Detections; beyond its
    end too: a wall behind --max-range stays visible) as a third item."""
    spec = power(x, beta, v, model.nfft, rows)
    pk = find_peaks(spec, search.lo, search.hi)
    got = (pk.bin * model.metres_per_bin, pk.snr_db)
    return (*got, cfar.detect(spec, search.lo)) if search.echoes else got


class SpectrumOps:
    """The spectrum steps of the tracker and the verification's tests in numpy; a
    backend swaps in its own (opencl.processor.OpenCLProcessor), with the same arguments
    and results."""

    def measure(self, x, beta, v, model: DopplerModel, search: Search, rows=None) -> tuple:
        return measure(x, beta, v, model, search, rows)

    def measure_each(self, xs, betas, v, model: DopplerModel, search: Search, rows=None) -> list[tuple]:
        """`measure` of each x of `xs` (a pair's rising and falling half-sweeps) with its
        beta of `betas`, the same velocities and rows (a backend: in one round trip)."""
        return [self.measure(x, beta, v, model, search, rows) for x, beta in zip(xs, betas, strict=True)]

    def track(self, rows: tuple, times: Times, model: DopplerModel, search: Search, iterations: int,
              single: bool) -> tuple[tuple, Passes | None]:
        """The tracker's plain pass of both directions of `rows` (every echo with
        `search.echoes`) and, when `single`, its de-chirp passes without integration
        (`passes`; a backend: on the device, its state read once)."""
        first = tuple(self.plain_pass(rows, model, search, times))
        if not single:
            return first, None
        return first, passes(rows, times, model, replace(search, echoes=False), iterations, self, first, 1)

    def integrated(self, rows: tuple, times: Times, model: DopplerModel, search: Search, iterations: int,
                   k: int) -> Passes:
        """The tracker's de-chirp passes on K-window integrated spectra of both
        directions of `rows` (`passes` with k > 1; a backend: on the device, its state
        read once)."""
        return passes(rows, times, model, search, iterations, self, None, k)

    def plain_pass(self, rows: tuple, model: DopplerModel, search: Search,
                   times: Times | None = None) -> list[tuple]:
        """`measure_each` of both directions of `rows` at 0 m/s: the tracker's first pass
        (`times`: the pairs'; each of its groups measured as if alone: a backend that takes
        two rows a transform pairs them within a group)."""
        return self.measure_each(rows, (model.beta_rise, model.beta_fall), None, model, search)

    def power(self, x, beta, v, nfft: int, rows=None) -> np.ndarray:
        return power(x, beta, v, nfft, rows)

    def residuals(self, t, dist, vel, trusted, rows=None) -> tuple[np.ndarray, np.ndarray]:
        """The continuity residuals (m) of the pairs `rows` (all when None) against the
        `trusted` ones, and how many vouch for each (`_residuals`, one group)."""
        return _residuals(t, dist, vel, trusted, rows)

    def disagreed(self, t, dist, vel, ok) -> np.ndarray:
        return disagreed(t, dist, vel, ok)

    def power_each(self, jobs: list, nfft: int) -> list[np.ndarray]:
        """`power` of each (x, beta, v) of `jobs`, rows of any count each (a backend: one
        download)."""
        return [self.power(x, beta, v, nfft) for x, beta, v in jobs]

    def spectra(self, x, beta, v, nfft: int, rows=None, store=None):
        """`store` (a (sweeps, nfft/2) array, new when None) with the rows `rows` (all
        when None) replaced by their power spectra, de-chirped at v (plain when None)."""
        spec = power(x, beta, v, nfft, rows)
        if store is None:
            return spec
        store[slice(None) if rows is None else rows] = spec
        return store

    def integrated_peaks(self, store, disp: np.ndarray, k: int, search: Search,
                         bounds: np.ndarray | None = None) -> tuple:
        """(bin, SNR dB, count) of the K-window integrated spectra (stages.integrate;
        `bounds`: each row's group's first and last row, None: one group)."""
        return integrate.peaks(store, disp, k, search, bounds)

    def survey(self, x, beta, v, nfft: int, rows, lo: int, tracked_bin, plain_bin, others) -> tuple:
        """echoes.hidden of the rows `rows` of x: (ratio, centroid, found) from their plain
        spectra and those de-chirped at v, and the plain spectra's echoes.block_sums."""
        from ..echoes import block_sums, hidden

        plain = power(x, None, None, nfft, rows)
        return (*hidden(plain, power(x, beta, v, nfft, rows), lo, tracked_bin, plain_bin, others),
                block_sums(plain))

    def phasors_each(self, xs, betas, v, bins, nfft: int) -> list[np.ndarray]:
        """stages.phase.phasors of each x of `xs` (a pair's two directions) with its beta
        and peak bins of `betas` and `bins`, the same velocities (a backend: one trip)."""
        return [phase.phasors(x, beta, v, b, nfft) for x, beta, b in zip(xs, betas, bins, strict=True)]

    def survey_each(self, xs, betas, v, nfft: int, rows, lo: int, tracked_bins, plain_bins, others) -> list:
        """`survey` of each x of `xs` (a pair's two directions) with its beta, tracked and
        plain bins and other echoes, the same rows and velocities (a backend: one trip)."""
        return [self.survey(*a[:2], v, nfft, rows, lo, *a[2:])
                for a in zip(xs, betas, tracked_bins, plain_bins, others, strict=True)]


NUMPY = SpectrumOps()


def solve_pair(d_r, d_f, v0, half_gap, model: DopplerModel):
    """Distance at the pair's centre time and velocity from two apparent distances.

    d_r = R_m - v h + dv k_r and d_f = R_m + v h + dv k_f with v = v0 + dv, where
    h is half the time between the sweeps' centres (the target moves meanwhile).
    """
    dv = (d_f - d_r - 2 * v0 * half_gap) / (2 * half_gap + model.k_fall - model.k_rise)
    dist = 0.5 * (d_r + d_f) - 0.5 * dv * (model.k_rise + model.k_fall)
    return dist, v0 + dv, dv


def acceleration_bias(acceleration, half_gap, model: DopplerModel):
    """The bias (m) of `solve_pair`'s distance for a target accelerating at
    `acceleration` (m/s^2). Both half-sweeps are de-chirped at the pair's one velocity
    (its value at the pair's centre), but the target moves by a tau^2 / 2 more, tau the
    time from that centre: tau = t - t_c -+ h in the rising and falling half-sweep (h =
    `half_gap`, s). As a phase its window-weighted slope moves each apparent distance,
    by q -+ h k + h^2 / 2 per m/s^2 (q: the slope of a (t - t_c)^2 / 2, `q_rise`,
    `q_fall`; -+ h k: the velocity a h off the de-chirp's; h^2 / 2: where the target is at
    the half-sweep's centre), and `solve_pair` carries them into the distance. At the
    paper's sweep 0.31 um per m/s^2 (0.11 mm at a jump's 360 m/s^2; 0.29 seen on
    constant accelerations of 30-300 m/s^2): the distance drifts against the integrated
    velocity by the acceleration's change, which the sync delay's refinement took for a
    delay error (7 samples on a 15 ms take-off). The velocity's bias, (c_f - c_r) over
    the solve's denominator, vanishes for a table's symmetric sweeps."""
    h = half_gap
    c_r = model.q_rise - h * model.k_rise + 0.5 * h * h
    c_f = model.q_fall + h * model.k_fall + 0.5 * h * h
    dv = (c_f - c_r) / (2 * h + model.k_fall - model.k_rise)
    return acceleration * (0.5 * (c_r + c_f) - 0.5 * dv * (model.k_rise + model.k_fall))


def _residuals(t: np.ndarray, dist: np.ndarray, vel: np.ndarray, trusted: np.ndarray,
               rows: np.ndarray | None = None, ends: tuple | None = None) -> tuple[np.ndarray, np.ndarray]:
    """For the pairs `rows` (all when None): |distance - the median prediction of its
    trusted neighbours| (inf with fewer than SUPPORT of them) and how many there are;
    `ends` (group_ends): neighbours only within a pair's group."""
    if rows is not None and every_row(rows, dist.size):
        resid, support = _residuals(t, dist, vel, trusted, ends=ends)
        return resid[rows], support[rows]
    if dist.size == 0:
        return np.zeros(0), np.zeros(0, np.int64)
    # each row's window of 2 NEIGHBOURS + 1 pairs (itself in the middle): strided views
    # of the padded arrays, taken RESIDUAL_BLOCK rows at a time (the (rows, window)
    # temporaries stay in cache), or copied for a subset of rows
    windows = [np.lib.stride_tricks.sliding_window_view(padded(np.asarray(a), NEIGHBOURS, fill),
                                                        2 * NEIGHBOURS + 1)
               for a, fill in ((trusted, False), (t, 0.0), (dist, 0.0), (vel, 0.0))]
    blocks = [rows] if rows is not None else [slice(a, a + RESIDUAL_BLOCK)
                                              for a in range(0, dist.size, RESIDUAL_BLOCK)]
    got = [_residuals_of(at, t, dist, vel, *windows, ends) for at in blocks]
    if len(got) == 1:
        return got[0]
    return np.concatenate([g[0] for g in got]), np.concatenate([g[1] for g in got])


def every_row(rows: np.ndarray | None, pairs: int) -> bool:
    """Whether `_residuals` of the pairs `rows` of `pairs` (None: all) are best taken for
    every pair (strided views) and picked."""
    return rows is None or rows.size > pairs // 4


def _residuals_of(at, t, dist, vel, ok, tj, dj, vj, ends) -> tuple[np.ndarray, np.ndarray]:
    """_residuals of the pairs `at` (a slice or indices), from the windows of the trusted
    flags, times, distances and velocities."""
    ok = np.array(ok[at])
    if ends is not None:
        ok &= numeric.window_index(dist.size, NEIGHBOURS, ends, at)[1]
    ok[:, NEIGHBOURS] = False                   # a pair does not vouch for itself
    support = ok.sum(axis=1)
    tj, dj, vj = tj[at], dj[at], vj[at]
    pred = np.where(ok, dj + (t[at, None] - tj) * 0.5 * (vel[at, None] + vj), np.nan)
    with np.errstate(invalid="ignore"):
        resid = np.where(support >= SUPPORT, np.abs(dist[at] - row_nanmedian(pred)), np.inf)
    return resid, support


def _tolerance(resid: np.ndarray, trusted: np.ndarray) -> float:
    """JUMP_M, or JUMP_SIGMAS robust standard deviations of the trusted pairs' residuals
    (a noisy capture), at most JUMP_MAX_M: when most pairs are wrong their scatter must
    not widen the test until wrong pairs pass."""
    sure = np.isfinite(resid) & trusted
    sigma = 1.4826 * median(resid[sure]) if sure.any() else 0.0
    return min(max(JUMP_M, JUMP_SIGMAS * sigma), JUMP_MAX_M)


def continuity(t: np.ndarray, dist: np.ndarray, vel: np.ndarray, trusted: np.ndarray,
               groups: np.ndarray | None = None) -> np.ndarray:
    """Which pairs' distances agree with what their trusted neighbours predict.

    Neighbour j (within NEIGHBOURS pairs) predicts d_j + (t_i - t_j) (v_i + v_j) / 2 for
    pair i (the velocities are measured to mm/s, so the prediction is as good as d_j).
    A pair agrees when the median prediction is within JUMP_M, or JUMP_SIGMAS robust
    standard deviations of all residuals (a noisy capture; at most JUMP_MAX_M), of its
    distance, and at least SUPPORT neighbours vouch for it. A noise peak in a fade, or
    both half-sweeps on another echo, moves both sweeps' distances alike: the velocity
    test cannot see it, this one does. `groups`: each group of pairs on its own
    (`group_slices`).
    """
    resid, _ = _residuals(t, dist, vel, trusted, ends=group_ends(groups, t.size))
    return agreeing(resid, trusted, groups)


def agreeing(resid: np.ndarray, trusted: np.ndarray, groups: np.ndarray | None = None) -> np.ndarray:
    """`continuity` from the pairs' residuals (`_residuals`, m): within the tolerance of
    their group's trusted pairs (`_tolerance`)."""
    if groups is None:
        return resid <= _tolerance(resid, trusted)
    out = np.empty(resid.size, bool)
    for g in group_slices(groups, resid.size):
        out[g] = resid[g] <= _tolerance(resid[g], trusted[g])
    return out


def verify(t: np.ndarray, dist: np.ndarray, vel: np.ndarray, ok: np.ndarray, ops: SpectrumOps = NUMPY
           ) -> tuple[np.ndarray, np.ndarray]:
    """Validity as a fixed point: of the pairs `ok`, those that at least SUPPORT other
    pairs of the final set vouch for (`continuity`'s test, against the final set only).

    A pair vouched for by neighbours that are themselves rejected is rejected in turn,
    until nothing changes; only the pairs near a change are tested again. Between
    rounds, the pairs that most valid pairs within KINEMATIC_S disagree with are dropped
    (`_kinematic`), runs whose distance leaves their integrated velocity (`_drifting`),
    and runs at rest that the motion around them passes by (`_bridged`); last, short
    runs need an anchor (`_anchored`). `ops`: whose `residuals` and `disagreed` (a
    backend's: on its device).

    Returns
    -------
    verified : the final set.
    unsupported : pairs of `ok` dropped for too few valid neighbours (the others
        dropped disagree with theirs).
    """
    ok = np.asarray(ok, bool).copy()
    unsupported = np.zeros(ok.size, bool)
    _vouched(t, dist, vel, ok, unsupported, ops)
    while _kinematic(t, dist, vel, ok, ops) | _drifting(t, dist, vel, ok) | _bridged(t, dist, vel, ok):
        _vouched(t, dist, vel, ok, unsupported, ops)
    _anchored(t, dist, vel, ok, unsupported)
    return ok, unsupported


def _agrees(ta, da, va, tb, db, vb):
    """Whether pairs (ta, da, va) predict pairs (tb, db, vb) (s, m, m/s) as one body
    whose acceleration stays within ACCEL_MAX: distance within JUMP_MAX_M + ACCEL_MAX
    dt^2 / 8 of the trapezoid d_a + dt (v_a + v_b) / 2 (its error bound for any such
    motion), velocity within ACCEL_MAX |dt| + CONSISTENT_MPS. Symmetric in a and b."""
    dt = tb - ta
    pred = da + dt * 0.5 * (va + vb)
    return ((np.abs(db - pred) <= JUMP_MAX_M + ACCEL_MAX * dt * dt / 8)
            & (np.abs(vb - va) <= ACCEL_MAX * np.abs(dt) + CONSISTENT_MPS))


def _kinematic(t, dist, vel, ok, ops: SpectrumOps) -> bool:
    """Drop, in place, the pairs of `ok` that most of the other pairs of `ok` within
    KINEMATIC_S disagree with (`disagreed`); whether any was dropped.

    The neighbours' test spans 0.4 ms, over which a velocity a few m/s off moves the
    prediction by less than its tolerance: a wrong echo followed for a few ms (a
    Doppler image beside a wall, one direction's peak on another echo) passes it while
    its velocities disagree with its own distances' course by cm. Over 2 ms the two
    part; a right pair beside a few wrong ones keeps its majority.
    """
    drop = ops.disagreed(t, dist, vel, ok)
    ok[drop] = False
    return bool(drop.any())


def disagreed(t: np.ndarray, dist: np.ndarray, vel: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """The pairs of `ok` (times s, distances m, velocities m/s) that most of the other
    pairs of `ok` within KINEMATIC_S disagree with (`_agrees`; twin: kernels/verify.cl)."""
    agree = np.zeros(ok.size, np.int32)
    near = np.zeros(ok.size, np.int32)
    for k in range(1, min(KINEMATIC_PAIRS, ok.size - 1) + 1):      # pairs k apart, both ways at once
        a, b = slice(0, ok.size - k), slice(k, ok.size)
        both = ok[a] & ok[b] & (t[b] - t[a] <= KINEMATIC_S)
        if not both.any():                  # pairs k apart are all further apart than that
            continue
        with np.errstate(invalid="ignore"):
            yes = both & _agrees(t[a], dist[a], vel[a], t[b], dist[b], vel[b])
        near[a] += both
        near[b] += both
        agree[a] += yes
        agree[b] += yes
    return ok & (2 * agree < near)


def _runs(t, dist, vel, ok) -> list[np.ndarray]:
    """The runs of the valid pairs `ok` (indices): cut at gaps of more than NEIGHBOURS
    pairs and where the next valid pair leaves its kinematics (a wrong echo beside right
    pairs joins no run of theirs)."""
    idx = np.flatnonzero(ok)
    if idx.size == 0:
        return []
    a, b = idx[:-1], idx[1:]
    cut = np.flatnonzero((b - a > NEIGHBOURS) | ~_agrees(t[a], dist[a], vel[a], t[b], dist[b], vel[b])) + 1
    return np.split(idx, cut)


def _drifting(t, dist, vel, ok) -> bool:
    """Drop, in place, the runs (`_runs`) whose distance less the integral of their
    velocity has a least-squares slope beyond DRIFT_MPS: those of at least DRIFT_S, and
    those of at least DRIFT_PAIRS where the slope is also DRIFT_SIGMAS standard errors
    (numeric.drifts' jackknife), all runs at once; whether any was. Within 2 ms a
    velocity 1 m/s off moves the prediction by 2 mm, against a tolerance of 1.25: a
    wrong echo held at one distance for 25 ms with a velocity of 0.94 m/s passes
    `_kinematic`; over its run it drifts by 23 mm. Its last 4.95 ms, where the target
    came within 2-3.5 mm of it and the run was cut from the rest, drifted at -0.74 m/s,
    20 standard errors. Under noise at full scale, a take-off past the band's edge left
    28 pairs (1.35 ms) at 1.6 m/s and 49 mm short of the target, de-chirped 3-4 dB over
    the floor: 0.44 m/s, 6.7 standard errors."""
    runs = _runs(t, dist, vel, ok)
    if not runs:
        return False
    sizes = np.array([r.size for r in runs])
    idx = np.concatenate(runs)
    ends = np.cumsum(sizes)
    long = t[idx[ends - 1]] - t[idx[ends - sizes]] >= DRIFT_S
    tested = long | (sizes >= max(3, DRIFT_PAIRS))
    if not tested.any():
        return False
    mine = idx[np.repeat(tested, sizes)]
    slope, se = numeric.drifts(t[mine], dist[mine], vel[mine], sizes[tested], DRIFT_BLOCKS)
    limit = np.where(long[tested], DRIFT_MPS, np.fmax(DRIFT_MPS, DRIFT_SIGMAS * se))
    drifts = np.zeros(sizes.size, bool)
    drifts[tested] = np.abs(slope) > limit
    ok[idx[np.repeat(drifts, sizes)]] = False
    return bool(drifts.any())


def _bridged(t, dist, vel, ok) -> bool:
    """Drop, in place, the runs (`_runs`) at rest (median speed under REST_MPS) that the
    nearest runs on either side whose facing ends move (END_PAIRS long at least) pass
    by: those two join as one body across it (`_agrees` of their facing ends, each the
    medians of END_PAIRS pairs, at most BRIDGE_S apart) while it joins neither; whether
    any was. A wall the fixed echoes' tables miss (a rail's target passing 4 mm from one
    of 400 codes) holds the tracker for 5 ms at a time: self-consistent, its pairs at
    rest, up to 18 mm from where the target went on."""
    runs = _runs(t, dist, vel, ok)
    if len(runs) < 3:
        return False

    def end(r, last):
        k = r[-END_PAIRS:] if last else r[:END_PAIRS]
        return median(t[k]), median(dist[k]), median(vel[k])

    # the runs long enough to have ends, and those whose last (first) end moves, in order
    # (a landing's last run comes to rest: its median speed is no matter)
    sizes = np.array([r.size for r in runs])
    long = np.flatnonzero(sizes >= END_PAIRS)
    if long.size < 2:
        return False
    moves = [np.abs(np.median(vel[np.stack([runs[i][k] for i in long])], axis=1)) >= REST_MPS
             for k in (slice(-END_PAIRS, None), slice(END_PAIRS))]
    leaving, arriving = long[moves[0]], long[moves[1]]
    speed = numeric.group_median(np.repeat(np.arange(len(runs)), sizes), vel[np.concatenate(runs)], len(runs))
    dropped = False
    for i in np.flatnonzero((sizes >= 3) & ~(np.abs(speed) >= REST_MPS)):
        b, a = np.searchsorted(leaving, i), np.searchsorted(arriving, i, side="right")
        if b == 0 or a == arriving.size:
            continue
        r = runs[i]
        before, after = end(runs[leaving[b - 1]], True), end(runs[arriving[a]], False)
        if (after[0] - before[0] <= BRIDGE_S and _agrees(*before, *after)
                and not _agrees(*before, *end(r, False)) and not _agrees(*end(r, True), *after)):
            ok[r] = False
            dropped = True
    return dropped


def _vouched(t, dist, vel, ok, unsupported, ops: SpectrumOps) -> None:
    """`verify`'s fixed point of the neighbours' test, in place."""
    rows = np.flatnonzero(ok)
    tol = None
    while rows.size:
        resid, support = ops.residuals(t, dist, vel, ok, rows)
        tol = _tolerance(resid, ok[rows]) if tol is None else tol   # the capture's scatter, once
        drop = resid > tol
        if not drop.any():
            break
        gone = rows[drop]
        ok[gone] = False
        unsupported[gone] = support[drop] < SUPPORT
        hit = np.zeros(ok.size, np.int32)
        hit[gone] = 1
        reach = np.convolve(hit, np.ones(2 * NEIGHBOURS + 1, np.int32))       # pairs within reach of a drop
        near = reach[NEIGHBOURS:NEIGHBOURS + ok.size] > 0
        rows = np.flatnonzero(ok & near)


def _anchored(t, dist, vel, ok, unsupported) -> None:
    """Runs of valid pairs (no gap wider than NEIGHBOURS pairs, each pair predicting the
    next as below) shorter than ANCHOR_PAIRS vouch for each other only: such a run stays
    valid where the anchor run nearest on either side predicts its end (`_agrees`)
    across a gap of at most ANCHOR_GAP_S; else every pair of it is unsupported (a wrong
    echo followed for a few pairs is self-consistent)."""
    runs = _runs(t, dist, vel, ok)
    if not runs:
        return

    def agrees(a, b):                           # pair a predicts pair b
        return _agrees(t[a], dist[a], vel[a], t[b], dist[b], vel[b])

    anchors = [r for r in runs if r.size >= ANCHOR_PAIRS]
    firsts = np.array([r[0] for r in anchors])
    for r in runs:
        if r.size >= ANCHOR_PAIRS:
            continue
        k = np.searchsorted(firsts, r[0])         # anchors[k - 1] lies before r, anchors[k] after
        sides = ([(anchors[k - 1][-1], r[0])] if k > 0 else []) + \
                ([(anchors[k][0], r[-1])] if k < len(anchors) else [])
        if not any(abs(t[b] - t[a]) <= ANCHOR_GAP_S and bool(agrees(a, b)) for a, b in sides):
            ok[r] = False
            unsupported[r] = True


def group_slices(groups: np.ndarray | None, pairs: int) -> list[slice]:
    """The pairs of each group (`groups`: the first pair of each, 0 first; None: one
    group of all `pairs`): pairs converted together but apart from one another (the
    delay's trial stretches: ChunkProcessor.process_apart), which are nobody's neighbours
    across a group's ends."""
    edges = [0] if groups is None else [int(g) for g in groups]
    return [slice(a, b) for a, b in zip(edges, [*edges[1:], pairs], strict=True) if b > a]


def group_bounds(groups: np.ndarray | None, pairs: int) -> np.ndarray:
    """(2 pairs,) int32: the first pair of each pair's group (`group_slices`), then the
    last of each: what a kernel is told of the groups."""
    first, last = _ends(groups, pairs)
    return np.concatenate([first, last]).astype(np.int32)


def group_ends(groups: np.ndarray | None, pairs: int) -> tuple[np.ndarray, np.ndarray] | None:
    """The first and last pair of each pair's group (`group_slices`); None for one group
    (numeric.window_index's segments)."""
    return None if groups is None or len(group_slices(groups, pairs)) < 2 else _ends(groups, pairs)


def _ends(groups: np.ndarray | None, pairs: int) -> tuple[np.ndarray, np.ndarray]:
    slices = group_slices(groups, pairs)
    size = [g.stop - g.start for g in slices]
    return (np.repeat([g.start for g in slices], size).astype(np.int64),
            np.repeat([g.stop - 1 for g in slices], size).astype(np.int64))


def _each(groups: np.ndarray, step, pairs: int, dtype=np.float64) -> np.ndarray:
    """`step(g)` of each group's slice g of `pairs`, laid end to end."""
    parts = [step(g) for g in group_slices(groups, pairs)]
    return np.concatenate(parts) if parts else np.zeros(0, dtype)


def running_median(v: np.ndarray, groups: np.ndarray | None = None, reach: int = NEIGHBOURS) -> np.ndarray:
    """Median of each pair's 2 reach + 1 pairs (edges, a group's too: nearest)."""
    return numeric.running_median(v, 2 * reach + 1, group_ends(groups, v.size))


def regularise(v: np.ndarray, trusted: np.ndarray, time: np.ndarray,
               smooth: np.ndarray | None = None, groups: np.ndarray | None = None) -> np.ndarray:
    """Continuity prior: running median of trusted velocities, gaps filled linearly
    (`smooth`: running_median(v) when the caller has it), each group on its own."""
    smooth = running_median(v, groups) if smooth is None else smooth
    if groups is not None:
        return _each(groups, lambda g: regularise(v[g], trusted[g], time[g], smooth[g]), v.size)
    if not np.any(trusted):
        return np.zeros_like(v)
    return np.interp(time, time[trusted], smooth[trusted])


class _Windows:
    """Both directions measured on K-window integrated spectra (stages.integrate); the
    spectra are kept between the tracker's passes, re-made only for the rows whose
    de-chirp velocity moved."""

    def __init__(self, ops, rows: tuple, model: DopplerModel, search: Search, k: int, times: Times):
        self.ops, self.rows, self.model, self.search, self.k = ops, rows, model, search, k
        self.t, self.groups = times.mid, times.groups
        # each group's windows end at its ends, its displacement starts at its start
        self.bounds = None if times.groups is None else times.bounds
        self.betas = (model.beta_rise, model.beta_fall)
        self.stores = [ops.spectra(x, None, None, model.nfft) for x in rows]

    def measure(self, vd: np.ndarray, moved: np.ndarray | None = None) -> tuple:
        """(d_r, s_r, d_f, s_f, count) of every pair, after re-making the spectra of the
        rows `moved` (all when None) de-chirped at vd; aligned along vd."""
        m = self.model
        if moved is not None:
            every = None if moved.size == vd.size else moved
            self.stores = [self.ops.spectra(x, beta, vd[moved], m.nfft, every, store)
                           for x, beta, store in zip(self.rows, self.betas, self.stores, strict=True)]
        if self.groups is None:
            disp = numeric.travelled(self.t, vd)
        else:
            disp = _each(self.groups, lambda g: numeric.travelled(self.t[g], vd[g]), vd.size)
        disp = disp / m.metres_per_bin
        out = []
        for store in self.stores:
            b, snr, count = self.ops.integrated_peaks(store, disp, self.k, self.search, self.bounds)
            out += [b * m.metres_per_bin, snr]
        return (*out, count)


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
    vd = np.zeros(t_mid.size)          # the velocity each pair was last de-chirped with
    windows = _Windows(ops, rows, model, search, k, times) if k > 1 else None
    if windows is not None:
        d_r, s_r, d_f, s_f, count = windows.measure(vd)
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
