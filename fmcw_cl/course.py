"""A band that follows an object in time: each pair searched where its object is.

A candidate of the scene is converted in a band of its own, fixed in range; two movers
whose ranges cross share it, and the tracker holds the stronger. A course gives each
pair its own band instead: at times `t_s`, each direction's [lo, hi) in metres (a
half-sweep's plain peak lies off the distance by its Doppler shift, opposite in the two
directions), interpolated at each half-sweep's centre and rounded outwards to padded
bins, inside the plan's band. Outside the course's times a pair keeps the plan's band.
Where the course also says how fast its object moves (`v_mps`), the tracker's first
measurement of a pair is de-chirped at that velocity: a mover's plain peak smears
(6.6 dB at 1 m/s, 11 dB at 3 m/s with the paper's DFB) and, shifted by its Doppler term,
lies among a stronger object's, where the de-chirped one stands sharp at its distance.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .stages.spectrum import Search

MIN_BINS = 4        # a pair's band holds at least this many bins (the peak's parabola and a floor)


@dataclass(frozen=True, eq=False)
class Course:
    """Each direction's band (m) at times `t_s` (s, increasing): `lo_m`, `hi_m` of shape
    (2, times), row 0 the rising half-sweeps', row 1 the falling ones'; `v_mps`: the
    object's velocity (m/s) at those times, 0 where not known (None: nowhere)."""

    t_s: np.ndarray
    lo_m: np.ndarray
    hi_m: np.ndarray
    v_mps: np.ndarray | None = None

    def bands(self, t_rise: np.ndarray, t_fall: np.ndarray, search: Search, metres_per_bin: float
              ) -> np.ndarray:
        """(2, pairs, 2) int32: each pair's [lo, hi) in padded bins, in each direction at
        its half-sweep's centre `t_rise` / `t_fall` (s), within [search.lo, search.hi);
        the search's band outside the course's times."""
        out = np.empty((2, np.size(t_rise), 2), np.int32)
        for j, t in enumerate((t_rise, t_fall)):
            inside = (t >= self.t_s[0]) & (t <= self.t_s[-1])
            lo = np.interp(t, self.t_s, self.lo_m[j]) / metres_per_bin
            hi = np.interp(t, self.t_s, self.hi_m[j]) / metres_per_bin
            lo = np.clip(np.floor(lo), search.lo, search.hi - MIN_BINS).astype(np.int64)
            hi = np.clip(np.ceil(hi) + 1, lo + MIN_BINS, search.hi).astype(np.int64)
            out[j, :, 0] = np.where(inside, lo, search.lo)
            out[j, :, 1] = np.where(inside, hi, search.hi)
        return out

    def velocities(self, t_mid: np.ndarray) -> np.ndarray | None:
        """Each pair's first de-chirp velocity (m/s, float32 values: a device de-chirps at
        float32) at its centre `t_mid` (s): the course's, 0 beyond its times and between
        two of them where either is unknown (0); None without velocities."""
        if self.v_mps is None:
            return None
        t = np.asarray(t_mid)
        v = np.interp(t, self.t_s, self.v_mps)
        a = np.clip(np.searchsorted(self.t_s, t, side="right") - 1, 0, self.t_s.size - 1)
        b = np.minimum(a + 1, self.t_s.size - 1)
        known = (self.v_mps[a] != 0) & (self.v_mps[b] != 0) & (t >= self.t_s[0]) & (t <= self.t_s[-1])
        return np.where(known, v, 0.0).astype(np.float32).astype(np.float64)


def searched(search: Search, course: Course | None, t_rise: np.ndarray, t_fall: np.ndarray,
             metres_per_bin: float) -> Search:
    """`search` with each pair's band and first de-chirp velocity along `course`
    (unchanged without one)."""
    if course is None:
        return search
    return replace(search, bands=course.bands(t_rise, t_fall, search, metres_per_bin),
                   velocity=course.velocities(0.5 * (np.asarray(t_rise) + np.asarray(t_fall))))


def lanes(known: list[np.ndarray], apart: int) -> list[list[int]]:
    """The courses (their `known` pairs, bool per pair) in lanes, each a conversion: a
    course joins the first lane none of whose courses is known within `apart` pairs of
    its own, the earliest known first."""
    wide = [np.convolve(k, np.ones(2 * apart + 1), "same") > 0 for k in known]
    out: list[list[int]] = []
    used: list[np.ndarray] = []
    for k in sorted(range(len(known)), key=lambda k: int(np.argmax(known[k]))):
        free = next((n for n, u in enumerate(used) if not (u & known[k]).any()), None)
        if free is None:
            out.append([k])
            used.append(wide[k].copy())
        else:
            out[free].append(k)
            used[free] |= wide[k]
    return out


def merged(got: list[tuple[Course, np.ndarray]]) -> Course:
    """One course of courses known (bool per pair) at other times: each pair's band the
    course's known there, else the first's (the candidate's own band)."""
    course, _ = got[0]
    lo, hi = course.lo_m.copy(), course.hi_m.copy()
    v = np.zeros(course.t_s.size) if course.v_mps is None else course.v_mps.copy()
    for c, k in got[1:]:
        lo[:, k], hi[:, k] = c.lo_m[:, k], c.hi_m[:, k]
        v[k] = 0.0 if c.v_mps is None else c.v_mps[k]
    return Course(course.t_s, lo, hi, v if v.any() else None)
