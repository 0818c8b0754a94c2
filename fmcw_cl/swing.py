"""A target's Doppler swing: how far its tracked peaks move with its velocity.

A half-sweep's plain peak lies at the pair's distance plus k v (its direction's Doppler
shift per m/s, fitted over the capture: `shift_per_mps`); a target that vibrates or
creeps to rest swings its peaks by up to `doppler_reach`, and its mean spectra's peaks
within that reach are its own (fmcw_cl.target, fmcw_cl.fixed_echoes).
"""

from __future__ import annotations

import numpy as np

from . import echoes
from .numeric import drift, nearest
from .stages.verification import DRIFT_MPS

SWING_FIT = 0.9       # a target swings where its pairs' Doppler shifts explain this share of its plain
                      # peaks' offsets (their power) ...
SMEAR_M = 0.001       # ... and reach a resolution cell; the mean spectra's peaks within its reach plus
                      # this are its own (a vibration's peaks swing +-9 mm at 0.31 m/s, +-1.8 at 0.06)
REST_MPS = 0.02       # verified pairs this slow ...
REST_PAIRS = 40       # ... this many in a row (2 ms at 50 us) rest: an echo, no swing's image
REST_APART_M = 0.002  # a rest this far from the fixed echo, where the mean spectra hold another echo:
                      # that echo (a pane's back surface 6 mm behind the window the tracker held)


def doppler_reach(e: echoes.Echoes, time_s, distance_m, velocity_mps, valid) -> float:
    """How far (m) the tracked peaks of the plain pass (`e.tracked`) swing from their
    verified pair's distance with its velocity: in each direction the peaks' offset is
    fitted as a multiple of the pair's velocity (their Doppler shift, opposite in the
    two), and where that explains SWING_FIT of the offsets' power in both, 99 % of the
    fitted shifts lie within the reach; else 0 (a target at rest: noise; noise at full
    scale: the tracked peaks anywhere, not with the velocity). A vibration of 50 um at
    1 kHz: 9 mm, its mean spectra's peaks at the ends of its swing in each direction."""
    held, offset, v = peak_offsets(e, time_s, distance_m, velocity_mps, valid)
    rising = e.rising[held]
    reach = 0.0
    for way in (rising, ~rising):
        o, u = offset[way], v[way]
        power, weight = float(np.sum(o * o)), float(np.sum(u * u))
        if o.size < 2 or power == 0.0 or weight == 0.0:
            return 0.0
        shift = shift_per_mps(o, u) * u                      # the fitted Doppler shifts (m)
        if 1.0 - float(np.sum((o - shift) ** 2)) / power < SWING_FIT:
            return 0.0
        reach = max(reach, float(np.percentile(np.abs(shift), 99)))
    return reach


def peak_offsets(e: echoes.Echoes, time_s, distance_m, velocity_mps, valid
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The tracked detections of the echo table that lie within a period of a verified
    pair (their indices), their offsets from that pair's distance (m) and its velocity
    (m/s); all empty with under two verified pairs."""
    ok = np.flatnonzero(np.asarray(valid, bool) & np.isfinite(distance_m) & np.isfinite(velocity_mps))
    held = np.flatnonzero(e.tracked)
    if ok.size < 2 or held.size == 0:
        return np.zeros(0, np.int64), np.zeros(0), np.zeros(0)
    at = ok[nearest(time_s[ok], e.time_s[held])]
    near = np.abs(time_s[at] - e.time_s[held]) <= np.median(np.diff(time_s))
    held, at = held[near], at[near]
    return held, e.distance_m[held] - distance_m[at], velocity_mps[at]


def shift_per_mps(offset: np.ndarray, velocity: np.ndarray) -> float:
    """The least-squares Doppler shift per m/s (m) of one direction's `offset`s (m) at
    their pairs' `velocity` (m/s); 0 where every velocity is 0."""
    weight = float(np.sum(velocity**2))
    return float(np.sum(offset * velocity)) / weight if weight > 0 else 0.0


def swinging(e: echoes.Echoes, time_s, distance_m, velocity_mps, valid) -> bool:
    """Whether the verified pairs are one echo in motion though no echo of the tables
    stays or travels: their tracked plain peaks swing with their velocities
    (`doppler_reach` >= SMEAR_M: noise cannot) and their distances follow those
    velocities (numeric.drift within pairing.DRIFT_MPS: a wall at rest read at 0.35 m/s
    under a delay 77 samples off has plain peaks offset with its constant velocity, but
    its distances stand still)."""
    ok = np.asarray(valid, bool) & np.isfinite(distance_m) & np.isfinite(velocity_mps)
    if ok.sum() < 3 or doppler_reach(e, time_s, distance_m, velocity_mps, valid) < SMEAR_M:
        return False
    return abs(drift(time_s[ok], distance_m[ok], velocity_mps[ok])[0]) <= DRIFT_MPS


def rests(time_s, distance_m, velocity_mps, valid) -> np.ndarray:
    """The distances (m) where the verified pairs rest: each run of at least REST_PAIRS
    consecutive verified pairs slower than REST_MPS, at its median. A Doppler image of
    a swing is never at rest (it exists by the velocity); a run at rest is an echo."""
    ok = np.asarray(valid, bool) & np.isfinite(distance_m) & (np.abs(np.nan_to_num(velocity_mps, nan=np.inf))
                                                              < REST_MPS)
    edges = np.flatnonzero(np.diff(np.r_[0, ok.astype(np.int8), 0]))
    return np.array([float(np.median(distance_m[a:b])) for a, b in zip(edges[::2], edges[1::2], strict=True)
                     if b - a >= REST_PAIRS])
