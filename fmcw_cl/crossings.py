"""Where two objects' echoes cannot be told apart (fmcw_cl.objects' rules, fmcw_cl.scene).

An object's `path` (its verified pairs, bridged across short gaps) and `course` (moved
on at its velocity beyond them); where another's comes within GATE_M of an object's
pair (`conflicts`), where a pair lies on another's harmonic (`harmonics`) or de-chirped
image (`images`), or a fixed object's pair reads moving (`read_moving`), the pair is
``ambiguous``. A `still` object leaves rows without still
echoes (stages.clutter): a conversion on them need not fear it.
"""

from __future__ import annotations

import numpy as np

from . import fixed_echoes
from .coherence import slope
from .numeric import follows
from .objects import GATE_M, SAME_M, level, per_pair
from .stages import faults
from .stages.clutter import STILL_S
from .stages.verification import ACCEL_MAX, KINEMATIC_S
from .track import Track

BRIDGE_S = 5e-3          # an object's path is interpolated across gaps this short
COURSE_S = 0.01          # an object's images are looked for this far beyond its verified pairs
                         # (moved on at their velocity: 25 mm at 500 m/s^2, inside an image's reach)
STILL_M = 5e-4           # an object whose verified distances span at most this is still (`still`)
SLOPE_S = 2e-3           # a course accelerates this long beyond its pairs, as their velocities within it
FOLLOW_PAIRS = 16        # a fixed object's pairs read moving this close in pairs are taken together ...
FOLLOW_M = 2.5e-4        # ... and their own where their distances follow their velocities within this
MOVERS_M = 5e-3          # two movers this close, or their peaks in either direction, cannot be told apart


def path(track: Track) -> np.ndarray:
    """The object's distance at each pair (m): its verified pairs, linearly
    interpolated across gaps of at most BRIDGE_S, NaN elsewhere."""
    ok = np.flatnonzero(track.valid)
    out = np.full(track.pairs, np.nan)
    if ok.size == 0:
        return out
    t = track.time_s
    out[ok] = track.distance_m[ok]
    nxt = np.searchsorted(ok, np.arange(track.pairs))       # the next verified pair
    inner = (nxt > 0) & (nxt < ok.size)
    i = np.flatnonzero(inner & ~track.valid)
    a, b = ok[nxt[i] - 1], ok[nxt[i]]
    short = t[b] - t[a] <= BRIDGE_S
    i, a, b = i[short], a[short], b[short]
    w = (t[i] - t[a]) / (t[b] - t[a])
    out[i] = (1 - w) * track.distance_m[a] + w * track.distance_m[b]
    return out


def read_moving(tracks: list[Track], moving: list[bool]) -> list[np.ndarray]:
    """Per object, its pairs that are not its own where it is fixed (`moving` False):
    those that read a velocity of fixed_echoes.MOVING_MPS or more where, with the others
    so read within FOLLOW_PAIRS of them, their distances do not follow their velocities
    (numeric.follows: first to last, within FOLLOW_M + 25 % of their integral): another echo's,
    or two bodies' peaks paired across (a part cut from a jump's conversion: 43
    integrated pairs standing at 0.334 m while they read -0.34 to -0.61 m/s). A mover's
    part too brief to run (objects.runs), so fixed, keeps its pairs (a glide's 41 at
    +0.52 m/s, 1.0 mm in 2 ms). None of a mover's; as a fixed target's
    (target.ambiguous), for the parts the objects were cut into."""
    out = []
    for t, m in zip(tracks, moving, strict=True):
        fast = np.flatnonzero(np.abs(t.velocity_mps) >= fixed_echoes.MOVING_MPS)
        taken = np.zeros(t.pairs, bool)
        if not m and fast.size:
            for k in np.split(fast, np.flatnonzero(np.diff(fast) > FOLLOW_PAIRS) + 1):
                along = k.size > 1 and follows(t.time_s[k], t.distance_m[k], t.velocity_mps[k], FOLLOW_M)[0]
                taken[k] = not along
        out.append(taken)
    return out


def heard(track: Track) -> np.ndarray:
    """The object's `path`, and where it is NaN at an ``ambiguous`` pair (verified, but
    beside another echo), the mean of that pair's de-chirped half-sweep peaks (m): an
    echo was measured there, whichever object it was."""
    out = path(track)
    if track.reason is None:
        return out
    held = np.isnan(out) & (track.reason == faults.AMBIGUOUS)
    out[held] = np.mean(per_pair(track, "sweep_distance_dechirped_m")[:, held], axis=0)
    return out


def course(track: Track, reach_s: float = COURSE_S) -> tuple[np.ndarray, np.ndarray]:
    """An object's distance (m) and velocity (m/s) at each pair as far as its motion
    tells: its `path` (the velocities interpolated alike), and beyond it, within
    `reach_s` of the nearest verified pair, that pair moved on at its velocity and, for
    SLOPE_S (as long as it was measured), at its acceleration (`_acceleration`); NaN
    further. At its velocity alone, a hand's course 3.5 ms before its first verified
    pair (accelerating at 40 m/s^2) lay 0.13 m/s off, and its image 4 mm from where a
    pair of its peak and a jump's lay (benchmarks/movers.py seed 17, capture 12)."""
    where = path(track)
    ok = np.flatnonzero(track.valid)
    if ok.size == 0:
        return where, where.copy()
    t, d, v = track.time_s, track.distance_m, track.velocity_mps
    u = np.interp(t, t[ok], v[ok])
    u[np.isnan(where)] = np.nan
    gap = np.flatnonzero(np.isnan(where))
    nxt = np.searchsorted(ok, gap)
    before, after = ok[np.maximum(nxt - 1, 0)], ok[np.minimum(nxt, ok.size - 1)]
    near = np.where(np.abs(t[gap] - t[before]) <= np.abs(t[after] - t[gap]), before, after)
    dt = t[gap] - t[near]
    reach = np.abs(dt) <= reach_s
    gap, near, dt = gap[reach], near[reach], dt[reach]
    ends, which = np.unique(near, return_inverse=True)
    acc = _acceleration(t[ok], v[ok], t[ends])[which]
    held = np.clip(dt, -SLOPE_S, SLOPE_S)            # as long as it was measured, then at that velocity
    where[gap] = d[near] + v[near] * dt + acc * held * (dt - 0.5 * held)
    u[gap] = v[near] + acc * held
    return where, u


def _acceleration(t: np.ndarray, v: np.ndarray, at: np.ndarray) -> np.ndarray:
    """The slope (m/s^2) of the verified velocities `v` at times `t` (s) within SLOPE_S
    of each of the pairs' times `at`, at most ACCEL_MAX; 0 where those pairs span less
    than half of SLOPE_S (a few pairs' noise is no acceleration)."""
    lo, hi = np.searchsorted(t, at - SLOPE_S), np.searchsorted(t, at + SLOPE_S, side="right")
    wide = t[hi - 1] - t[lo] >= 0.5 * SLOPE_S
    return np.where(wide, np.clip(slope(t, v, at, SLOPE_S), -ACCEL_MAX, ACCEL_MAX), 0.0)


def conflicts(tracks: list[Track], fixed: list[bool] | None = None,
              unseen: set[tuple[int, int]] = frozenset(), k: tuple[float, float] | None = None,
              there: list[tuple[float, float]] | None = None) -> list[np.ndarray]:
    """For each track, the pairs where another object's path lies within GATE_M of its
    own (`heard`: its ambiguous pairs too): the two echoes cannot be told apart there
    (a wall of 150 codes 5 mm from a rail creeping off: the rail's pairs ambiguous
    beside the wall, the wall's read 2 mm off, its peak pulled by the rail's). A `fixed` object is
    there all along, at the span of its verified distances (1st-99th percentile),
    whether or not its own track holds it then: a pair of another within GATE_M of that
    span is ambiguous on both (a cable swaying +-10 mm, a fixed echo of the tables,
    whose band edge cut its near swing: the rail's tracker held that swing once the
    rail had left its band); a body's rest only from when it came to when it left (`there`,
    s per track: fmcw_cl.rest_spans). Not where (i, j) is `unseen`: track i's rows hold nothing
    of object j (a still one, taken out of a mover's rows: fmcw_cl.scene). With the
    Doppler factors `k` (m per m/s, rising and falling), a fixed object and a mover
    that passes it so fast that their peaks lie more than GATE_M apart in each
    direction (the distance + k v: a spectrum de-chirped at any velocity shifts both
    alike) are told apart (a hand at -1.1 m/s passing a foot at rest: its peaks 30 mm
    either side of the foot's; movers.py seed 3, capture 12, the foot 360 pairs
    `ambiguous`); where one direction's peaks meet elsewhere, the images' rule judges.
    Two movers only where they lie more than MOVERS_M apart and so do their peaks in
    each direction (`movers_apart`): a glide at +3.5 m/s and a sway at -1.3 m/s 1-2
    mm apart left a blend 2.1 mm off the glide however far apart their peaks
    (`passing`; movers.py seed 2, capture 29: 6 valid pairs off their object)."""
    fixed = fixed or [False] * len(tracks)
    own = [path(t) for t in tracks]
    paths = [p if f else heard(t) for t, p, f in zip(tracks, own, fixed, strict=True)]
    speeds = [course(t)[1] for t in tracks] if k is not None else []
    out = [np.zeros(t.pairs, bool) for t in tracks]
    for i in range(len(tracks)):
        for j in range(i + 1, len(tracks)):
            gap = paths[i] - paths[j]
            close = np.abs(gap) <= GATE_M      # NaN: False
            if k is not None:
                close &= ~_apart(gap, speeds[i] - speeds[j], k, fixed[i] or fixed[j])
            # an ambiguous pair's peaks where the other's own verified pair lies: that
            # echo seen by a second tracker, not a second echo beside it
            echo = np.isnan(own[i]) ^ np.isnan(own[j])
            close &= ~(echo & (np.abs(gap) <= SAME_M))
            for a, b in ((i, j), (j, i)):
                if fixed[b] and tracks[b].valid.any():
                    near = _within_span(tracks[b], paths[a])
                    if there is not None:
                        near &= (tracks[a].time_s >= there[b][0]) & (tracks[a].time_s <= there[b][1])
                    if k is not None:   # the mover's peaks either side of the still span
                        apart = [~_within_span(tracks[b], paths[a] + kj * speeds[a]) for kj in k]
                        near &= ~(apart[0] & apart[1] & np.isfinite(speeds[a]))
                    close |= near
            for a, b in ((i, j), (j, i)):
                if (a, b) not in unseen:
                    out[a] |= close
    return out


def passing(tracks: list[Track], k: tuple[float, float] | None = None,
            fixed: list[bool] | None = None) -> list[np.ndarray]:
    """For each track, the verified pairs within GATE_M of the `course` of another
    object in motion (a verified pair at fixed_echoes.MOVING_MPS or faster, of either
    kind: a sway's 2 ms at -1.3 m/s, 3 mm, is a fixed part; a still wall is
    `conflicts`', whose rows a mover's conversion may not hold) up to
    verification.KINEMATIC_S beyond its verified pairs: where one
    tracker passed from one mover to another as they crossed, its last pairs on the
    one and its first on the other, which no two tracks held at once (`conflicts`), a
    merged peak's (a glide at +3.5 m/s and a sway at -1.3 m/s 1-2 mm apart: the glide's
    last pair 2.1 mm off it). With the Doppler factors `k`, not a `fixed` object's pairs
    where its velocity and the course's put their peaks more than GATE_M apart in each
    direction (`conflicts`: a pair on the other's echo reads its velocity), nor a mover's
    where they lie apart as two movers' (`movers_apart`)."""
    moving = [bool(np.any(np.abs(t.velocity_mps[t.valid]) >= fixed_echoes.MOVING_MPS)) for t in tracks]
    courses = [course(t, KINEMATIC_S) if m else None for t, m in zip(tracks, moving, strict=True)]
    out = [np.zeros(t.pairs, bool) for t in tracks]
    for i, a in enumerate(tracks):
        for j, c in enumerate(courses):
            if i != j and c is not None:
                gap = a.distance_m - c[0]
                near = np.abs(gap) <= GATE_M
                if k is not None:
                    near &= ~_apart(gap, a.velocity_mps - c[1], k, fixed is not None and fixed[i])
                out[i] |= a.valid & near
    return out


def _peaks_apart(gap_m: np.ndarray, dv_mps: np.ndarray, k: tuple[float, float],
                 gate_m: float = GATE_M) -> np.ndarray:
    """Where two echoes `gap_m` (m) and `dv_mps` (m/s) apart have their peaks (the
    distance + k v, `k`: m per m/s, rising and falling) more than `gate_m` apart in both
    directions: told apart (NaN, a velocity not known: not apart)."""
    return (np.abs(gap_m + k[0] * dv_mps) > gate_m) & (np.abs(gap_m + k[1] * dv_mps) > gate_m)


def movers_apart(gap_m: np.ndarray, dv_mps: np.ndarray, k: tuple[float, float]) -> np.ndarray:
    """Where two movers `gap_m` (m) and `dv_mps` (m/s) apart are told apart: more than
    MOVERS_M apart, and so are their peaks in each direction (`_peaks_apart`). A Hann
    window's peak 4 mm from one twice as strong moves at most 0.011 mm (3 mm: 0.04 mm;
    2x padded, Gaussian interpolation); GATE_M also took two movers' pairs 5-10 mm
    apart (glides overtaking, a hand past a foot: benchmarks/movers.py)."""
    return (np.abs(gap_m) > MOVERS_M) & _peaks_apart(gap_m, dv_mps, k, MOVERS_M)


def indistinct(gap_m: np.ndarray, dv_mps: np.ndarray | None, k: tuple[float, float] | None = None
               ) -> np.ndarray:
    """Where two echoes `gap_m` (m) apart lie within GATE_M of each other and, with the
    Doppler factors `k` (m per m/s) and their velocities `dv_mps` (m/s) apart, are not
    told apart as two movers are (`movers_apart`): one cannot be told from the other."""
    near = np.abs(gap_m) <= GATE_M
    return near if k is None else near & ~movers_apart(gap_m, dv_mps, k)


def _apart(gap_m: np.ndarray, dv_mps: np.ndarray, k: tuple[float, float], fixed: bool) -> np.ndarray:
    """Where two echoes `gap_m` (m) and `dv_mps` (m/s) apart are told apart: by their
    peaks alone where one is `fixed` (`_peaks_apart`), else as two movers are
    (`movers_apart`)."""
    return _peaks_apart(gap_m, dv_mps, k) if fixed else movers_apart(gap_m, dv_mps, k)


def _within_span(fixed: Track, d: np.ndarray) -> np.ndarray:
    """Where distances `d` (m, per pair) lie within GATE_M of a fixed object's span of
    verified distances."""
    lo, hi = np.percentile(fixed.distance_m[fixed.valid], [1, 99])
    return (d >= lo - GATE_M) & (d <= hi + GATE_M)


def harmonics(tracks: list[Track], unambiguous_m: float) -> list[np.ndarray]:
    """For each track, the verified pairs that lie where a harmonic of another object
    would (2..fixed_echoes.HARMONICS times its distance, folded at the unambiguous range,
    within fixed_echoes.HARMONIC_M per multiple, moving k times as fast within
    fixed_echoes.MOVING_MPS per multiple), fixed_echoes.HARMONIC_DB or more under its median level:
    a distortion's ghost of a strong echo, which a band of its own lets a tracker hold."""
    out = [np.zeros(t.pairs, bool) for t in tracks]
    for i, a in enumerate(tracks):
        weakest = np.nanmin(per_pair(a, "sweep_snr_dechirped_db"), axis=0)
        for j, b in enumerate(tracks):
            if i == j or not b.valid.any():
                continue
            weak = weakest <= level(b) - fixed_echoes.HARMONIC_DB
            for k in range(2, fixed_echoes.HARMONICS + 1):
                at = np.mod(k * b.distance_m, 2 * unambiguous_m)
                fold = at > unambiguous_m
                at = np.where(fold, 2 * unambiguous_m - at, at)
                v = np.where(fold, -k, k) * b.velocity_mps
                out[i] |= (a.valid & weak & (np.abs(a.distance_m - at) <= k * fixed_echoes.HARMONIC_M)
                           & (np.abs(a.velocity_mps - v) <= k * fixed_echoes.MOVING_MPS))
    return out


def images(tracks: list[Track], model, window: np.ndarray,
           unseen: set[tuple[int, int]] = frozenset()) -> list[np.ndarray]:
    """For each track, the verified pairs whose de-chirped peaks could be the image of
    another object (fmcw_cl.wall_images.confused_moving, along its `course`, at its
    velocity and level, `_levels`): a band left empty of echoes lets a tracker hold
    another's image (a rail's, de-chirped 10 m/s off, 0.3 m beyond it). A fixed one's
    too, beside the target choice's `walls_m`: a cable swaying +-10 mm at 0.19 m/s,
    listed at 0.260 m, put its image 15 mm from that of a still tone there. Not where
    (i, j) is `unseen` (`conflicts`): no image of j in track i's rows."""
    from .wall_images import confused_moving

    out = [np.zeros(t.pairs, bool) for t in tracks]
    sources = {}                        # each object's course, velocity, verified path and levels
    for j, b in enumerate(tracks):
        if b.valid.any():
            sources[j] = (*course(b), path(b), _levels(b))
    for i, a in enumerate(tracks):
        if not a.valid.any():
            continue
        peaks, snr = per_pair(a, "sweep_distance_dechirped_m"), per_pair(a, "sweep_snr_dechirped_db")
        for j, (where, u, known, top) in sources.items():
            if j == i or (i, j) in unseen:
                continue
            out[i] |= a.valid & confused_moving(a.velocity_mps, tuple(peaks), tuple(snr), known, u, top,
                                                model, window, a.valid)
            # beyond its verified pairs its level is not known (an integrated track's peaks
            # stand as high as an image 10 dB under the mover: taken as strong enough); near
            # its course the other may be this one itself, seen again (`conflicts`, `returns`)
            beyond = np.where(np.isnan(known) & (np.abs(a.distance_m - where) > GATE_M), where, np.nan)
            out[i] |= a.valid & confused_moving(a.velocity_mps, tuple(peaks), tuple(snr), beyond, u, np.inf,
                                                model, window, a.valid)
    return out


def _levels(track: Track) -> np.ndarray:
    """An object's level (dB over the floor) in each pair's rising and falling
    half-sweeps, (2, pairs): its median (objects.level), or its own de-chirped peak's
    where a verified pair reads it louder. A jump's image 3.7 m/s off passed as 3.1 dB
    under the peak of a pair that held it, by its median level, 20.6 dB; its own
    half-sweeps there read 21-24 dB (benchmarks/movers.py seed 17, capture 15)."""
    median = level(track)
    own = per_pair(track, "sweep_snr_dechirped_db")
    return np.where(track.valid, np.fmax(own, median), median)


def still(track: Track, wavelength_m: float) -> bool:
    """Whether an object is still enough that rows without still echoes
    (stages.clutter) hold nothing of it: its verified distances span at most STILL_M
    (1st-99th percentile: no sway), and their trend moves it less than a quarter
    wavelength over the running mean's span (stages.clutter.STILL_S)."""
    ok = track.valid
    if ok.sum() < 20:
        return False
    t, d = track.time_s[ok], track.distance_m[ok]
    lo, hi = np.percentile(d, [1, 99])
    slope = np.polyfit(t - t.mean(), d, 1)[0] if np.ptp(t) > 0 else np.inf
    return bool(hi - lo <= STILL_M and abs(slope) * STILL_S < wavelength_m / 4)
