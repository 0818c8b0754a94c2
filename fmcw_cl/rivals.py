"""Rivals of a lone fixed echo: what else a conversion's tables hold beside it.

With no moving echo and one fixed echo, that echo is the target (fmcw_cl.target)
unless OTHERS_SHARE of the half-sweeps hold other echoes (`others_share`), the mean
spectra hold another echo (`besides`), the two directions put it at two distances
(`directions_apart`: the sync delay or the chirp off), or the verified pairs lie elsewhere
(`elsewhere`: the tracker held something the tables missed).
"""

from __future__ import annotations

import numpy as np

from . import echoes
from .fixed_echoes import APART_M, GATE_M, MOVING_MPS, OTHERS_SHARE, harmonic, in_both_directions, merged

SPLIT_M = 0.002       # a fixed echo's directions this far apart in the mean spectra: the conversion is off


def elsewhere(distance_m: np.ndarray, valid: np.ndarray, fixed_m: np.ndarray,
               still: np.ndarray | None = None) -> tuple[float, ...] | None:
    """(share, lo, hi m) of the verified pairs more than GATE_M from every fixed echo
    `fixed_m` (those no `ambiguous` verdict on the echoes covers), where they are
    OTHERS_SHARE of the verified pairs at least (None else): the tracker held another
    echo that the tables (and the second look) missed. With velocities `still` (m/s),
    only where those pairs are at rest (99 % of them slower than MOVING_MPS). A landing
    under noise at full scale passed a wall of 800 codes and rested 32 mm before it for
    18 ms: "one echo" put 507 valid pairs on the wall, up to 64 mm off; a target at rest
    between walls, 18 mm from one of 400 codes that no table found, the fixed echoes
    ambiguous: 392 valid pairs on that wall."""
    ok = np.asarray(valid, bool)
    far = ok & (np.min(np.abs(distance_m[:, None] - np.asarray(fixed_m)[None, :]), axis=1) > GATE_M)
    if not ok.any() or far.sum() < OTHERS_SHARE * ok.sum():
        return None
    if still is not None and np.percentile(np.abs(still[far]), 99) >= MOVING_MPS:
        return None
    d = distance_m[far]
    return float(far.sum() / ok.sum()), float(np.percentile(d, 1)), float(np.percentile(d, 99))


def others_share(e: echoes.Echoes, fixed_m: float, band, sweeps: int) -> float:
    """The share of the capture's `sweeps` half-sweeps whose CFAR echoes include one
    inside `band` that is not the tracked peak and lies APART_M or more from the fixed
    echo at `fixed_m`. Of all half-sweeps, not of those with an echo: a weak target's
    single half-sweeps rarely hold one (at -20 dB per sample 10 of 796, one of them a
    false alarm)."""
    inside = ((e.distance_m >= band[0]) & (e.distance_m < (band[1] or np.inf)) & ~e.tracked
              & (np.abs(e.distance_m - fixed_m) >= APART_M))
    return np.unique(e.time_s[inside]).size / sweeps if sweeps else 0.0


def besides(e: echoes.Echoes, fixed_m: float, band, unambiguous_m: float, clipped: bool = False
             ) -> list[float]:
    """The distances (m) of the other echoes that either direction's mean spectrum over
    the capture holds inside `band`, the two directions' within GATE_M as one, at their
    mean:
    - within APART_M of the fixed echo at `fixed_m`, those its power hides from the CFAR
      (echoes.masked_peaks): a second object at rest a few resolution cells away, or a
      moving target's Doppler-shifted peak in one direction;
    - the peaks (echoes.mean_peaks) more than GATE_M from it, but its harmonics
      (`harmonic`): an object at rest too weak for a half-sweep's CFAR, seen over the
      capture (at noise at full scale, a target 5.6-5.8 dB over the noise in the mean
      spectra had 7 CFAR echoes in 1996 half-sweeps, as many as the false alarms, and the
      wall seen in 28 was taken for it; in one direction only, the other's just under
      the limit), or the peaks of a blend of echoes around the fixed one (walls at 0.404
      and 0.435 m, the target at 0.416 m between). Where some pairs are `clipped`, only
      peaks of both directions within GATE_M of each other: a clipped stretch's
      distortion puts peaks 7 dB over the noise into one direction's mean spectrum or the
      other's."""
    lo, hi = band[0], band[1] or np.inf
    near = e.masked(lo, hi)
    rising, d, db = e.peaks(lo, hi)
    own = np.abs(d - fixed_m) <= GATE_M
    level = np.max(db[own]) if own.any() else -np.inf        # the fixed echo's, where a peak
    far = ~own & ~harmonic(np.r_[fixed_m, d], np.r_[level, db], unambiguous_m)[1:]
    far = [x for x, _ in in_both_directions(rising[far], d[far], db[far], 1)] if clipped else d[far]
    return merged(np.r_[near[np.abs(near - fixed_m) < APART_M], far])


def directions_apart(e: echoes.Echoes, fixed_m: float, band) -> tuple[float, float] | None:
    """(rising, falling) distances (m) of the fixed echo at `fixed_m` in the two
    directions' mean spectra over the capture (their peaks within GATE_M of it nearest
    to it) where they lie more than SPLIT_M apart: an echo at rest lies at one distance
    in both, unless the conversion is off (a sync delay 55 samples off under noise at
    full scale: a wall at 0.2325 and 0.2401 m, and the target beside it lost)."""
    rising, d, _ = e.peaks(band[0], band[1] or np.inf)
    near = np.abs(d - fixed_m) <= GATE_M
    if not (near & rising).any() or not (near & ~rising).any():
        return None
    r, f = (d[m][np.argmin(np.abs(d[m] - fixed_m))] for m in (near & rising, near & ~rising))
    return (float(r), float(f)) if abs(r - f) > SPLIT_M else None
