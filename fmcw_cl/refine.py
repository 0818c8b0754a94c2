"""The sync delay refined on every capture's own target.

The intensity triangle in the low-passed beat gives a first estimate of how far the
sync lags the optics (`stages.sync`); a lab's weak triangle under noise leaves it a few
samples off in 50 ms. A delay error shifts the resampling instants along the nonlinear
chirp, which moves the rising and falling peaks in opposite directions: a velocity
appears that the distance does not show. So the delay is moved to where the track is
kinematically consistent: over a few stretches of the capture, the distance less the
integral of the velocity must not drift (its least-squares slope, the *mismatch*, is
zero), found by secant steps from the intensity estimate.

The mismatch's standard error (each run's the larger of its white residuals' and a
jackknife's, or the stretches' spread where that is larger) over its slope against the
delay is the delay's uncertainty (where noise keeps the secant steps from settling, the
root and its error come from a line through the trials near the best); in
velocity it is the standard error itself, in distance the delay's uncertainty times how
far the stretches' mean distance moves per sample. A run is the valid pairs of a
stretch with at most BRIDGE_PAIRS invalid ones between two, across which the distance
moves as the velocity says; a capture whose stretches hold no run of MIN_RUN valid pairs
keeps the intensity estimate.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from . import numeric
from .capture import Capture
from .chunk_state import Held
from .chunks import held_end_to_end
from .motion import SMOOTH, Motion, choose
from .stages import doppler, kinematics

STRETCHES = 3
STRETCH_PERIODS = 240
STEP_SAMPLES = 2.0        # first secant step
MAX_SHIFT_SAMPLES = 200.0
TOLERANCE_SAMPLES = 0.02
MAX_EVALUATIONS = 6
MIN_RUN = 60              # valid pairs of a run used
BRIDGE_PAIRS = 3          # a run goes on across this many invalid pairs (150 us) ...
BRIDGE_M = 0.002          # ... where the distance moves by no more than this beyond the velocity's
JACKKNIFE_BLOCKS = 6      # blocks of a run left out in turn for the drift's standard error
FIT_SAMPLES = 5.0         # unsettled trials this near the best are fitted by a line
TRIAL_ITERATIONS = 3      # de-chirp passes of a trial conversion: on a lab's landings six
                          # moved the delay by 0.02 samples at most, two left it 1-4 samples off
SETTLED = 0.25            # a mismatch this many of its standard errors from zero is the root


@dataclass(frozen=True)
class Mismatch:
    """Kinematic inconsistency of a trial delay: `mps`, the drift of distance less the
    integrated velocity (m/s, mean over stretches; NaN when none could be measured),
    `sigma_mps` its standard error, `distance_m` the stretches' mean distance,
    `distances` every pair's distance of the stretches (NaN where not valid), for the
    delay's effect on the same pairs; `motion` the windows their velocities call for
    (fmcw_cl.motion.choose)."""

    mps: float
    sigma_mps: float
    distance_m: float
    distances: np.ndarray = field(default_factory=lambda: np.zeros(0))
    motion: Motion = SMOOTH


def drift(t: np.ndarray, d: np.ndarray, v: np.ndarray) -> tuple[float, float]:
    """numeric.drift of one run, its error the larger of the white residuals' and a
    jackknife's over JACKKNIFE_BLOCKS blocks: the tracker's distances are correlated
    over several pairs (under noise at full scale their variogram grows from 40 um at
    one pair to a plateau of 90 um at 5-10), which the white residuals' error misses by
    a factor of two or so."""
    return numeric.drift(t, d, v, JACKKNIFE_BLOCKS)


def stretches(cap: Capture, plan, processor) -> Held:
    """The trial stretches of `plan`'s capture, STRETCHES of STRETCH_PERIODS spread
    through it: their chunks read once, end to end, each with what `processor.prepare`
    finds in it (the trial conversions move only the delay). Once a capture, chunk size
    and processor: the second look converts them again (`Capture.held` keeps them while
    nothing else takes their slot)."""
    key = ("stretches", plan.options.chunk_periods, plan.options.context_periods, processor)
    if cap.held is not None and cap.held[0] == key:
        return cap.held[1]
    info = cap.info
    length = int(STRETCH_PERIODS * info.samples_per_period)
    starts = np.unique(np.linspace(0, max(0, info.samples - length), STRETCHES).astype(np.int64))
    ranges = [(int(a), int(a) + length) for a in starts]
    beat, chunks, offsets, stretch = held_end_to_end(cap, plan.options, ranges)
    held = Held(beat, chunks, offsets, [processor.prepare(c, info) for c in chunks], stretch)
    cap.held = (key, held)
    return held


def by_stretch(held: Held, converted: list[list]) -> list[list]:
    """The measurements of each stretch of `held`, from those of each of its chunks."""
    out = [[] for _ in range(max(held.stretch, default=-1) + 1)]
    for k, parts in zip(held.stretch, converted, strict=True):
        out[k] += parts
    return out


def trial_plan(plan, lag: float):
    """`plan` at `lag` for a trial conversion: no range check, survey or echo list, at
    most TRIAL_ITERATIONS de-chirp passes (distances and velocities alone)."""
    options = replace(plan.options, iterations=min(plan.options.iterations, TRIAL_ITERATIONS))
    return replace(plan, lag=lag, check=None, survey=False, search=replace(plan.search, echoes=False),
                   options=options)


def mismatches(held: Held, plan, lags: list[float], processor) -> list[Mismatch]:
    """The kinematic inconsistency of `plan` at each delay of `lags` over the trial
    stretches `held` (`stretches`), all converted together by `processor` in one pass,
    each stretch and delay apart (`trial_plan`)."""
    processor.open(trial_plan(plan, lags[0]))
    at = held.at(lags)
    each = by_stretch(at, processor.process_apart(at))
    n = len(each) // len(lags)
    return [mismatch(each[j * n: (j + 1) * n], plan.model, plan.motion) for j in range(len(lags))]


def mismatch(stretches: list[list], model, motion: Motion = SMOOTH) -> Mismatch:
    """The kinematic inconsistency of converted trial stretches (each a list of
    ChunkMeasurements): their longest bridged runs' mean drift, its standard error and
    the runs' mean distance (`pairs_of` over `motion`'s windows)."""
    slopes, errors, dist, every = [], [], [], []
    heard = [np.concatenate([q.result.velocity[q.result.heard] for q in parts])
             for parts in stretches if parts]
    for parts in stretches:
        if not parts:
            continue
        t, d, v, ok = pairs_of(parts, model, motion)
        every.append(np.where(ok, d, np.nan))
        run = max(bridged_runs(t, d, v, ok), key=np.size, default=np.zeros(0, np.int64))
        if run.size < MIN_RUN:
            continue
        slope, se = drift(t[run], d[run], v[run])
        slopes.append(slope)
        errors.append(se)
        dist.append(float(np.mean(d[run])))
    every = np.concatenate(every) if every else np.zeros(0)
    motion = choose(heard)
    if not slopes:
        return Mismatch(float("nan"), float("nan"), float("nan"), every, motion)
    # the standard error of the mean: from the runs' residuals, or from the stretches'
    # spread where that is larger (the residuals of d - integral of v are not white)
    n = len(slopes)
    sigma = float(np.sqrt(np.sum(np.square(errors)))) / n
    if n > 1:
        sigma = max(sigma, float(np.std(slopes, ddof=1)) / np.sqrt(n))
    return Mismatch(float(np.mean(slopes)), sigma, float(np.mean(dist)), every, motion)


def bridged_runs(t: np.ndarray, d: np.ndarray, v: np.ndarray, ok: np.ndarray) -> list[np.ndarray]:
    """The indices of the valid pairs of `ok` (times s, distances m, velocities m/s),
    split where more than BRIDGE_PAIRS invalid pairs lie between two, or where the
    distance across the invalid ones moves by more than BRIDGE_M beyond what the
    velocity says (another echo). The velocity is integrated across the other gaps:
    noise leaves a few isolated invalid pairs in a lab's runs."""
    idx = np.flatnonzero(ok)
    if idx.size == 0:
        return []
    a, b = idx[:-1], idx[1:]
    jump = np.abs(d[b] - d[a] - 0.5 * (v[a] + v[b]) * (t[b] - t[a]))
    return np.split(idx, np.flatnonzero((b - a > BRIDGE_PAIRS + 1) | ((b - a > 1) & (jump > BRIDGE_M))) + 1)


def pairs_of(parts, model, motion: Motion = SMOOTH) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Time (s), distance (m), velocity (m/s) and validity of the pairs of converted
    chunks (processor.ChunkMeasurements) of one stretch, the distances of valid runs
    free of the acceleration's bias (doppler.acceleration_bias, its acceleration over
    `motion.bias` pairs, as the track's are; `model`: the plan's DopplerModel)."""
    t = np.concatenate([0.5 * (q.t_rise + q.t_fall) for q in parts])
    d = np.concatenate([q.result.distance for q in parts])
    v = np.concatenate([q.result.velocity for q in parts])
    ok = np.concatenate([q.reason == 0 for q in parts])
    if t.size > 1:
        # over a wider window than the track's: a trial's velocities may be noise (a
        # chirp far off its table: 17 mm/s a pair), whose acceleration must not move the
        # distances it is integrated against
        held = kinematics.held_acceleration(np.where(ok, v, np.nan), ok, float(np.median(np.diff(t))),
                                            motion.bias, motion.hold)
        half_gap = np.concatenate([0.5 * (q.t_fall - q.t_rise) for q in parts])
        d = d - doppler.acceleration_bias(held, half_gap, model)
    return t, d, v, ok


def refine_lag(cap: Capture, plan, processor):
    """The plan with its lag moved to where the track is kinematically consistent
    (trial stretches converted by `processor`), with the delay's uncertainty (samples)
    and what it means in velocity (m/s) and distance (m), and the windows its target's
    motion calls for (fmcw_cl.motion: chosen on the first trial, made again with them).

    Keeps the estimate (lag_refined False) when no stretch can be measured."""
    lag0 = plan.lag
    held = stretches(cap, plan, processor)
    xs = [lag0, lag0 + STEP_SAMPLES]
    ms = mismatches(held, plan, xs, processor)
    if plan.motion is SMOOTH and ms[0].motion is not SMOOTH:    # a vibration: its windows, the trials again
        plan = plan.with_motion(ms[0].motion)
        ms = mismatches(held, plan, xs, processor)
    if not (np.isfinite(ms[0].mps) and np.isfinite(ms[1].mps)) or ms[1].mps == ms[0].mps:
        return plan
    # d(mismatch)/d(lag) and d(distance)/d(lag) from the first step: smooth in the lag
    slope = (ms[1].mps - ms[0].mps) / STEP_SAMPLES
    moves = distance_step(ms[0], ms[1]) / STEP_SAMPLES
    settled = False
    while len(xs) < MAX_EVALUATIONS:
        a, b = [k for k, m in enumerate(ms) if np.isfinite(m.mps)][-2:]
        if not np.isfinite(ms[-1].mps):
            # a trial without runs (under noise at full scale, some 9 samples from the
            # root): half way back to the last one with runs, not the search's end
            nxt = 0.5 * (xs[-1] + xs[b])
        else:
            step = (ms[b].mps - ms[a].mps) / (xs[b] - xs[a])
            if step == 0:
                break
            nxt = float(np.clip(xs[b] - ms[b].mps / step, lag0 - MAX_SHIFT_SAMPLES, lag0 + MAX_SHIFT_SAMPLES))
        done = abs(nxt - xs[b]) < TOLERANCE_SAMPLES
        xs.append(nxt)
        ms += mismatches(held, plan, [nxt], processor)
        # converged, or what is left is small against its own uncertainty: a further
        # trial conversion would move the delay by a fraction of its sigma
        settled = done or abs(ms[-1].mps) <= SETTLED * ms[-1].sigma_mps
        if settled:
            break
    good = [k for k, m in enumerate(ms) if np.isfinite(m.mps)]
    best = min(good, key=lambda k: abs(ms[k].mps))
    lag, left, sigma_mps = xs[best], abs(ms[best].mps), ms[best].sigma_mps
    sigma_lag = sigma_mps / abs(slope)
    near = [k for k in good if abs(xs[k] - lag) <= FIT_SAMPLES]
    if not settled and len(near) >= 3:
        # noise kept the secant steps from settling: the root of a line through the
        # trials near the best, weighted by their errors, uses them all
        fit = line_root(np.array([xs[k] for k in near]), np.array([ms[k].mps for k in near]),
                        np.array([ms[k].sigma_mps for k in near]))
        if fit is not None:
            lag, sigma_lag, slope = fit
            left, sigma_mps = 0.0, sigma_lag * abs(slope)
    if not settled and left > 0:
        # not at a root (a trial without runs ended the search): what is left of the
        # mismatch is uncertainty too (a lab's capture under noise at full scale kept
        # 0.117 m/s, 7.6 of its sigmas, and stated 1.0 samples for 55 off)
        sigma_mps = float(np.hypot(sigma_mps, left))
        sigma_lag = sigma_mps / abs(slope)
    return replace(plan, lag=lag, lag_refined=True, lag_mismatch_mps=left,
                   lag_sigma_samples=sigma_lag, lag_sigma_mps=sigma_mps,
                   lag_sigma_m=abs(moves) * sigma_lag, lag_at_m=ms[best].distance_m)


DISAGREE_SIGMAS = 3.0     # the refined delay and the intensity's this far apart are said to disagree


def disagreement(plan) -> float:
    """How many standard uncertainties apart the refined delay and the intensity
    triangle's estimate lie (NaN when not refined or either has none).

    The rule where they disagree (over DISAGREE_SIGMAS): the refined delay is kept. It
    is measured on the target's own motion, what the velocities depend on; the
    intensity triangle is not the optical frequency (a laser's thermal tuning lags its
    current), and a moving target's beat leaks into its fit: of 36 short captures
    (benchmarks/delay.py, seeds 1-3) four disagreed by 3.3-9.7 sigmas, each time the
    intensity estimate 16-109 samples off and the refined one within 0.3."""
    if not plan.lag_refined:
        return float("nan")
    both = float(np.hypot(plan.lag_sigma_samples, plan.lag_intensity_sigma))
    return abs(plan.lag - plan.lag_intensity) / both


def distance_step(a: Mismatch, b: Mismatch) -> float:
    """How far trial `b` moves the distances of `a` (m): the median over the pairs valid
    in both (the runs' mean distances differ by which pairs each kept: on a moving
    target, by centimetres that no delay made). NaN when none are."""
    if a.distances.size != b.distances.size:
        return float("nan")
    both = np.isfinite(a.distances) & np.isfinite(b.distances)
    return float(np.median(b.distances[both] - a.distances[both])) if both.any() else float("nan")


def line_root(x: np.ndarray, y: np.ndarray, sigma: np.ndarray) -> tuple[float, float, float] | None:
    """(root, its standard error, slope) of the weighted least-squares line through
    (x, y +- sigma); the error from the given sigmas or from the residuals, the larger
    (None: a flat line, or a root outside the span of x)."""
    w = 1.0 / np.square(sigma)
    xm = np.sum(w * x) / np.sum(w)
    sxx = np.sum(w * np.square(x - xm))
    slope = np.sum(w * (x - xm) * y) / sxx
    mean = np.sum(w * y) / np.sum(w)
    if slope == 0:
        return None
    root = xm - mean / slope
    if not x.min() <= root <= x.max():
        return None
    chi2 = np.sum(w * np.square(y - mean - slope * (x - xm))) / max(1, x.size - 2)
    # var(root) from var(mean) = 1 / sum w and var(slope) = 1 / sxx (independent about xm)
    var = (1.0 / np.sum(w) + np.square(root - xm) / sxx) / np.square(slope) * max(1.0, chi2)
    return float(root), float(np.sqrt(var)), float(slope)
