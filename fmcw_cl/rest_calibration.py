"""The chirp calibrated on a capture's own rest, where the G(I) table no longer holds.

When the tuning check finds peaks far wider than the window's own (a laser whose thermal
tuning lags the current), a stretch where the target rests (a foot before a jump) is a
calibration target (`calibration.chirp_of`), but at a distance that the smeared peaks
give only roughly. The chirp so measured has the right *shape* (the resampling
instants) and a scale (its bandwidth) off by the rough distance's error: every
distance then reads too far or too near by that factor.

The target's motion sets the scale. The Doppler velocity, 2 v / lambda with lambda from
the table's mean frequency, does not depend on the bandwidth (the apparent shift per m/s,
`DopplerModel.k_*`, scales with the distances it is read from); the distance does. So
over the runs where the target moves, the distance travelled over the integrated
velocity is the chirp's scale (regressed over whole runs, the longest baselines);
segments of SEGMENT_PAIRS pairs regressed alike give, from their spread, the scale's
standard uncertainty, which the distance scale then states.

The sync delay stays that of the first conversion: the chirp is measured against
half-sweeps at that delay, and at rest the directions agree by construction. A capture
is left uncalibrated (its pairs `uncalibrated`, `rest_calibration` saying why) where it
holds no rest of REST_PERIODS periods, does not move MIN_TRAVEL_M, its rest is too noisy
to calibrate on, or its motion fixes the scale no better than SCALE_SIGMA_MAX.
"""

from __future__ import annotations

import bisect
from dataclasses import replace

import numpy as np

from .calibration import chirp_of
from .capture import Capture
from .chirp import Chirp, Direction
from .chunks import capture_parts
from .errors import CaptureError
from .numeric import runs, travelled
from .plan import OWN_REST, Plan
from .processor import ChunkProcessor
from .refine import pairs_of
from .track import Track

REST_BLOCK = 50          # pairs whose median distance is one step of the rest
REST_M = 0.3e-3          # a rest's blocks stay this close to its median distance (m)
REST_MPS = 0.02          # ... and velocity (m/s: 0.05 mm over a block)
REST_HEARD = 6          # pairs a block's medians need (fewer: a silent block)
REST_GAP = 2            # silent blocks in a row that a rest goes on through (5 ms)
REST_TRIM = 4            # blocks cut off a rest's ends that border motion (a take-off's onset
#                          reads 0.003-0.05 m/s over the 10 ms before the tolerances see it)
# ... times the first of these that finds a rest of REST_PERIODS_WANTED, else the first
# that finds one of REST_PERIODS: at a lab's SNR an uncalibrated chirp's block medians
# wander by 0.7 mm and 0.03 m/s at rest, and a chirp measured on 250 periods there left
# the jump a 0.17 mm bias, on 900 none
REST_LOOSEN = (1, 2, 3, 4)
REST_PERIODS = 200       # the shortest rest calibrated on
REST_PERIODS_WANTED = 600
MIN_TRAVEL_M = 0.02      # a target that moves less cannot set the scale
SEGMENT_PAIRS = 200      # pairs of a segment of the scale's regression
SCALE_SIGMA_MAX = 1e-3   # the scale must be known this well (relative, 1 sigma)


class _GrowingMedian:
    """np.median of a growing set of numbers (NaN once one is NaN), each added in
    O(log n) comparisons: a rest of a minute's capture is 24 000 blocks long."""

    def __init__(self, first: float) -> None:
        self.values: list[float] = []
        self.nan = False
        self.add(first)

    def add(self, value: float) -> None:
        if np.isnan(value):
            self.nan = True
        else:
            bisect.insort(self.values, float(value))

    def median(self) -> float:
        n = len(self.values)
        if self.nan:
            return float("nan")
        return self.values[n // 2] if n % 2 else (self.values[n // 2 - 1] + self.values[n // 2]) / 2


def rest_stretch(distance_m: np.ndarray, velocity_mps: np.ndarray, block: int = REST_BLOCK,
                 tol: float = REST_M, tol_v: float = REST_MPS, trim: int = REST_TRIM,
                 gap: int = REST_GAP) -> tuple[int, int]:
    """Pairs [i, j) of the longest rest ((0, 0) if none).

    A rest is a run of consecutive blocks of `block` pairs whose median distance stays
    within `tol` (m), and median velocity within `tol_v` (m/s) but for single blocks, of
    the run's median so far: the velocity sees a take-off's first tenths of a millimetre,
    which the distance's noise hides (an uncalibrated chirp leaves the velocity biased
    but steady at rest, hence relative). `trim` blocks are cut off each end that borders
    motion, where the motion's onset is still below both tolerances: a foot's Doppler
    bends the chirp measured there (0.02 m/s: 0.65 cycles over a half-sweep, 0.9 % of
    the beat's at 0.07 m). A block of fewer than REST_HEARD pairs is silent: up to `gap`
    of them in a row are part of a rest that resumes after them; more end it. At a
    lab's SNR a chirp lagging 5 us leaves 14 % of the jump's pairs, 7 a block: 6 of 10
    such captures found no rest while a quarter of a block was needed and one silent
    block ended a rest."""
    nb = distance_m.size // block
    med = np.full((2, nb), np.nan)
    for row, x in enumerate((distance_m, velocity_mps)):
        blocks = x[:nb * block].reshape(nb, block)
        heard = np.isfinite(blocks).sum(axis=1) >= REST_HEARD
        med[row, heard] = np.nanmedian(blocks[heard], axis=1)

    def within(m: int, ref: np.ndarray) -> np.ndarray:      # False for NaN
        return np.abs(med[:, m] - ref) < [tol, tol_v]

    silent = ~np.all(np.isfinite(med), axis=0)
    best, k = (0, 0), 0
    while k < nb:
        m = k + 1
        run = [_GrowingMedian(med[0, k]), _GrowingMedian(med[1, k])]
        while m < nb:
            # up to `gap` silent blocks go on with the rest where it resumes after them
            n = m
            while n < nb and n - m < gap and silent[n]:
                n += 1
            if n >= nb or silent[n]:
                break
            ref = np.array([r.median() for r in run])
            ok = within(n, ref)
            # the velocity must leave for two blocks running: an uncalibrated chirp's
            # velocity wanders by about the tolerance from block to block
            if not (ok[0] and (ok[1] or (n + 1 < nb and within(n + 1, ref)[1]))):
                break
            for r, value in zip(run, med[:, n], strict=True):
                r.add(value)
            m = n + 1
        if np.all(np.isfinite(med[:, k])):
            a, b = k + trim * (k > 0), m - trim * (m < nb)
            if b - a > best[1] - best[0]:
                best = (a, b)
        k = m
    return best[0] * block, best[1] * block


def choose_rest(distance_m: np.ndarray, velocity_mps: np.ndarray) -> tuple[int, int, float] | None:
    """The rest calibrated on: pairs [i, j) and the factor on the tolerances (the
    tightest of REST_LOOSEN that finds REST_PERIODS_WANTED, else REST_PERIODS), or None."""
    found = [(*rest_stretch(distance_m, velocity_mps, tol=REST_M * loosen, tol_v=REST_MPS * loosen), loosen)
             for loosen in REST_LOOSEN]
    usable = ([f for f in found if f[1] - f[0] >= REST_PERIODS_WANTED]
              or [f for f in found if f[1] - f[0] >= REST_PERIODS])
    return usable[0] if usable else None


def kinematic_scale(t: np.ndarray, d: np.ndarray, v: np.ndarray, ok: np.ndarray,
                    segment: int = SEGMENT_PAIRS) -> tuple[float, float]:
    """The distance scale against the Doppler velocity's, and its standard uncertainty.

    The scale is the least-squares slope of distance (m) on travelled distance
    (integrated velocity, m) over each valid run of `ok`, pooled: a run's whole travel
    is the longest baseline. Its uncertainty is that of the same slope pooled from
    segments of `segment` pairs, from their scatter. (NaN, NaN) with fewer than 3
    segments."""
    def moments(pieces):
        num, den = [], []
        for a, b in pieces:
            x = travelled(t[a:b], v[a:b])
            x, y = x - x.mean(), d[a:b] - d[a:b].mean()
            num.append(float(x @ y))
            den.append(float(x @ x))
        return np.array(num), np.array(den)

    spans = [(int(i), int(j)) for i, j in runs(ok) if j - i >= segment // 2]
    pieces = [(a, min(j, a + segment)) for i, j in spans for a in range(i, j - segment // 2, segment)]
    num, den = moments(pieces)
    moved = den > 0
    if moved.sum() < 3:
        return float("nan"), float("nan")
    slopes = num[moved] / den[moved]
    pooled = num.sum() / den.sum()
    # the pooled segments' error from their scatter, weighted as they are pooled
    sigma = np.sqrt(np.sum(den[moved] * (slopes - pooled) ** 2) / den.sum() / (moved.sum() - 1))
    num, den = moments(spans)
    return float(num.sum() / den.sum()), float(sigma)


def scaled(chirp: Chirp, factor: float) -> Chirp:
    """`chirp` with its optical frequencies (and so its bandwidth) times `factor`."""
    return Chirp(Direction(chirp.rising.s, chirp.rising.nu_hz * factor),
                 Direction(chirp.falling.s, chirp.falling.nu_hz * factor), chirp.attrs)


def calibrate(cap: Capture, plan: Plan, track: Track, processor: ChunkProcessor) -> tuple[Plan | None, dict]:
    """The plan resampled on a chirp calibrated on the capture's own rest (`track`: its
    first conversion with the G(I) table), or None where none can be made; and the
    track attributes that say which (`rest_calibration`: "made" or why not)."""
    info = cap.info
    rest = choose_rest(track.distance_m, track.velocity_mps)
    if rest is None:
        return None, {"rest_calibration": f"no rest of {REST_PERIODS} periods to calibrate on"}
    i, j, loosen = rest
    moved = track.distance_m[np.isfinite(track.distance_m)]
    if np.ptp(moved) < MIN_TRAVEL_M:
        return None, {"rest_calibration": f"the target moves less than {MIN_TRAVEL_M * 1e3:g} mm: nothing "
                                          "sets the distance scale"}
    rough = float(np.nanmedian(track.distance_m[i:j]))
    half = info.samples_per_period / 2
    start = max(0, int(track.time_s[i] * info.sample_rate_hz - half))
    stop = min(info.samples, int(track.time_s[j - 1] * info.sample_rate_hz + half))
    try:
        shape = chirp_of(cap, plan, rough, start, stop)
    except CaptureError as exc:
        return None, {"rest_calibration": f"its rest cannot be calibrated on: {exc.problem}"}
    # the scale from the motion, on a trial conversion without the survey of hidden echoes
    trial = replace(plan.with_chirp(shape, OWN_REST), survey=False)
    parts = capture_parts(cap, trial, processor)
    k, sigma = kinematic_scale(*pairs_of(parts, trial.model, trial.motion))
    if not sigma <= SCALE_SIGMA_MAX:
        return None, {"rest_calibration": f"its motion sets the distance scale to +-{sigma * 1e6:.0f} ppm "
                                          f"only (at most {SCALE_SIGMA_MAX * 1e6:.0f})"}
    return plan.with_chirp(scaled(shape, k), OWN_REST, sigma), {
        "rest_calibration": "made",
        "rest_calibration_span_s": np.array([track.time_s[i], track.time_s[j - 1]]),
        "rest_calibration_tolerance": np.array([REST_M * loosen, REST_MPS * loosen]),
        "rest_calibration_periods": int(shape.attrs["periods_used"]),
        "rest_calibration_distance_m": rough / k,
        "rest_calibration_scale": k,
        "rest_calibration_residual_phase_rad": float(shape.attrs["residual_phase_rad"]),
    }
