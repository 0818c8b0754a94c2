"""Whether a pair's two half-sweeps hold one body: their phases move together.

Each half-sweep's phase at its peak reads k R(t_c) (stages.phase; k = 4 pi n nu_c / c,
2 pi per half wavelength) up to a constant of its direction. Between two consecutive
pairs (T apart) one body moves alike in both directions, so the change of the two
directions' phase difference theta = phi_first - phi_second is k T (v(t_first) -
v(t_second)) = k T h a (h = t_first - t_second, -25 us; a the acceleration): 0.33 rad
for a rail braking at 32 m/s^2, whatever its speed. A pair made of two bodies' peaks
(a rail's Doppler-shifted peak in one direction, a glide's in the other, crossing: their
mean moves at their mean velocity as one body's would) changes theta by k T (v_A - v_B),
hundreds of radians a step, and by k T^2 (a_A - a_B) from step to step: the steps'
residuals against k T h a scatter round the circle, or sit away from zero. A still
wall's phase holds, speckle turns both directions alike, and a blend of two echoes in
one peak (a mover passing a wall within the resolution) reads each direction's own
mixture: not one body either.

`apart` judges windows of WINDOW consecutive steps between verified pairs: where the
pairs' SNRs promise a mean resultant length of at least JUDGED_R (each phase's noise
1 / sqrt(2 SNR), as the displacement's) and the steps' residuals reach less than
MIN_R, or their mean lies more than OFF_RAD from zero, the window's pairs are two
bodies'. Uniform residuals exceed MIN_R over WINDOW steps with probability
exp(-WINDOW MIN_R^2) (2 %).
"""

from __future__ import annotations

import numpy as np

from . import objects
from .fixed_echoes import MOVING_MPS
from .objects import per_pair
from .stages import faults
from .stages.verification import ACCEL_MAX, JUMP_MAX_M
from .track import Track

WINDOW = 16         # steps a window (0.8 ms at 20 kHz)
MIN_R = 0.5         # a window's mean resultant length under this: its residuals scatter round the circle
OFF_RAD = 1.0       # ... or its mean residual this far from zero (rad): the directions drift apart
JUDGED_R = 0.8      # a window is judged where the SNRs promise this resultant length or more
STEP_S = 3.5        # a step joins consecutive pairs at most this many periods apart
SPAN_S = 5e-3       # s: a window's steps lie within this (a tracker's run may break between them)
SLOPE_PERIODS = 8   # the acceleration: the slope of the velocities within this many periods of a step


def residuals(time_s: np.ndarray, sweep_time_s: np.ndarray, phase_rad: np.ndarray, snr_db: np.ndarray,
              velocity_mps: np.ndarray, used: np.ndarray, rad_per_m: float, period_s: float
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The steps between consecutive `used` pairs at most STEP_S periods apart: their
    first and second pairs' indices, the residual (rad) of the change of theta against k T h a, and
    the variance (rad^2) the four phases' noise gives it.

    Parameters
    ----------
    time_s : (n,) the pairs' centre times (s).
    sweep_time_s, phase_rad, snr_db : (2, n) per pair, its two half-sweeps' centre
        times (s), phases at their peaks (rad) and SNRs (dB), in time order.
    velocity_mps : (n,) the pairs' velocities (m/s): the acceleration at a step is
        their slope over the `used` pairs within SLOPE_PERIODS of it (a take-off's
        jerk: the kinematics' smoothed acceleration, or none where its window is not
        whole, missed k T h a by 2.5 rad).
    used : (n,) bool, the pairs whose steps count (verified, single half-sweeps).
    rad_per_m : k (rad/m); period_s : the modulation period (s).
    """
    i = np.flatnonzero(used)
    close = np.diff(time_s[i]) <= STEP_S * period_s
    a, b = i[:-1][close], i[1:][close]
    theta = phase_rad[0] - phase_rad[1]
    h = sweep_time_s[0] - sweep_time_s[1]
    acc = slope(time_s[i], velocity_mps[i], 0.5 * (time_s[a] + time_s[b]), SLOPE_PERIODS * period_s)
    expected = rad_per_m * (time_s[b] - time_s[a]) * 0.5 * (h[a] + h[b]) * acc
    eps = np.angle(np.exp(1j * (theta[b] - theta[a] - expected)))
    with np.errstate(over="ignore"):
        var = 0.5 * np.sum(np.power(10.0, -snr_db[:, a] / 10) + np.power(10.0, -snr_db[:, b] / 10), axis=0)
    return a, b, eps, var


def slope(t: np.ndarray, y: np.ndarray, at: np.ndarray, reach: float) -> np.ndarray:
    """The least-squares slope of y(t) over the points within `reach` of each of `at`
    (0 where fewer than three lie there)."""
    t0 = t[0] if t.size else 0.0
    t, at = t - t0, at - t0
    sums = [np.concatenate([[0.0], np.cumsum(x)]) for x in (np.ones_like(t), t, t * t, y, t * y)]
    lo, hi = np.searchsorted(t, at - reach), np.searchsorted(t, at + reach, side="right")
    n, st, stt, sy, sty = (c[hi] - c[lo] for c in sums)
    det = n * stt - st * st
    with np.errstate(invalid="ignore", divide="ignore"):
        out = (n * sty - st * sy) / det
    return np.where((n >= 3) & (det > 0), out, 0.0)


def apart(time_s: np.ndarray, sweep_time_s: np.ndarray, phase_rad: np.ndarray, snr_db: np.ndarray,
          velocity_mps: np.ndarray, used: np.ndarray, rad_per_m: float, period_s: float) -> np.ndarray:
    """The `used` pairs (bool, per pair) within a window of WINDOW consecutive steps
    (`residuals`: each across at most STEP_S periods; all within SPAN_S) whose phases do not move as
    one body's: its SNRs promise a resultant length of JUDGED_R or more, and its
    residuals' is under MIN_R or their mean lies more than OFF_RAD from zero."""
    first, second, eps, var = residuals(time_s, sweep_time_s, phase_rad, snr_db, velocity_mps, used,
                                        rad_per_m, period_s)
    if first.size < WINDOW:
        return np.zeros(time_s.size, bool)
    z = np.exp(1j * eps)
    promised = np.exp(-0.5 * var)
    cz = np.concatenate([[0], np.cumsum(z)])
    cp = np.concatenate([[0], np.cumsum(promised)])
    s = np.arange(first.size - WINDOW + 1)
    whole = time_s[second[s + WINDOW - 1]] - time_s[first[s]] <= SPAN_S
    mean = (cz[s + WINDOW] - cz[s]) / WINDOW
    judged = whole & ((cp[s + WINDOW] - cp[s]) / WINDOW >= JUDGED_R)
    r = np.abs(mean)
    bad = judged & ((r < MIN_R) | (np.abs(np.angle(mean)) > OFF_RAD))
    # every used pair from a bad window's first step to its last (one lone between its steps too)
    edge = np.zeros(time_s.size + 1, int)
    k = np.flatnonzero(bad)
    np.add.at(edge, first[k], 1)
    np.add.at(edge, second[k + WINDOW - 1] + 1, -1)
    return used & (np.cumsum(edge)[:-1] > 0)


def two_bodies(track: Track, rad_per_m: float) -> np.ndarray:
    """`apart` on a track's verified pairs of single half-sweeps (an integrated pair's
    phase is its sum's, over 1.6 ms at K = 32: an occluder's read 0.16 m with 39 dB
    before it was seen, its residuals scattered round the circle): per pair, whether it
    lies in a window of two bodies' steps (none where the track holds no phases: the
    paper's method)."""
    if track.sweep_phase_rad is None or track.sweep_snr_dechirped_db is None:
        return np.zeros(track.pairs, bool)
    phases = per_pair(track, "sweep_phase_rad")
    snr = per_pair(track, "sweep_snr_dechirped_db")
    used = track.valid & np.all(np.isfinite(phases) & np.isfinite(snr), axis=0)
    if track.integrated is not None:
        used &= track.integrated <= 1
    elif track.attrs.get("integrated_sweeps_max", 1) > 1:      # every pair a sum of K half-sweeps
        used[:] = False
    return apart(track.time_s, per_pair(track, "sweep_time_s"), phases, snr, track.velocity_mps, used,
                 rad_per_m, _period(track))


def cuts(track: Track, two: np.ndarray, others: list[Track]) -> np.ndarray:
    """The times (s) at which `track` held another body as well as its own, and came
    out of it on one of the two with nothing to tell which: the middle of each run of
    its `two` pairs (`two_bodies`) with verified pairs on both sides, one of those two
    slower than fixed_echoes.MOVING_MPS or the velocity across the run turned by more
    than that beyond the accelerations either side (`slope`), where a mover of `others`
    can have been there (from its last verified pair before the run or its first after,
    `_there`): two legs' plateaus within the resolution at once, parting at
    +0.18 and +0.19 m/s (365 valid pairs of one leg on the other's object); two legs
    crossing at -0.50 and +0.43 m/s (42). Not where the track runs on through it as
    one body (a switch to a body moving alike within that is not caught), nor where no
    other mover can have been there (a target setting off beside a trembling wall, its
    rest cut from its run: 80 -> 72 % of its periods)."""
    k = np.flatnonzero(track.valid)
    flag = two[k]
    if not flag.any():
        return np.zeros(0)
    edge = np.diff(np.r_[0, flag.astype(np.int8), 0])
    lo, hi = np.flatnonzero(edge == 1), np.flatnonzero(edge == -1) - 1      # runs of flagged pairs, in k
    inner = (lo > 0) & (hi < k.size - 1)
    lo, hi = k[lo[inner]], k[hi[inner]]
    before, after = k[np.searchsorted(k, lo) - 1], k[np.searchsorted(k, hi) + 1]
    t, v = track.time_s, track.velocity_mps
    rest = k[~flag]                 # the accelerations either side, from the pairs outside the runs
    acc = [slope(t[rest], v[rest], t[x], SLOPE_PERIODS * _period(track)) for x in (before, after)]
    turn = np.abs(v[after] - v[before] - 0.5 * (acc[0] + acc[1]) * (t[after] - t[before]))
    keep = (np.minimum(np.abs(v[before]), np.abs(v[after])) < MOVING_MPS) | (turn > MOVING_MPS)
    lo, hi = lo[keep], hi[keep]
    near = np.zeros(lo.size, bool)
    for o in others:
        ok = np.flatnonzero(o.valid)
        if not ok.size:
            continue
        last = ok[np.maximum(np.searchsorted(o.time_s[ok], t[lo]) - 1, 0)]
        first = ok[np.minimum(np.searchsorted(o.time_s[ok], t[hi], "right"), ok.size - 1)]
        near |= (o.time_s[last] < t[lo]) & _there(o, last, t[lo], track.distance_m[lo])
        near |= (o.time_s[first] > t[hi]) & _there(o, first, t[hi], track.distance_m[hi])
    return 0.5 * (t[lo[near]] + t[hi[near]])


def _period(track: Track) -> float:
    """The track's modulation period (s): its own, else its pairs' median spacing."""
    return track.period_s or float(np.median(np.diff(track.time_s)))


def _there(o: Track, k: np.ndarray, t: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Whether the body of `o`'s pairs `k` can be at distances `d` (m) at times `t` (s):
    within verification.JUMP_MAX_M + ACCEL_MAX dt^2 / 2 of where its velocity carries it."""
    dt = t - o.time_s[k]
    return np.abs(d - o.distance_m[k] - o.velocity_mps[k] * dt) <= JUMP_MAX_M + 0.5 * ACCEL_MAX * dt * dt


def verified_again(track: Track) -> Track:
    """`track` with its valid pairs verified once more among themselves
    (stages.faults.verified): a pair whose neighbours were two bodies' is vouched for by
    none (`UNVERIFIED`) or disagrees with those left (`DISCONTINUOUS`)."""
    code = faults.verified(track.time_s, track.distance_m, track.velocity_mps,
                           np.where(track.valid, faults.OK, faults.AMBIGUOUS).astype(np.int8),
                           looks=track.integrated)
    out = objects.invalidated(track, code == faults.UNVERIFIED, faults.UNVERIFIED)
    objects.invalidate(out, code == faults.DISCONTINUOUS, faults.DISCONTINUOUS)
    return out
