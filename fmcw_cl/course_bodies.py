"""The echo table's bodies that carry a mover's course.

A body of the echo table (moving_echoes.bodies: a rising and a falling line that move
as one echo; fast_echoes.bodies: the velocity bank's) that lies on a mover's verified
pairs for MATCH_S is the mover's, and says its course where its tracker held another
echo; so does one that goes on as those beyond the mover's verified pairs, across a gap
that one body's motion crosses (GAP_S at most), or inside a gap of them (FILL_S from
either end), clear of every other object (fmcw_cl.along converts the mover along it).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from . import braking, crossings, fast_echoes, moving_echoes, numeric, objects, touches
from .braking import comes_to_rest, set_off_from
from .conversions import First
from .identities import TREND_S
from .moving_echoes import AGREE_MPS
from .numeric import centred_slope
from .stages.verification import reachable
from .track import Track

GAP_S = 0.02          # a gap of a mover's verified pairs this long or shorter is bridged
FILL_S = 2 * GAP_S    # a body inside a gap of them this far from either end goes on as them
ACCEL_MPS2 = 500.0    # what a body can have moved since its nearest verified pair: a t^2 / 2
MATCH_S = 1e-3        # a body of the echo table on a mover's verified pairs this long ...
MATCH_M = 0.0015      # ... within this of them (median) is its; it says its course ...
BEYOND_S = 1e-3       # ... this far from every one of them (where the tracker held another echo)

Turns = Callable[[tuple, tuple, bool], bool]   # a test that bars a join of two points across a gap


def bodies_of(first: First) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The bodies (moving_echoes.bodies) of every detection of the first conversion's
    echo table, its tracked peaks too: a body's line then runs through the stretch its
    object holds and on beyond it (off them, a line began only where the first tracker
    left it, and seldom lay on the object for MATCH_S: two glides, movers.py seed 3,
    capture 3, the second 20 -> 46 %)."""
    e, m = first.track.echoes, first.plan.model
    return [] if e is None else moving_echoes.bodies(e, m.k_rise, m.k_fall, np.ones(e.time_s.size, bool))


def fast_bodies_of(first: First) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The velocity bank's bodies of the first conversion's echo table
    (fast_echoes.bodies: movers too fast for a plain peak)."""
    e = first.track.echoes
    return [] if e is None else fast_echoes.bodies(e.fast)


def going_on(mine: list[tuple[np.ndarray, np.ndarray, np.ndarray]],
              left: list[tuple[np.ndarray, np.ndarray, np.ndarray]], ends: tuple | None = None,
              within_s: float = np.inf, turns: Turns | None = None
              ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The bodies of `left` (time s, distance m, velocity m/s each) that go on as the
    bodies `mine` before the first of them or after the last, and those that go on as
    those in turn, the nearest in time first (a body seen again far off passes over the
    ones between), then the nearest in place: one body seen again (objects.seen_again)
    or, with `ends` ((first, last) points (t, d, v) of the object beyond its bodies: its
    verified pairs'), one body's motion across a gap of `within_s` at most (`one_body`),
    unless `turns` (a function of the two points, `_barred`) bars it: it came to rest
    and turned (`_turning`), or another mover goes on as its end (`_taken_across`)."""
    got: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    pool = list(left)
    while pool:
        firsts = [(b[0][0], b[1][0], b[2][0]) for b in mine + got] + ([ends[0]] if ends else [])
        lasts = [(b[0][-1], b[1][-1], b[2][-1]) for b in mine + got] + ([ends[1]] if ends else [])
        first, last = min(firsts, key=lambda p: p[0]), max(lasts, key=lambda p: p[0])
        # (gap s, miss m) of each body seen again before the first or after the last
        keys = [(np.inf, np.inf)] * len(pool)
        for n, b in enumerate(pool):
            a, z = _across(b, first, last)
            if a is not None and (one_body(a, z) and not (turns and turns(a, z, a is last)) if ends
                                  else objects.seen_again(*a, *z)):
                keys[n] = (z[0] - a[0], abs(z[1] - a[1] - 0.5 * (a[2] + z[2]) * (z[0] - a[0])))
        n = min(range(len(pool)), key=lambda n: keys[n])        # the nearest in time, then in place
        if not keys[n][0] <= within_s:
            break
        got.append(pool.pop(n))
    return got


def _across(b: tuple[np.ndarray, np.ndarray, np.ndarray], first: tuple, last: tuple) -> tuple:
    """The points (t s, d m, v m/s) either side of the gap between the body `b` and the
    `first` point of what it may go on as, or its `last`: `b`'s last before `first`, or
    its first after `last`; (None, None) where it lies on neither side. A body reaching
    past the end by less than MATCH_S (too briefly to lie on it, `continuing`) counts
    from its points beyond it (a rail's first 25 ms, its body 0.6 ms past the first
    verified pair: movers.py seed 3, capture 11); one reaching further, from where it
    passes the end within MATCH_M and AGREE_MPS (a glide's rest and
    set-off, its body 3.9 ms past the first of the body its course goes on as:
    movers.py seed 1, capture 1)."""
    t = b[0]
    if t[0] < first[0] and t[-1] < first[0] + MATCH_S:
        k = int(np.searchsorted(t, first[0])) - 1
        return (t[k], b[1][k], b[2][k]), first
    if t[-1] > last[0] and t[0] > last[0] - MATCH_S:
        k = int(np.searchsorted(t, last[0], "right"))
        return last, (t[k], b[1][k], b[2][k])
    for end in (first, last):      # passing through it: that point of it is the end's
        at = (end[0], np.interp(end[0], t, b[1]), np.interp(end[0], t, b[2]))
        if t[0] < end[0] < t[-1] and abs(at[1] - end[1]) <= MATCH_M and abs(at[2] - end[2]) <= AGREE_MPS:
            return (at, end) if end is first else (end, at)
    return None, None


def continuing(tracks: list[Track | None], found: list[tuple[np.ndarray, np.ndarray, np.ndarray]],
               held: list[Track] = (), rests: list[Track] = ()
               ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray] | None]:
    """Per track (None: none wanted), the points (time s, distance m, velocity m/s) of
    the bodies `found` (moving_echoes.bodies) that go on as it, more than BEYOND_S from
    each of its verified pairs: a body is the track's whose verified pairs it lies on
    for MATCH_S, within MATCH_M (median) and their velocity within
    AGREE_MPS, and of those the one it lies on longest (a rail's fast body
    lay on a glide's conversion's few pairs of the rail as closely as on the rail's own,
    and carried the glide's course onto the rail), then the nearest's (median). One body's course
    where its tracker held another echo (a weaker mover the lone candidate's tracker
    left once the stronger came into its band). With them, the bodies no track holds
    that go on as them beyond the track's verified pairs (`going_on`, gaps of GAP_S at
    most) or inside a gap of them (`_fills`) and lie clear of every other object of
    `held` (`clear`), none where the track braked to one of the fixed objects `rests`
    and the body moves off the other way (`_turning`) nor across a gap where another
    mover of `held` goes on as the track's end (`_taken_across`). Each body is cut
    where one of `held` touches it first (touches.pieces: it may have gone on from one
    mover to another there)."""
    seen = [touches.path_of(h) for h in held if h.valid.any()]
    cut = [(n, p) for n, b in enumerate(found) for p in touches.pieces(b, seen)]
    found, origin = [p for _, p in cut], {id(p[0]): n for n, p in cut}   # each piece's body
    near = np.full((len(found), len(tracks)), np.inf)
    along = np.zeros((len(found), len(tracks)))          # how long it lies on each (steps)
    for j, track in enumerate(tracks):
        if track is None:
            continue
        ok = track.valid & np.isfinite(track.distance_m) & np.isfinite(track.velocity_mps)
        if not ok.any():
            continue
        t_ok, d_ok, v_ok = track.time_s[ok], track.distance_m[ok], track.velocity_mps[ok]
        for n, (grid, at, v) in enumerate(found):
            i = numeric.nearest(t_ok, grid)
            on = np.abs(t_ok[i] - grid) <= 2 * (track.period_s or 50e-6)
            if on.sum() * moving_echoes.STEP_S < MATCH_S:
                continue
            miss = float(np.median(np.abs(at[on] - d_ok[i[on]])))
            if miss <= MATCH_M and np.median(np.abs(v[on] - v_ok[i[on]])) <= AGREE_MPS:
                near[n, j], along[n, j] = miss, on.sum()
    owned: list[list[tuple[np.ndarray, np.ndarray, np.ndarray]]] = [[] for _ in tracks]
    for n, body in enumerate(found):
        if np.isfinite(near[n]).any():
            # the track it lies on longest (another's few stray pairs on it are no claim), then nearest
            owned[int(np.argmax(np.where(np.isfinite(near[n]), along[n] - 0.5 * near[n] / MATCH_M,
                                         -np.inf)))].append(body)
    left = [b for n, b in enumerate(found) if not np.isfinite(near[n]).any()]
    out: list[tuple[np.ndarray, np.ndarray, np.ndarray] | None] = [None] * len(tracks)
    rested = [(r.time_s[r.valid], float(np.median(r.distance_m[r.valid]))) for r in rests if r.valid.any()]
    for j, track in enumerate(tracks):
        if not owned[j]:
            continue
        ok = track.valid
        t_ok, d_ok, v_ok = track.time_s[ok], track.distance_m[ok], track.velocity_mps[ok]
        ends = ((t_ok[0], d_ok[0], v_ok[0]), (t_ok[-1], d_ok[-1], v_ok[-1]))
        # and the bodies no track holds that go on as them beyond its ends (a fast glide's
        # earlier stretches, between which it passed a stronger object's peaks)
        others = [h for h in held if h is not track]
        # (not a piece of a body it holds: that body touched another mover there)
        mine = {origin[id(b[0])] for b in owned[j]}
        free = [b for b in left if clear(b[0], b[1], others) and origin.get(id(b[0])) not in mine]
        movers = [h for h in others if not any(h is r for r in rests)]
        gone = going_on(owned[j], free, ends, GAP_S, _barred(_turning(t_ok, v_ok, owned[j], rested),
                                                             _taken_across(movers)))
        gone += [b for b in free if _fills(b, t_ok, d_ok, v_ok) and not any(b is g for g in gone)]
        left = [b for b in left if not any(b is g for g in gone)]
        for grid, at, v in owned[j] + gone:
            off = np.abs(t_ok[numeric.nearest(t_ok, grid)] - grid) > BEYOND_S
            if off.any():
                got = out[j] or (np.zeros(0), np.zeros(0), np.zeros(0))
                out[j] = tuple(np.r_[a, b[off]] for a, b in zip(got, (grid, at, v), strict=True))
    return out


def _turning(t: np.ndarray, v: np.ndarray, bodies: list[tuple[np.ndarray, np.ndarray, np.ndarray]],
             rests: list[tuple[np.ndarray, float]]) -> Turns | None:
    """A function of two points (t s, d m, v m/s) either side of a gap of a mover (its
    verified pairs' times `t` and velocities `v`, its `bodies`), the earlier its own
    (`after`) or the later: whether it braked to rest at one of the fixed objects
    `rests` (the times s of its verified pairs, its distance m; braking.comes_to_rest,
    its velocities' slope over identities.TREND_S up to the earlier point;
    braking.set_off_from one, over TREND_S from the later point), first seen
    after it (last seen before it) and still there when the other point moves the other
    way (already there), both braking.MOVING_MPS or faster: a body that turned at its
    rest (a jump's apex) sets off from there after it, not while it rests. A landing
    foot's course (-0.86 m/s, braking at 220 m/s^2, its rest seen 17 ms on 3 mm from
    where it braked) went on as a hand flying off at +2.98 m/s 11 ms later: 610 valid
    pairs of the hand on the foot, movers.py seed 5, capture 22. None where there is
    no rest."""
    if not rests:
        return None
    tt = np.concatenate([t, *(b[0] for b in bodies)])
    vv = np.concatenate([v, *(b[2] for b in bodies)])

    def acc(lo: float, hi: float) -> float:
        near = (tt >= lo) & (tt <= hi)
        return centred_slope(tt[near], vv[near])[0] if near.sum() >= 3 else 0.0

    def turns(a: tuple, z: tuple, after: bool) -> bool:
        if a[2] * z[2] >= 0 or min(abs(a[2]), abs(z[2])) < braking.MOVING_MPS:
            return False
        if after:       # braked at a, and still at rest once z moved
            end = (0, *a, acc(a[0] - TREND_S, a[0]))
            return any(comes_to_rest(end, r, s[0] - a[0]) and s[-1] > z[0] for s, r in rests)
        end = (0, *z, acc(z[0], z[0] + TREND_S))          # set off at z, at rest as a moved
        return any(set_off_from(end, r, z[0] - s[-1]) and s[0] < a[0] for s, r in rests)

    return turns


def _taken_across(movers: list[Track]) -> Turns:
    """A function of two points (t s, d m, v m/s) either side of a gap of a mover, the
    earlier its own (`after`) or the later: whether another of the `movers` seen inside
    the gap goes on as the mover's end there (`one_body` from its verified pair nearest
    that end): the mover's part beyond its end is that one's, and a body beyond the gap
    is no more its own. A leg's descent from its apex, its part before the apex 3.8 ms
    earlier another object (cut where its tracker passed to the other leg), went on
    backwards as the other leg's take-off 19 ms earlier, 20 mm off its trapezoid: 554
    valid pairs of the other leg (movers.py seed 32, capture 20)."""
    seen = [touches.path_of(m) for m in movers]

    def taken(a: tuple, z: tuple, after: bool) -> bool:
        for t, d, v in seen:
            inside = np.flatnonzero((t > a[0]) & (t < z[0]))
            if inside.size:
                k = inside[0] if after else inside[-1]
                if one_body(a, (t[k], d[k], v[k])) if after else one_body((t[k], d[k], v[k]), z):
                    return True
        return False

    return taken


def _barred(*tests: Turns | None) -> Turns | None:
    """One test of two points across a gap (`Turns`) that bars where any of `tests` does."""
    tests = tuple(f for f in tests if f is not None)
    return (lambda a, z, after: any(f(a, z, after) for f in tests)) if tests else None


def _fills(b: tuple[np.ndarray, np.ndarray, np.ndarray], t: np.ndarray, d: np.ndarray, v: np.ndarray) -> bool:
    """Whether the body `b` lies inside one gap of the verified pairs (t s, d m, v m/s)
    and one body's motion (`one_body`) joins it to the pairs either side, each within
    FILL_S: held at both ends, a longer gap than GAP_S (a glide's bank body 5 and 25 ms
    from the ends of a 66 ms gap of its pairs, 0.3 mm off the trapezoid, went on as no
    object: movers.py seed 3, capture 23)."""
    i, k = np.searchsorted(t, [b[0][0], b[0][-1]])
    if i != k or i == 0 or i == t.size or b[0][0] - t[i - 1] > FILL_S or t[i] - b[0][-1] > FILL_S:
        return False
    return one_body((t[i - 1], d[i - 1], v[i - 1]), (b[0][0], b[1][0], b[2][0])) and one_body(
        (b[0][-1], b[1][-1], b[2][-1]), (t[i], d[i], v[i]))


def one_body(a: tuple, z: tuple) -> bool:
    """Whether one body last seen at `a` can be the one seen at `z` ((t s, d m, v m/s)):
    the trapezoid of their velocities within the verification's bound
    (verification.reachable, as across a course's gaps, `_bridged`), their velocities
    within AGREE_MPS + ACCEL_MPS2 dt (a body 6 mm off a rail's end 4 ms on,
    objects.seen_again's 40 mm allowed: a wall's, 73 valid pairs on it;
    tests/test_scenes.py, hunt seed 9)."""
    dt = z[0] - a[0]
    return bool(reachable(*a, *z) and abs(z[2] - a[2]) <= AGREE_MPS + ACCEL_MPS2 * dt)


def clear(grid: np.ndarray, at: np.ndarray, others: list[Track], v: np.ndarray | None = None,
          k: tuple[float, float] | None = None) -> bool:
    """Whether a body (times s, distances m) lies mostly more than objects.GATE_M from
    each of `others`' verified pairs nearest in time, those within GAP_S of it: an object
    unverified a while is still there (a foot at rest 2 mm from the other landing foot,
    whose body went on as the other's course: 165 valid pairs on it, movers.py seed 1,
    capture 30). With its velocities `v` (m/s) and the Doppler factors `k` (m per m/s),
    nor where the two are told apart as two movers are (crossings.movers_apart)."""
    on = np.zeros(grid.size, bool)
    for track in others:
        ok = track.valid
        if not ok.any():
            continue
        t_ok, d_ok = track.time_s[ok], track.distance_m[ok]
        i = numeric.nearest(t_ok, grid)
        dv = None if k is None else v - track.velocity_mps[ok][i]
        on |= (np.abs(t_ok[i] - grid) <= GAP_S) & crossings.indistinct(at - d_ok[i], dv, k)
    return bool(on.mean() < 0.5)
