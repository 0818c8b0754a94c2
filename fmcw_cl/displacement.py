"""The target's displacement from the beat's phase: nanometres where the peaks give micrometres.

Each half-sweep's phase at its peak (stages.phase) reads k R(t_c), k = 4 pi n nu_c / c
(2 pi per half wavelength), up to a constant of its direction (the scene's phase, the
sync delay's and the chirp's share, which differ between rising and falling sweeps).
Along time the phase of each direction is unwrapped with the motion the pairs'
velocities predict between half-sweeps (trapezoids: 50 us at 7 m/s is 450 half
wavelengths, which no unwrapping of the phase alone follows): the step's residual,
wrapped into (-pi, pi], is the prediction's error. The pair's displacement is the mean
of its two directions, each unwrapped from the stretch's first pair (0 is the mean of
the first stretch's first ZERO_PAIRS: a capture's first pair reads a nanometre or two
off, the sync's edge): the mean refers it
to the pair's centre time and cancels what differs in sign between the directions (the
residual video phase, a delay error).

A step is followed only between pairs whose distance is verified (their velocities,
verified or not, only predict it: the residuals and third differences judge), across at
most GAP_PAIRS missing ones, and only where its residual stays within SLIP_RAD in both
directions and the two directions agree within SLIP_RAD: beyond that a whole turn (a
slip of half a wavelength) cannot be excluded, and the stretch ends there. A stretch
shorter than MIN_PAIRS is not valid. A later stretch is referred to the first by the
peaks' distances (their mean difference to the phase over each stretch), with their
uncertainty; within a stretch, the peaks check the phase: where the distance leaves
the displacement by more than CHECK_SIGMAS of their local scatter plus a quarter
wavelength (a slip the residuals missed, several in a row), the pairs are not valid.
Where a stretch's echo scintillates (speckle decorrelating: its phase turns as its
amplitude changes, `_scintillates`), the target's surface does: no stretch of the
capture is valid (one judged alone sits on the threshold: 0.09-0.10 beside 0.14).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .numeric import median, ragged, running_median, segment_cumsum

SLIP_RAD = np.pi / 2      # a step's residual (or the directions' disagreement) beyond this may hide a turn
GAP_PAIRS = 4             # the phase is followed across at most this many missing pairs (150 us)
MIN_PAIRS = 8             # a stretch this short is not valid
CHECK_PAIRS = 64          # the peaks' check: running means over this many pairs
CHECK_SIGMAS = 5.0
COVERAGE = 2.0            # expanded uncertainty, k = 2 (as the distance's)
BLOCKS = 8                # a stretch's reference from the peaks: its error from this many blocks' means
SCINT_PAIRS = 32          # an echo's amplitude change over this many pairs (1.6 ms) ...
SCINT_LN = 0.1            # ... beyond this (ln, median): it scintillates, its phase is no displacement
ZERO_PAIRS = 8            # the displacement's zero: the mean of the first stretch's first pairs
BIAS_PAIRS = 64           # the velocities' common bias: the steps' mean residual over this many pairs ...
BIAS_RAD = 3 * np.pi / 8  # ... taken off where the stated one is at most this a step (a turn then passes
                          # unseen only under a bias of six times its standard uncertainty, less the noise)
JERK_PASSES = 3           # the third differences checked, the pairs of a wrong turn dropped, this often


@dataclass(frozen=True)
class Displacement:
    """Per pair: displacement (m; 0 is the mean of the first stretch's first ZERO_PAIRS
    pairs), whether it holds, its expanded uncertainty (m, k = 2), its stretch (0, 1,
    ...; -1 where not valid)."""

    metres: np.ndarray
    valid: np.ndarray
    uncertainty_m: np.ndarray
    stretch: np.ndarray
    scintillating: int = 0        # stretches refused: the echo's amplitude scintillates

    @classmethod
    def none(cls, pairs: int) -> Displacement:
        """No pair's displacement (none measured, or none followed)."""
        nan = np.full(pairs, np.nan)
        return cls(nan, np.zeros(pairs, bool), nan.copy(), np.full(pairs, -1, np.int32))

    def attrs(self) -> dict:
        ok = self.valid
        return {"displacement_stretches": int(self.stretch.max(initial=-1) + 1),
                "displacement_valid_pairs": int(ok.sum()),
                "displacement_scintillating_stretches": int(self.scintillating),
                "displacement_slip_rad": SLIP_RAD, "displacement_gap_pairs": GAP_PAIRS}


def _wrap(a: np.ndarray) -> np.ndarray:
    return np.angle(np.exp(1j * a))


def phase_sigma(snr_db: np.ndarray) -> np.ndarray:
    """Standard deviation (rad) of a peak's phase at its SNR (peak power over the mean
    noise power of a bin): the noise's component across the phasor, 1 / sqrt(2 SNR)."""
    return 1.0 / np.sqrt(2.0 * 10 ** (np.asarray(snr_db, np.float64) / 10))


def displacement(t_r: np.ndarray, t_f: np.ndarray, phasor_r: np.ndarray, phasor_f: np.ndarray,
                 snr_r: np.ndarray, snr_f: np.ndarray, distance: np.ndarray, velocity: np.ndarray,
                 ok: np.ndarray, rad_per_m: float, distance_u: np.ndarray | None = None,
                 moments: tuple[float, float] = (0.0, 0.0), bias_mps: float = 0.0, curved: bool = False
                 ) -> Displacement:
    """The displacement of every pair (see the module's text).

    Parameters
    ----------
    t_r, t_f : (P,) centre times (s) of each pair's rising and falling half-sweep.
    phasor_r, phasor_f : (P,) the beat's phasor at their peaks (stages.phase; NaN: none):
        its angle the phase, its magnitude the echo's amplitude.
    snr_r, snr_f : (P,) their SNR (dB).
    distance, velocity : (P,) the pairs' distance (m) and velocity (m/s).
    distance_u : (P,) the distances' expanded uncertainty (m, k = 2; None: their scatter
        alone): a later stretch's reference carries it (its systematic part, a Doppler or
        acceleration bias, does not average out over the stretch).
    ok : (P,) pairs whose distance is verified.
    rad_per_m : the phase's rate with distance (stages.phase.radians_per_metre).
    moments : (m, s2) of the rising direction (stages.phase.centre_moments). An
        acceleration a moves the mean of the directions by a (h^2 / 2 + s2 - h m) from
        the pair's centre, taken off: h^2 / 2 as the directions lie at t_c -+ h, s2 as
        the de-chirp is linear in time, - h m as each direction is de-chirped at the
        pair's velocity, -+ a h off its own (the falling one's m is -m). 6.4e-11 s^2:
        23 nm at a take-off's 360 m/s^2, 2.5 nm for 1 um at 1 kHz. a is the velocities'
        own derivative between neighbours (a smoothed one misses a vibration's).
    bias_mps : how far (m/s) the velocities may share a bias (the sync delay's expanded
        uncertainty in velocity): the steps' mean residual (over BIAS_PAIRS) is taken
        off the prediction up to this, what is left of a larger one breaks the stretch.
        A bias B a step is taken for a turn less (B - 2 pi) where |B - 2 pi| is within
        this plus SLIP_RAD: none is taken where this exceeds BIAS_RAD.
    curved : the velocities curve within a few pairs (a vibration's, fmcw_cl.motion.FAST):
        the steps are predicted by cubics through four of them (`_cubic_steps`), else by
        trapezoids, whose noise is less (0.26 against 0.31 rad rms a step on a lab's
        static target at 0.3 m, whose velocities scatter by 0.9 mm/s).
    """
    n = distance.size
    phase_r, phase_f = np.angle(phasor_r), np.angle(phasor_f)
    none = Displacement.none(n)
    metres, valid, u, stretch = none.metres, none.valid, none.uncertainty_m, none.stretch
    use = np.flatnonzero(ok & np.isfinite(phase_r) & np.isfinite(phase_f) & np.isfinite(velocity)
                         & np.isfinite(distance))
    if use.size < MIN_PAIRS:
        return none
    for checks_left in range(JERK_PASSES, -1, -1):      # the last unwrapping is not checked again
        x, incs, starts, ends = _unwrapped(use, t_r, t_f, phase_r, phase_f, velocity, moments, rad_per_m,
                                           bias_mps, curved)
        bad = _jerked(x, 0.5 * (t_r[use] + t_f[use]), starts, ends, rad_per_m) if checks_left else None
        if bad is None or not bad.any():
            break
        use = use[~bad]
        if use.size < MIN_PAIRS:
            return none
    sig = phase_sigma(np.stack([snr_r[use], snr_f[use]]))
    sig_pair = 0.5 * np.sqrt(sig[0] ** 2 + sig[1] ** 2) / rad_per_m       # one pair's phase noise (m)
    # the directions' disagreement from step to step, less its mean of three (a
    # vibration's own share): -(e[k+1] - 3 e[k] + 3 e[k-1] - e[k-2]) / 3 of the
    # directions' difference e, whose variance is 4 pair variances: 80/9 of a pair's
    step = _less_mean3(incs[1] - incs[0])
    seen = np.concatenate([[np.nan], _local_scatter(step)]) * 3.0 / np.sqrt(80.0)
    kept = [(a, b) for a, b in zip(starts, ends, strict=True) if b - a >= MIN_PAIRS]
    level = 0.5 * np.log(np.abs(phasor_r[use] * phasor_f[use]))       # ln of the amplitudes' mean
    scintillating = sum(_scintillates(level[a:b]) for a, b in kept)
    if scintillating:       # the surface's speckle decorrelates: no stretch's phase is a displacement
        kept = []
    if not kept:
        return replace(none, scintillating=scintillating)
    sig_pair = np.fmax(np.fmax(sig_pair, seen), _rough(x, starts, ends))
    d = distance[use]
    ref_offset, ref_u = None, 0.0
    sd = np.zeros(use.size) if distance_u is None else np.nan_to_num(distance_u[use]) / COVERAGE
    a0 = kept[0][0]
    zero = slice(a0, a0 + ZERO_PAIRS)
    x[a0:kept[0][1]] -= np.mean(x[zero])
    zero_sig = float(np.sqrt(np.mean(sig_pair[zero] ** 2) / sig_pair[zero].size))
    for s_id, (a, b) in enumerate(kept):
        rest = d[a:b] - d[a0] - x[a:b]
        offset, off_u = _reference(rest)
        off_u = max(off_u, median(sd[a:b]))
        if ref_offset is None:
            ref_offset, ref_u = offset, off_u
            shift, shift_u = 0.0, zero_sig
        else:   # its own zero's noise is in its offset: the peaks' reference stands for it
            shift, shift_u = offset - ref_offset, np.hypot(off_u, ref_u)
        good = _checked(rest - offset, d[a:b] - d[a], rad_per_m, COVERAGE * sd[a:b])
        idx = use[a:b]
        metres[idx] = x[a:b] + shift
        valid[idx] = good
        stretch[idx] = np.where(good, s_id, -1)
        u[idx] = COVERAGE * np.sqrt(sig_pair[a:b] ** 2 + shift_u ** 2)
    metres[~valid] = np.nan
    u[~valid] = np.nan
    return Displacement(metres, valid, u, stretch, scintillating)


def _unwrapped(use, t_r, t_f, phase_r, phase_f, velocity, moments, rad_per_m, bias_mps=0.0, curved=False):
    """The phase of the pairs `use` unwrapped along each direction (the steps the
    velocities predict, their residuals wrapped), the stretches' starts and ends (in
    `use`), and the pairs' displacement within their stretch (m, 0 at its start; the
    acceleration's share taken off, `displacement`'s `moments`)."""
    t_mid = 0.5 * (t_r[use] + t_f[use])
    steps = _cubic_steps if curved else _trapezoids
    preds = [steps(use, t, t_mid, velocity) for t in (t_r, t_f)]
    resid = [_wrap(np.diff(ph[use]) - rad_per_m * pred)
             for ph, pred in zip((phase_r, phase_f), preds, strict=True)]
    # the velocities' common bias (a sync delay's error: 2 mm/s is 0.8 rad a step) as far
    # as `bias_mps` allows: what is left of it beyond that breaks the stretch
    limit = rad_per_m * bias_mps * float(np.median(np.diff(t_mid))) if use.size > 1 else 0.0
    limit = limit if limit <= BIAS_RAD else 0.0
    taken = np.clip(_running_angle(np.exp(1j * resid[0]) + np.exp(1j * resid[1])), -limit, limit)
    resid = [_wrap(r - taken) for r in resid]
    incs = [pred + (taken + r) / rad_per_m for pred, r in zip(preds, resid, strict=True)]
    breaks = ((np.diff(use) > GAP_PAIRS + 1) | (np.abs(resid[0]) > SLIP_RAD) | (np.abs(resid[1]) > SLIP_RAD)
              | (np.abs(resid[1] - resid[0]) > SLIP_RAD))
    starts = np.concatenate([[0], np.flatnonzero(breaks) + 1])
    ends = np.concatenate([starts[1:], [use.size]])
    h = 0.5 * (t_f[use] - t_r[use])
    mean_s, half_square_s2 = moments
    bent = np.gradient(velocity[use], t_mid) * (0.5 * h * h + half_square_s2 - h * mean_s)
    x = np.zeros(use.size)
    # x[a + 1:b] of each stretch [a, b): the running sums of its steps a .. b - 2
    after = ragged(starts + 1, ends)[1]
    x[after] = 0.5 * (segment_cumsum(incs[0], starts, ends - 1) + segment_cumsum(incs[1], starts, ends - 1))
    x -= bent - np.repeat(bent[starts], ends - starts)
    return x, incs, starts, ends


def _trapezoids(use: np.ndarray, t: np.ndarray, t_mid: np.ndarray, velocity: np.ndarray) -> np.ndarray:
    """The motion (m) between consecutive half-sweeps of a direction (at times `t[use]`)
    the pairs' velocities predict: trapezoids of the velocity interpolated to the
    half-sweep's own time (a pair's is at its centre `t_mid`, 12.5 us away: at a
    take-off's 300 m/s^2 that alone moves a step by 1.5 rad)."""
    v = np.interp(t[use], t_mid, velocity[use])
    return 0.5 * (v[:-1] + v[1:]) * np.diff(t[use])


def _cubic_steps(use: np.ndarray, t: np.ndarray, t_mid: np.ndarray, velocity: np.ndarray) -> np.ndarray:
    """`_trapezoids`, curved: the integral of the cubic through the four velocities
    about each step (at their centres `t_mid`; three or two where a piece between gaps
    of more than GAP_PAIRS is that short). Trapezoids of a 50 um, 1 kHz vibration's
    velocity miss its steps by up to 2.8 rad. Local, as trapezoids: a wrong velocity
    moves the four steps about it (a spline's would ring through the stretch)."""
    out = np.zeros(use.size - 1)
    v = velocity[use]
    cuts = np.concatenate([[0], np.flatnonzero(np.diff(use) > GAP_PAIRS + 1) + 1, [use.size]])
    for a, b in zip(cuts[:-1], cuts[1:], strict=True):
        n = b - a
        if n < 2:
            continue
        order = min(4, n)
        k = np.arange(a, b - 1)                       # the steps k -> k + 1 of this piece
        first = np.clip(k - (order - 1) // 2, a, b - order)
        idx = first[:, None] + np.arange(order)       # the velocities about each step
        # about the step's centre, in steps: the cubic's powers of comparable size
        centre, h = 0.5 * (t_mid[k] + t_mid[k + 1]), t_mid[k + 1] - t_mid[k]
        x = (t_mid[idx] - centre[:, None]) / h[:, None]
        coef = np.linalg.solve(x[:, :, None] ** np.arange(order), v[idx][:, :, None])[:, :, 0]   # sum c_j x^j
        lo, hi = ((t[use[k + s]] - centre) / h for s in (0, 1))
        powers = np.arange(1, order + 1)
        out[a:b - 1] = h * np.sum(coef / powers * (hi[:, None] ** powers - lo[:, None] ** powers), axis=1)
    return out


def _running_angle(z: np.ndarray) -> np.ndarray:
    """The angle of the sum of `z` over BIAS_PAIRS values about each (fewer at the ends)."""
    if z.size == 0:
        return np.zeros(0)
    size = min(BIAS_PAIRS, z.size)
    return np.angle(np.convolve(z, np.ones(size), mode="same"))


def _jerked(x, t, starts, ends, rad_per_m) -> np.ndarray:
    """The pairs (of `x`, at times `t`) in a window of four of a stretch whose third
    difference leaves the running median of three of them by more than a quarter
    wavelength: a whole turn taken wrong at one of them (one velocity wrong by a turn's
    worth, both directions alike, which their residuals cannot show) is a spike of
    (1, -3, 3, -1) or (1, -2, 1) half wavelengths. Real motion's third difference is
    jerk x dt^3 (31 nm for 1 um at 1 kHz, 1.5 um for 50 um) and smooth: the median
    takes it off to (1 - cos(2 pi f dt)) of itself, 75 nm at 50 um."""
    bad = np.zeros(x.size, bool)
    long = np.flatnonzero(ends - starts >= 4)
    if not long.size:
        return bad
    d = x
    for k in (1, 2, 3):                       # divided differences: exact for any spacing
        d = np.diff(d) / (t[k:] - t[:-k])
    third = 6.0 * d * ((t[3:] - t[:-3]) / 3.0) ** 3
    # each stretch's thirds (those of four of its own pairs), filtered within it
    lo, hi = starts[long], ends[long] - 3
    which, k = ragged(lo, hi)
    end = np.cumsum(hi - lo)
    first, last = (end - (hi - lo))[which], (end - 1)[which]      # each third's stretch, in `own`
    own = third[k]
    hit = k[np.abs(own - running_median(own, 3, (first, last))) > np.pi / rad_per_m]
    for s in range(4):
        bad[hit + s] = True
    return bad


def _scintillates(level: np.ndarray) -> bool:
    """Whether a stretch's echo scintillates: the median change of its amplitude over
    SCINT_PAIRS pairs (1.6 ms; `level`: ln of the phasors' magnitude, a running median
    over SCINT_PAIRS + 1 pairs against the noise) exceeds SCINT_LN. A surface whose
    speckle decorrelates (a diffuse target turning, or moving across the beam) turns
    the echo's phase as it changes its amplitude (for a circular Gaussian field the two
    change alike): that phase is no displacement. Measured: 0.25-0.75 under 2-3 ms
    speckle, at most 0.016 without (static, creep, rail, jump, a wall, a lab's SNR).
    The SNR would not do: at 40 dB its floor holds the echo's own phase-noise skirt."""
    if level.size < 2 * SCINT_PAIRS + 1:
        return False
    smooth = running_median(level, SCINT_PAIRS + 1)
    return median(np.abs(smooth[SCINT_PAIRS:] - smooth[:-SCINT_PAIRS])) > SCINT_LN


def _rough(x: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """A pair's noise (m) from the displacement itself: the local scatter of its third
    differences less their mean of three (a vibration's own share; -1/3 of a fifth
    difference, into which a white error enters 252/9 times its variance) within each
    stretch / sqrt(28); what both directions share (a de-chirp's, the sync's) shows here
    and not in their disagreement. NaN where a stretch is too short."""
    out = np.full(x.size, np.nan)
    for a, b in zip(starts, ends, strict=True):
        if b - a >= 8:
            third = _local_scatter(_less_mean3(np.diff(x[a:b], 3))) / np.sqrt(28.0)
            out[a + 1:b - 2] = third
            out[a], out[b - 2:b] = third[0], third[-1]
    return out


def _less_mean3(x: np.ndarray) -> np.ndarray:
    """x less the mean of each value and its two neighbours (the ends: their
    neighbour's): what varies from one value to the next, a smooth course taken off."""
    y = np.array(x, np.float64)
    if y.size >= 3:
        y[1:-1] = x[1:-1] - (x[:-2] + x[1:-1] + x[2:]) / 3.0
        y[0], y[-1] = y[1], y[-2]
    return y


def _local_scatter(x: np.ndarray) -> np.ndarray:
    """A robust standard deviation of `x` about each point, over CHECK_PAIRS of them
    (1.4826 x the running median of |x - its running median|)."""
    if x.size == 0:
        return x
    size = min(CHECK_PAIRS + 1, x.size - 1 + x.size % 2)        # odd
    dev = np.abs(x - running_median(x, size))
    return 1.4826 * running_median(dev, size)


def _reference(rest: np.ndarray) -> tuple[float, float]:
    """The peaks' distance less the phase's displacement over a stretch: its mean and the
    mean's standard error from BLOCKS blocks (the peaks' errors correlate over pairs)."""
    blocks = [b.mean() for b in np.array_split(rest, min(BLOCKS, rest.size)) if b.size]
    mean = float(np.mean(rest))
    if len(blocks) < 2:
        return mean, float(np.std(rest))
    return mean, float(np.std(blocks, ddof=1) / np.sqrt(len(blocks)))


def _checked(rest: np.ndarray, travel: np.ndarray, rad_per_m: float, allowed: np.ndarray) -> np.ndarray:
    """The pairs of a stretch where the peaks' distance agrees with the phase (`rest`:
    their difference less its mean; `travel`: the distance travelled, m): its running
    mean over CHECK_PAIRS, less a line in `travel` (the distance scale's error of the
    G(I) table, ppm, grows with the travel), within CHECK_SIGMAS of its scatter plus a
    quarter wavelength plus the distance's own uncertainty `allowed` (m, k = 2: its
    biases in motion do not average out)."""
    m = rest.size
    if m < 2 * CHECK_PAIRS:
        return np.ones(m, bool)
    design = np.stack([np.ones(m), travel], axis=1)
    coef, *_ = np.linalg.lstsq(design, rest, rcond=None)
    left = rest - design @ coef
    kernel = np.ones(CHECK_PAIRS) / CHECK_PAIRS
    smooth = np.convolve(left, kernel, mode="same")
    scatter = 1.4826 * median(np.abs(left - median(left)))
    limit = CHECK_SIGMAS * scatter / np.sqrt(CHECK_PAIRS) + np.pi / rad_per_m + allowed
    return np.abs(smooth) <= limit
