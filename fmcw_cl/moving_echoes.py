"""Moving echoes no tracker held: lines of the echo table (fmcw_cl.echoes).

A second mover that the first conversion's tracker never held, and that stays nowhere
long enough to be a persistent echo of a slice (a glide at 1 m/s crosses a 2 mm bin in
2 ms), still leaves its plain peaks among each half-sweep's CFAR detections, shifted by
its Doppler term k v (k: `DopplerModel.k_rise`, `k_fall`, opposite in the two
directions). In each direction the detections that are not the tracked peak are
linked into `lines`: each detection goes on the line whose last ones, moved on at
their velocity, reach it within LINK_M + ACCEL_MAX dt^2 / 2, across at most GAP_S.
A line of MIN_DETECTIONS over MIN_SPAN_S is an echo's. A rising and a falling line at
once give an echo's distance and its Doppler velocity (the two equations d = R + k v);
where that velocity is the distance's own slope, they are one moving body's (`bodies`,
which course_bodies.continuing reads too; noise lines, one direction's sidelobes, or two
echoes' lines are not), unless it lies on the tracked target (within
fixed_echoes.APART_M: the target's own peak split, smeared) or on its harmonics (two
and three times its distance), and only where the tracker held verified pairs at once
(else it may be the target's own echo lost). `unheld`
gives each such echo's span (those that overlap, one), for objects.candidates; an
echo that a body known only by its smeared energy reaches, or leaves from, widens that
body's span instead (its slower stretch: `joined`).
"""

from __future__ import annotations

import numpy as np

from . import echoes
from .coherence import slope
from .fixed_echoes import APART_M, MIN_TRAVEL_M, MOVING_MPS, beside_span
from .numeric import matched, nearest, runs
from .objects import seen_again
from .stages.verification import ACCEL_MAX, KINEMATIC_S
from .track import Track

LINK_M = 1e-3          # a detection this far from where its line's velocity carries it goes on it
GAP_S = KINEMATIC_S    # ... after at most this without one (a fade)
START_S = 2e-4         # a line of one detection takes the next within this (its velocity unknown) ...
START_MPS = 10.0       # ... as fast as this
TREND = 16             # a line's velocity over its last this many detections
MIN_DETECTIONS = 20    # a line of this many detections ...
MIN_SPAN_S = 2e-3      # ... over this long is an echo's
REACH_S = 5e-4         # an echo's slope: least squares within this either side
AGREE_MPS = 0.2        # a rising and a falling line whose Doppler velocity is their echo's slope
                       # within this are one echo ...
OVERLAP_S = 1e-3       # ... over at least this of time together
STEP_S = 2.5e-4        # ... taken at times this far apart
HARMONICS = (2, 3)     # a line this many times the tracked distance is its harmonic


def lines(time_s: np.ndarray, distance_m: np.ndarray) -> list[np.ndarray]:
    """The lines (indices into the arrays, in time order) of one direction's detections
    at `time_s` (s, sorted) and `distance_m` (m) of MIN_DETECTIONS or more over
    MIN_SPAN_S or more. A line's velocity is its last detection's distance less its
    TREND'th last's over their time (its first's while shorter)."""
    if not time_s.size:
        return []
    # a half-sweep holds one to three detections and a few lines are open: Python's
    # floats link them several times faster than numpy's calls on such small arrays, and
    # a lone detection goes to its nearest line without the matching's sort (3x); a line
    # keeps its last time, distance and velocity, made once as a detection joins it
    t, d = time_s.tolist(), distance_m.tolist()
    starts = np.r_[0, np.flatnonzero(np.diff(time_s) > 0) + 1, time_s.size].tolist()
    open_: list[_Line] = []
    out: list[list[int]] = []
    for a, b in zip(starts[:-1], starts[1:], strict=True):
        now = t[a]
        kept = []
        for x in open_:
            if now - x.t <= (GAP_S if len(x.at) > 1 else START_S):
                kept.append(x)
            elif len(x.at) > 1:
                out.append(x.at)
        open_ = kept
        if not open_:
            open_ = [_Line(i, t, d) for i in range(a, b)]
            continue
        if b - a == 1:
            best, miss, here = None, 0.0, d[a]
            for x in open_:
                at, reach = x.ahead(now)
                m = abs(here - at)
                if m <= reach and (best is None or m < miss):       # the nearest, on a tie the first
                    best, miss = x, m
            if best is None:
                open_.append(_Line(a, t, d))
            else:
                best.add(a, t, d)
            continue
        ahead = [x.ahead(now) for x in open_]        # (where, reach) of each line
        near = [(m, i, n) for n, (at, reach) in enumerate(ahead) for i in range(b - a)
                if (m := abs(d[a + i] - at)) <= reach]        # (miss, detection, line) within reach
        taken = [False] * (b - a)
        for i, n in matched(near):                      # one detection a line
            open_[n].add(a + i, t, d)
            taken[i] = True
        open_ += [_Line(a + i, t, d) for i in range(b - a) if not taken[i]]
    out += [x.at for x in open_]
    return [np.asarray(x) for x in out
            if len(x) >= MIN_DETECTIONS and t[x[-1]] - t[x[0]] >= MIN_SPAN_S]


class _Line:
    """An open line of `lines`: its detections `at` (indices of times s and distances m),
    its last time `t` and distance `d`, and its velocity `v` (m/s; None while its
    detections span no time)."""

    __slots__ = ("at", "t", "d", "v")

    def __init__(self, i: int, t: list[float], d: list[float]) -> None:
        self.at, self.t, self.d, self.v = [i], t[i], d[i], None

    def add(self, i: int, t: list[float], d: list[float]) -> None:
        """Detection `i` of times `t` and distances `d` joins: the velocity over the last
        TREND detections (all while fewer)."""
        self.at.append(i)
        back = self.at[-TREND] if len(self.at) >= TREND else self.at[0]
        self.t, self.d = t[i], d[i]
        span = self.t - t[back]
        self.v = (self.d - d[back]) / span if span > 0 else None

    def ahead(self, now: float) -> tuple[float, float]:
        """Where the line is at `now` (s), moved on at its velocity, and how far from
        there a detection may lie to go on it (m; -1: none may)."""
        dt = now - self.t
        if self.v is None:
            return self.d, LINK_M + START_MPS * dt if dt <= START_S else -1.0
        return self.d + self.v * dt, LINK_M + 0.5 * ACCEL_MAX * dt * dt


def unheld(e: echoes.Echoes, k_rise: float, k_fall: float, track: Track, band: tuple[float, float | None],
           known: list[tuple[float, float]], fast: list | None = None) -> list[tuple[float, float]]:
    """(lo, hi) m of each moving echo of the echo table `e` that `track`'s tracker did
    not hold, inside `band` (m) and centred beyond APART_M of the `known` spans (m).
    Each body (`bodies`, and those of the velocity bank `fast`, fast_echoes.bodies, in
    its form) of the detections neither at the tracked peak nor within
    APART_M of a known span that moves (median speed MOVING_MPS or more),
    travels MIN_TRAVEL_M and lies beside the verified pairs (`_beside`). Where it goes on
    to a slice of a known span that holds no moving verified pair, or comes from one
    (`_smeared`, `_continues`), that span widened to hold it is given instead."""
    # not the known echoes' detections (a sway's: most of a table's)
    free = ~e.tracked & off_spans(e.distance_m, known)
    ok = track.valid & np.isfinite(track.distance_m)
    held_t, held_d = track.time_s[ok], track.distance_m[ok]
    ends = _run_ends(track)
    smeared = _smeared(e, track, known)
    lo, hi = band[0], band[1] or np.inf
    out = []
    for grid, at, v in bodies(e, k_rise, k_fall, free) + list(fast or []):
        if np.median(np.abs(v)) < MOVING_MPS or np.ptp(at) < MIN_TRAVEL_M:
            continue
        if not _beside(grid, at, held_t, held_d) or _goes_on(grid, at, v, ends):
            continue
        span = (float(np.percentile(at, 1)), float(np.percentile(at, 99)))
        on = [k for k in smeared if _continues(grid, at, v, smeared[k])]
        if on:                      # a smeared span's own body, before or after its smear
            out.append((min(span[0], *(k[0] for k in on)), max(span[1], *(k[1] for k in on))))
        elif span[1] >= lo and span[0] < hi and not beside_span(0.5 * (span[0] + span[1]), known):
            out.append(span)
    return _merged(out)


def off_spans(distance_m: np.ndarray, spans: list[tuple[float, float]]) -> np.ndarray:
    """Which distances (m) lie more than APART_M from every one of `spans` (m)."""
    keep = np.ones(np.shape(distance_m), bool)
    for a, b in spans:
        keep &= (distance_m < a - APART_M) | (distance_m > b + APART_M)
    return keep


def bodies(e: echoes.Echoes, k_rise: float, k_fall: float, free: np.ndarray
           ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """(times s, distances m, velocities m/s) of each body the `free` detections of the
    echo table `e` show: a rising and a falling line (`lines`) together for OVERLAP_S,
    at STEP_S steps, are one echo at R = (k_f d_r - k_r d_f) / (k_f - k_r) moving at
    (d_f - d_r) / (k_f - k_r) (d_r = R + k_r v, d_f = R + k_f v; `k_rise`, `k_fall`: m
    per m/s, the Doppler model's) where that velocity is R's own slope within AGREE_MPS
    (noise lines, or a line and another echo's, are not one body's motion)."""
    way = []
    for rising in (True, False):
        idx = np.flatnonzero(free & (e.rising == rising))
        t, d = e.time_s[idx], e.distance_m[idx]         # in time order, as the table
        way.append([(t[x], d[x]) for x in lines(t, d)])
    out = []
    for tr, dr in way[0]:
        for tf, df in way[1]:
            start, end = max(tr[0], tf[0]), min(tr[-1], tf[-1])
            if end - start < OVERLAP_S:
                continue
            grid = np.arange(start, end, STEP_S)
            r, f = np.interp(grid, tr, dr), np.interp(grid, tf, df)
            at = (k_fall * r - k_rise * f) / (k_fall - k_rise)
            v = (f - r) / (k_fall - k_rise)
            if np.median(np.abs(v - slope(grid, at, grid, REACH_S))) <= AGREE_MPS:
                out.append((grid, at, v))
    return out


def joined(known: list[tuple[float, float]], found: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """The `known` moving spans (m) and the `found` ones (`unheld`), nearest first; a
    known span that a found one holds and shares an end with (a smeared span widened by
    its body's own line) left out."""
    def widened(k: tuple[float, float]) -> bool:
        return any(a <= k[0] and k[1] <= b and (a == k[0] or b == k[1]) for a, b in found)

    return sorted([k for k in known if not widened(k)] + found)


def _smeared(e: echoes.Echoes, track: Track, known: list[tuple[float, float]]) -> dict:
    """The slices (time s, distance m; the echo table's diffuse persistent echoes) of
    each `known` span (m, within APART_M: its ends are percentiles) that holds no moving
    verified pair of `track`: a body known only by its Doppler-smeared energy, whose
    slower stretches may be lines."""
    p = e.persistent
    fast = track.valid & np.isfinite(track.distance_m) & (np.abs(track.velocity_mps) >= MOVING_MPS)
    d = track.distance_m[fast]
    out = {}
    for a, b in known:
        at = p["diffuse"] & (p["distance_m"] >= a - APART_M) & (p["distance_m"] <= b + APART_M)
        if at.any() and not np.any((d >= a) & (d <= b)):
            out[(a, b)] = (p["time_s"][at], p["distance_m"][at])
    return out


def _continues(t: np.ndarray, c: np.ndarray, v: np.ndarray, slices: tuple[np.ndarray, np.ndarray]) -> bool:
    """Whether the echo (distances `c` m, velocities `v` m/s at `t` s) reaches, at its
    ends' velocities, one of the smeared `slices` (time s, distance m) after it, or
    comes from one before it (the slices carry no velocity)."""
    ts, ds = slices
    return _meets(t, c, v, (ts, ds, v[0]), (ts, ds, v[-1]))


def _meets(t: np.ndarray, c: np.ndarray, v: np.ndarray, last: tuple, first: tuple) -> bool:
    """Whether a body last seen at one of `last` (time s, distance m, velocity m/s;
    arrays) before the echo (distances `c` m, velocities `v` m/s at `t` s) is seen
    again as it, or the echo is seen again at one of `first` after it (objects.seen_again)."""
    return bool(np.any((last[0] < t[0]) & seen_again(*last, t[0], c[0], v[0]))
                or np.any((first[0] > t[-1]) & seen_again(t[-1], c[-1], v[-1], *first)))


def _merged(spans: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """`spans` (m), those that overlap one (a line broken by a fade pairs with the
    other direction's twice), nearest first."""
    out: list[tuple[float, float]] = []
    for lo, hi in sorted(spans):
        if out and lo <= out[-1][1]:
            out[-1] = (out[-1][0], max(out[-1][1], hi))
        else:
            out.append((lo, hi))
    return out


def _beside(t: np.ndarray, c: np.ndarray, held_t: np.ndarray, held_d: np.ndarray) -> bool:
    """Whether most of a line's distances `c` (m, at `t` s) lie beside the verified pairs
    (`held_t`, `held_d`): one within GAP_S, and more than APART_M from it and from two
    and three times its distance. Where the tracker held no verified pair, the line may
    be its own echo lost (a rail's last 16 mm, slowing, found beyond its verified pairs:
    its band cut there, its own conversion lost them)."""
    if not held_t.size:
        return False
    off = np.abs(t - held_t[nearest(held_t, t)]) <= GAP_S
    off &= ~on_multiples(c, np.interp(t, held_t, held_d), (1, *HARMONICS))
    return bool(np.mean(off) > 0.5)


def on_multiples(c: np.ndarray, near: np.ndarray, multiples) -> np.ndarray:
    """Which distances `c` (m) lie within APART_M of one of `multiples` times the
    distances `near` (m) of a tracked echo then: its own line (1) or its harmonics."""
    on = np.zeros(np.shape(c), bool)
    for m in multiples:
        on |= np.abs(c - m * near) <= APART_M
    return on


def _run_ends(track: Track) -> tuple[np.ndarray, np.ndarray]:
    """The first and the last pair (time s, distance m, velocity m/s; rows of a (3, R)
    array each) of each run of `track`'s verified pairs."""
    ok = track.valid & np.isfinite(track.distance_m) & np.isfinite(track.velocity_mps)
    at = np.vstack([track.time_s, track.distance_m, track.velocity_mps])
    r = runs(ok)
    return at[:, r[:, 0]], at[:, r[:, 1] - 1]


def _goes_on(t: np.ndarray, c: np.ndarray, v: np.ndarray, ends: tuple[np.ndarray, np.ndarray]) -> bool:
    """Whether the echo (distances `c` m, velocities `v` m/s at `t` s) can be the body of
    a run of verified pairs (`_run_ends`) that ends before it, or starts after it, seen
    again (objects.seen_again): the tracker's own echo where it lost it (a rail's last
    16 mm, its tracker on a glide since: found as another echo, it cut the rail's band
    there, 85 -> 44 %, movers.py seed 9, capture 26)."""
    first, last = ends
    return _meets(t, c, v, last, first)
