"""The time scale of the target's motion that a conversion follows: a leg's, smooth over
a millisecond, or a vibration's, whose velocity reverses within one.

The tracker's continuity prior is the running median of its pairs' velocities over
2 reach + 1 pairs (stages.pairing); the acceleration and the velocity's check against
the distances' slope are Savitzky-Golay fits over windows of pairs; a trial conversion's
distances are freed of the acceleration's bias over a wider one (refine). A leg's
windows (`SMOOTH`, 0.85-3 ms) average out noise and outliers. A vibration of 50 um at
1 kHz (0.31 m/s, 1970 m/s^2, 20 pairs a period) reverses within them: the median of
17 pairs misses its velocity by 0.2 m/s, so the de-chirp never settles (no valid
pair), and the acceleration's bias of the distance (0.31 um per m/s^2: 0.6 mm, against
a 50 um motion) is left in, which moves the refined sync delay by samples. `FAST`
windows follow it. The windows are chosen once per capture (`choose`), from the
velocities of its first trial conversion: only what the measurement itself shows
(the velocities leave the long median far more than the short one) makes them short.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import numeric, uncertainty
from .stages import groups, kinematics

FAST_MPS = 0.02      # a velocity this far from the running median: not followed (4 % of a de-chirp off)
FAST_SHARE = 0.25    # SMOOTH's median misses this share of the velocities ...
FAST_RATIO = 3.0     # ... and this many times the share FAST's misses: the motion reverses within it


@dataclass(frozen=True)
class Motion:
    """The windows (pairs) a conversion fits its pairs over."""

    name: str
    reach: int           # the tracker's velocity median: half-width (stages.groups.NEIGHBOURS)
    window: int          # the acceleration's Savitzky-Golay fit (stages.kinematics.WINDOW_PAIRS)
    slope: int           # the distances' slope the velocity is checked against (uncertainty.SLOPE_PAIRS)
    bias: int            # a trial conversion's acceleration, for its distances' bias (refine.pairs_of:
                         # a leg's over 3 ms, as a trial's velocities may be noise)
    hold: bool           # that acceleration held near a run's ends (kinematics.held_acceleration)
    curved: bool         # the phase's steps predicted by cubics, not trapezoids (fmcw_cl.displacement)


SMOOTH = Motion("smooth", groups.NEIGHBOURS, kinematics.WINDOW_PAIRS, uncertainty.SLOPE_PAIRS, bias=61,
                hold=True, curved=False)
FAST = Motion("fast", reach=2, window=5, slope=7, bias=5, hold=False, curved=True)


def reverses(velocities: list[np.ndarray]) -> tuple[float, float]:
    """The share of the velocities (m/s; each array a stretch's heard pairs, in time)
    more than FAST_MPS from their running median over SMOOTH's reach, and over FAST's.
    A median follows a monotonic course exactly (a take-off, each flank of a vibration):
    it misses where the velocity turns within its reach, and where noise or another
    echo moves a pair (both medians alike)."""
    long, short = [], []
    for v in velocities:
        if v.size > 2 * SMOOTH.reach:
            long.append(np.abs(v - numeric.running_median(v, 2 * SMOOTH.reach + 1)) > FAST_MPS)
            short.append(np.abs(v - numeric.running_median(v, 2 * FAST.reach + 1)) > FAST_MPS)
    if not long:
        return 0.0, 0.0
    return float(np.mean(np.concatenate(long))), float(np.mean(np.concatenate(short)))


def choose(velocities: list[np.ndarray]) -> Motion:
    """FAST where SMOOTH's median misses FAST_SHARE of the velocities (`reverses`) and
    FAST_RATIO times the share FAST's misses; else SMOOTH. Noise and wrong echoes move
    both alike (at 30 mm/s of noise: 0.50 against 0.40); a leg's take-off, landing or
    rest are followed by both."""
    long, short = reverses(velocities)
    return FAST if long >= FAST_SHARE and long >= FAST_RATIO * short else SMOOTH
