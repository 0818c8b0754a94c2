"""A band that follows an object in time: each pair searched where its object is.

A candidate of the scene is converted in a band of its own, fixed in range; two movers
whose ranges cross share it, and the tracker holds the stronger. A course gives each
pair its own band instead: at times `t_s`, each direction's [lo, hi) in metres (a
half-sweep's plain peak lies off the distance by its Doppler shift, opposite in the two
directions), interpolated at each half-sweep's centre and rounded outwards to padded
bins, inside the plan's band. Outside the course's times a pair keeps the plan's band.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .stages.spectrum import Search

MIN_BINS = 4        # a pair's band holds at least this many bins (the peak's parabola and a floor)


@dataclass(frozen=True, eq=False)
class Course:
    """Each direction's band (m) at times `t_s` (s, increasing): `lo_m`, `hi_m` of shape
    (2, times), row 0 the rising half-sweeps', row 1 the falling ones'."""

    t_s: np.ndarray
    lo_m: np.ndarray
    hi_m: np.ndarray

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


def searched(search: Search, course: Course | None, t_rise: np.ndarray, t_fall: np.ndarray,
             metres_per_bin: float) -> Search:
    """`search` with each pair's band along `course` (unchanged without one)."""
    if course is None:
        return search
    return replace(search, bands=course.bands(t_rise, t_fall, search, metres_per_bin))
