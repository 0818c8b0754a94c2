"""Parts of one body that their courses carried to meet, joined.

The identities are told (fmcw_cl.identities) before the courses add their pairs
(fmcw_cl.along): a mover lost at a crossing is two objects then, and its courses may
carry both to within milliseconds of each other (a glide at -2.85 m/s, as two objects
3.6 ms apart after a glide the other way crossed it). Two moving objects, the earlier's
last verified pair before the later's first, are one where one body in motion the
same way moves so across the gap (along's test for a course's bodies). A mover and a
fixed object first seen after it are one where the mover's braking brings it to rest
there in time (a rail slowing at 41 m/s^2, lost at +0.90 m/s 12 mm short of where it
rests, 35 ms later); a fixed object and a mover seen after it, where the mover's
acceleration sets it off from there. Neither where another object can be either's
other part, lies on the course between them at that body's speed, or was at the
rest's place before it came to rest or after it set off (`_contested`). Before
that, a mover is cut at a gap of its verified pairs where another mover first seen
within it goes on as the part before, or one last seen within it as the part after,
the mover's own pairs across it do not, and that join is free (`_taken_on`): a course
can add a body's part where the tracker had passed to another echo.
"""

from __future__ import annotations

import numpy as np

from . import course_bodies, identities, objects
from .braking import MOVING_MPS, comes_to_rest, set_off_from
from .numeric import centred_slope
from .objects import SceneObject
from .track import Track

GAP_S = course_bodies.GAP_S         # a gap this long or shorter is joined across


def met(scene: list[SceneObject]) -> list[SceneObject]:
    """`scene` with the objects that are one body's parts joined (objects.joined), the
    cheapest join (identities._costs) first, one at a time (a new list; the objects
    are kept in their order, a joined one at the earlier's place, moving), after
    `_taken_on`'s cuts."""
    scene = _taken_on(list(scene))
    while True:
        ends = [_ends(o) for o in scene]
        joins = _joins(scene, ends)
        free = [(c, i, j) for c, i, j in joins if not _contested(scene, ends, joins, i, j)]
        if not free:
            return scene
        _, i, j = min(free)
        a, b = scene[i], scene[j]
        scene[i] = SceneObject(0, True, objects.joined(a.track, b.track), f"{a.note}; met: {b.note}",
                               a.whole if a.whole is b.whole else None)
        scene.pop(j)


def _taken_on(scene: list[SceneObject]) -> list[SceneObject]:
    """`scene` with each mover cut (identities.split) at a gap of its verified pairs
    where another mover goes on as its part (`_handed`) and that join is then free
    (`_joins`, not `_contested`): a course can add the pairs of a body whose tracker had
    passed to another echo (a new list)."""
    scene = list(scene)
    k = 0
    while k < len(scene):
        o = scene[k]
        for mid, y, before in _handed(o, scene):
            parts = identities.split(o, identities.cut_at([o.track.valid], np.array([mid]), o.track.time_s),
                                     "another mover's course goes on across its gap, its own does not")
            trial = scene[:k] + parts + scene[k + 1:]
            j = next(n for n, p in enumerate(trial) if p.track is y)
            pair = (k, j) if before else (j, k + 1)
            ends = [_ends(p) for p in trial]
            joins = _joins(trial, ends)
            if any((p, q) == pair for _, p, q in joins) and not _contested(trial, ends, joins, *pair):
                scene = trial
                break
        else:
            k += 1
    return scene


def _handed(o: SceneObject, scene: list[SceneObject]) -> list[tuple[float, Track, bool]]:
    """(time s, track, before) of each gap of mover `o`'s verified pairs across which
    its own course is no one body's steady motion (identities.goes_on) nor a join's
    (`_goes_on`, `braking.comes_to_rest`) while another mover's goes on as its part
    (`_goes_on`): one first seen within the gap from its pair before it (`before`), or
    one last seen within it to its pair after (the tracker followed a foot's take-off
    to +0.85 m/s, then came back 2.9 ms later on the other foot at rest 4.2 mm behind,
    while the take-off's course went on from within the gap at +1.19 m/s: movers.py
    seed 24, capture 35, 70 valid pairs of the take-off on the foot at rest)."""
    x = o.track
    if not (o.moving and x.valid.any()):
        return []
    before, after = identities.gaps(x)
    inner = (before >= 0) & (after >= 0)
    before, after = before[inner], after[inner]
    trend = identities._trend(x, before)
    steady = identities.goes_on(*identities.pairs_at(x, before), trend, *identities.pairs_at(x, after))
    movers = [p.track for p in scene if p.moving and p.track is not x and p.track.valid.any()]
    out = []
    for g in np.flatnonzero(~steady):
        p, n = before[g], after[g]
        end = (*_pair(x, p)[:4], trend[g])
        if _goes_on(end, _pair(x, n)) or comes_to_rest(end, x.distance_m[n], x.time_s[n] - x.time_s[p]):
            continue                # its own pairs a join would make
        mid = 0.5 * (x.time_s[p] + x.time_s[n])
        for y in movers:
            first, last = np.flatnonzero(y.valid)[[0, -1]]
            if p < first < n and _goes_on(end, _pair(y, first)):
                out.append((mid, y, True))
            if p < last < n and _goes_on(_pair(y, last), _pair(x, n)):
                out.append((mid, y, False))
    return out


def _pair(track: Track, k: int) -> tuple:
    """`track`'s pair `k` as an end (index, t, d, v; no acceleration known)."""
    return (int(k), float(track.time_s[k]), float(track.distance_m[k]), float(track.velocity_mps[k]), 0.0)


def _ends(o: SceneObject) -> tuple | None:
    """`o`'s first and last verified pairs' (index, time s, distance m, velocity m/s,
    acceleration m/s^2: its velocities' slope over identities.TREND_S from there on,
    or up to there), as two tuples; None where it holds none."""
    tr = o.track
    k = np.flatnonzero(tr.valid)
    if not k.size:
        return None
    t, d, v = identities.pairs_at(tr, k[[0, -1]])
    first = k[tr.time_s[k] <= t[0] + identities.TREND_S]
    start = centred_slope(tr.time_s[first], tr.velocity_mps[first])[0] if first.size >= 3 else 0.0
    end = identities._trend(tr, k[[-1]])[0]
    return (int(k[0]), t[0], d[0], v[0], start), (int(k[-1]), t[-1], d[-1], v[-1], end)


def _goes_on(a: tuple, z: tuple) -> bool:
    """Whether a moving body last seen at `a` (index, t, d, v, acc) is the moving one
    first seen at `z`: later within GAP_S, in motion the same way at both (a rail
    slowing to +0.90 m/s is not a glide setting off from beside it at -0.71 m/s 7.3 ms
    later, although a body can turn so: movers.py seed 3, capture 26, 757 valid pairs
    of the rail joined to the glide), one body's motion across (course_bodies.one_body)."""
    dt = z[1] - a[1]
    return bool(z[0] > a[0] and 0 < dt <= GAP_S and min(abs(a[3]), abs(z[3])) >= MOVING_MPS
                and a[3] * z[3] > 0 and course_bodies.one_body(a[1:4], z[1:4]))


def _joins(scene: list[SceneObject], ends: list) -> list[tuple[float, int, int]]:
    """(cost, i, j): object i's last verified pair goes on as object j's first (a
    mover's as a mover's, `_goes_on`; a mover's as its rest, or a rest's as the mover
    that set off from it, `braking.comes_to_rest`, `braking.set_off_from`)."""
    out = []
    for i, e in enumerate(ends):
        for j, f in enumerate(ends):
            if i == j or e is None or f is None or f[0][0] <= e[1][0]:
                continue
            a, z, dt = e[1], f[0], f[0][1] - e[1][1]
            mi, mj = scene[i].moving, scene[j].moving
            if mi and mj:
                ok = _goes_on(a, z)
            elif mi:
                ok = comes_to_rest(a, _still_at(scene[j]), dt)
            elif mj:
                ok = set_off_from(z, _still_at(scene[i]), dt)
            else:
                ok = False
            if ok:
                out.append((float(identities._costs(*a[1:4], *z[1:4])), i, j))
    return out


def _still_at(o: SceneObject) -> float:
    """A fixed object's distance (m): its verified pairs' median."""
    return float(np.median(o.track.distance_m[o.track.valid]))


def _contested(scene: list[SceneObject], ends: list, joins: list, i: int, j: int) -> bool:
    """Whether another object could be i's or j's other part instead: another join of
    either; between movers, another object's verified pairs from i's end to j's start
    within objects.GATE_M of the course between them (the trapezoid of their
    velocities) at a velocity as alike as one body's (objects.alike); at a rest,
    another object's verified pairs within objects.GATE_M of it before it came to rest
    (a wall there all along; the other foot at rest where one landed) or after it set
    off, unless most of its verified pairs while the rest was verified lie elsewhere
    (a glide at rest 2.6 mm from where the other came to rest 60 ms after it set off,
    verified 0.1 m away then: movers.py seed 3, capture 8)."""
    if any((p == i) != (q == j) for _, p, q in joins if (p == i) or (q == j)):
        return True
    (_, ta, da, va, _), (_, tb, _, vb, _) = ends[i][1], ends[j][0]
    if not (scene[i].moving and scene[j].moving):
        rest = j if scene[i].moving else i
        at = _still_at(scene[rest])
        lo, hi = ends[rest][0][1], ends[rest][1][1]
        for k, o in enumerate(scene):
            tr = o.track
            when = tr.time_s < tb if rest == j else tr.time_s > ta
            there = np.abs(tr.distance_m - at) <= objects.GATE_M
            meanwhile = tr.valid & (tr.time_s >= lo) & (tr.time_s <= hi)
            away = meanwhile.any() and np.mean(~there[meanwhile]) > 0.5     # verified elsewhere meanwhile
            if k not in (i, j) and np.any(tr.valid & when & there) and not away:
                return True
        return False
    for k, o in enumerate(scene):
        if k in (i, j):
            continue
        tr = o.track
        at = tr.valid & (tr.time_s >= ta) & (tr.time_s <= tb)
        if not at.any():
            continue
        u = (tr.time_s[at] - ta) / (tb - ta)
        course = da + (tb - ta) * u * (va + 0.5 * u * (vb - va))
        v = va + u * (vb - va)
        if np.any((np.abs(tr.distance_m[at] - course) <= objects.GATE_M)
                  & objects.alike(0.0, v, tr.velocity_mps[at])):
            return True
    return False
