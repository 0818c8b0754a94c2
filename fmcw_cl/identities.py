"""Which body is which: objects cut where no one body can have made their pairs, and
parts joined again where one body's motion makes them, and no other's does alike.

A conversion's tracker follows the echo of its band; where two movers cross, or pass
near each other while both are lost, it can come back on the other one (a rail and an
object moved the other way: each band's tracker held the other mover after the
crossing, 2016 and 1708 valid pairs on the wrong object). Distances alike, the bodies'
motions are not: a rail at +1.9 m/s continues at +2.5 m/s, not at -2.9 m/s. So:

- `parted`: each object cut where consecutive verified pairs cannot be one body's
  (objects.bodies), and, where two movers are both lost at once and either could have
  come back as the other (objects.seen_again), at that gap, a track's ends counting as
  gaps, and a fixed object's first and last pairs too, or where the other is first or
  last seen within the mover's gap and one `goes_on` as the other (`crossing_cuts`);
- `rejoined`: parts seen again joined (objects.returns). Among several movers a join is
  made only where it is the one the motions tell (`contested`: no mover's part seen
  between them could join either, or is first seen between them as the earlier going
  on, or last seen going on as the later, and none seen from the first's start to the second's end
  joins either within RATIO times their `_cost` plus FLOOR, and no object of the other
  kind seen between them, or while one of them is seen and within that bound, could be
  either instead; contests wherever the parts hold two movers), and only where a body
  can move so (verification.reachable's bounds), the cheapest first; else the parts stay
  objects of their own (fewer periods tracked, none on the wrong object); then a
  conversion's parts across kinds on one body's steady course (a sway's turn); never
  into a part that starts, nor out of one that ends, where another mover's path touches
  it (fmcw_cl.touches: the echo tables' bodies). Parts of one object cut at crossings
  alone that are all joined again are that object as it was.
"""

from __future__ import annotations

import numpy as np

from . import fixed_echoes, handovers, objects, touches
from .numeric import centred_slope
from .objects import SceneObject
from .stages import faults
from .stages.verification import ACCEL_MAX, JUMP_MAX_M, KINEMATIC_S, reachable

BLOCK = 64            # contested joins weighed at once, the cheapest first
RATIO = 3.0           # a join is the motion's where every other costs this many times its `_cost` ...
FLOOR = 1.0           # ... plus this (m/s^1.5: 30 m/s^2 over 1 ms); the rail: 3.3 on, 38 as the glide
TREND_S = 3.2e-3      # a part's acceleration at its end: its velocities' slope over this
ACCEL_FLOOR = 30.0    # m/s^2: a course across a gap within this, or its end's acceleration, of that ...
VELOCITY_NOISE = 0.05     # m/s and m of a pair's velocity and distance not counted as acceleration
DISTANCE_NOISE = 5e-4     # (a lab's SNR; de-chirped peaks)


def least_acceleration(ta, da, va, tb, db, vb):
    """The least acceleration (m/s^2) one body needs to be at pairs (ta, da, va) and
    then (tb, db, vb) (s, m, m/s): its velocity's change over the time between, and the
    trapezoid's miss (any motion within A misses it by at most A dt^2 / 8), each less
    VELOCITY_NOISE and DISTANCE_NOISE."""
    dt = np.maximum(np.abs(tb - ta), 1e-9)
    dv = np.maximum(np.abs(vb - va) - VELOCITY_NOISE, 0.0)
    miss = np.maximum(np.abs(db - da - 0.5 * (va + vb) * (tb - ta)) - DISTANCE_NOISE, 0.0)
    return np.maximum(dv / dt, 8.0 * miss / (dt * dt))


def gaps(track) -> tuple[np.ndarray, np.ndarray]:
    """The indices of the verified pairs before and after each gap of `track` (one
    pair or more unverified between them), its ends included as gaps open on one side
    (-1: no pair there): a tracker lost for good, or one that starts late, is lost too."""
    ok = np.flatnonzero(track.valid)
    gap = np.flatnonzero(np.diff(ok) > 1)
    return np.r_[-1, ok[gap], ok[-1]], np.r_[ok[0], ok[gap + 1], -1]


def pairs_at(track, k: np.ndarray) -> tuple:
    """(time s, distance m, velocity m/s) of `track`'s pairs `k` (k >= 0)."""
    return track.time_s[k], track.distance_m[k], track.velocity_mps[k]


def _trend(track, k: np.ndarray) -> np.ndarray:
    """The acceleration (m/s^2) of `track`'s verified pairs over TREND_S up to each pair
    `k`: their velocities' least-squares slope (0 where fewer than three)."""
    ok = np.flatnonzero(track.valid)
    t, v = track.time_s[ok], track.velocity_mps[ok]
    out = np.zeros(np.size(k))
    for m, r in enumerate(np.searchsorted(ok, k)):
        lo, hi = np.searchsorted(t, t[r] - TREND_S, "left"), r + 1
        if hi - lo >= 3:
            out[m] = centred_slope(t[lo:hi], v[lo:hi])[0]
    return out


def goes_on(ta, da, va, aa, tb, db, vb) -> np.ndarray:
    """Whether a body last seen at (ta, da, va), accelerating at `aa` (m/s^2, `_trend`),
    goes on as the one first seen at (tb, db, vb) (s, m, m/s; arrays): seen again
    (objects.seen_again) at a mean acceleration across the gap within its own, or
    ACCEL_FLOOR, of it (a foot's take-off at 170 m/s^2 seen again 17 ms on at 272; not
    a rail at +23 m/s^2 turned to a glide's -2.85 m/s 15 ms on, -316)."""
    gap = (vb - va) / np.maximum(np.abs(tb - ta), 1e-9)
    steady = np.abs(gap - aa) <= np.maximum(np.abs(aa), ACCEL_FLOOR)
    return objects.seen_again(ta, da, va, tb, db, vb) & steady


def _swaps(x, y, fixed: bool = False) -> np.ndarray:
    """The times (s) at which to cut mover `x`: the middles of its gaps that overlap a
    gap of mover `y` (both lost at once) across which either could have come back as
    the other (objects.seen_again). Where `y`'s gap is one of its ends (lost for good,
    or not yet seen), every later or earlier gap of `x` overlaps it: there the swap
    must also be about as cheap as `x`'s own course across its gap (`_least` within
    RATIO times it plus FLOOR, as a join's contest), not merely possible, unless `y`
    is first or last seen within `x`'s gap, where one goes on as the other (`goes_on`:
    a foot's take-off lost for 115 ms, the other foot's flight then on its tracker,
    while the first went on 17 ms later 7 mm from its trapezoid, as fast as it sped
    up; a long gap's course is cheap whatever body made it: 221 valid pairs of one foot
    on the other). A `fixed` `y`
    only at its ends: its first (first seen after `x` was lost: come to rest), cheaper
    than `x`'s course (a foot landing at a window's distance goes on its own course);
    its last (last seen while `x` was lost: set off as `x`), only where `x`'s course
    costs RATIO times the swap plus FLOOR or more, for a wall's echo fades (a landing
    cut where a weak wall seen for 2 ms 14 ms before its gap could have set off as it:
    84.8 -> 27.5 % of its periods) while a glide at rest 132 ms set off 11 mm from
    where it lay (a rail at rest 48 mm away, lost 58 ms: 1213 valid pairs of the glide)."""
    x0, x1 = gaps(x)
    inner = (x0 >= 0) & (x1 >= 0)
    x0, x1 = x0[inner], x1[inner]
    y0, y1 = gaps(y)
    if fixed:                                       # a fixed object's ends alone
        y0, y1 = y0[[0, -1]], y1[[0, -1]]
    ty0 = np.where(y0 >= 0, y.time_s[np.maximum(y0, 0)], -np.inf)
    ty1 = np.where(y1 >= 0, y.time_s[np.maximum(y1, 0)], np.inf)
    lo = np.searchsorted(ty1, x.time_s[x0], side="right")     # y's first gap ending after x's starts
    hi = np.searchsorted(ty0, x.time_s[x1], side="left")      # ... and past the last starting before x's ends
    gx = np.repeat(np.arange(x0.size), np.maximum(hi - lo, 0))
    if not gx.size:
        return np.zeros(0)
    gy = np.concatenate([np.arange(p, q) for p, q in zip(lo, hi, strict=True) if q > p])
    px, nx, py, ny = x0[gx], x1[gx], y0[gy], y1[gy]
    own = _least(*pairs_at(x, px), *pairs_at(x, nx))
    bar = RATIO * own + FLOOR

    def swapped(a, pa, b, nb, end, left, within):     # a last seen at pa, then b first seen at nb
        out = np.zeros(gx.size, bool)
        least = np.full(gx.size, np.inf)
        on = np.zeros(gx.size, bool)
        has = (pa >= 0) & (nb >= 0)
        pairs = (*pairs_at(a, pa[has]), *pairs_at(b, nb[has]))
        least[has] = _least(*pairs)
        # beyond the trapezoid (to or from rest), only as cheap as x's own course
        out[has] = objects.seen_again(*pairs) | (_landed(*pairs) & (least[has] <= bar[has]))
        end &= has                      # at y's end, as cheap as x's own course, or ...
        cost = least[end]
        if not fixed:                   # ... y's end within x's gap, a goes on as b (`goes_on`)
            at = np.flatnonzero(end & within)
            on[at] = goes_on(*pairs_at(a, pa[at]), _trend(a, pa[at]), *pairs_at(b, nb[at]))
            out[end] &= (cost <= bar[end]) | on[end]
        elif left:                      # a fixed y set off as x (or its echo faded): its motion tells
            out[end] &= RATIO * cost + FLOOR <= own[end]
        else:                           # x come to rest as a fixed y
            out[end] &= cost < own[end]
        return out

    tx0, tx1 = x.time_s[px], x.time_s[nx]
    swap = (swapped(y, py, x, nx, ny < 0, True, y.time_s[np.maximum(py, 0)] > tx0)
            | swapped(x, px, y, ny, py < 0, False, y.time_s[np.maximum(ny, 0)] < tx1))
    return 0.5 * (x.time_s[px] + x.time_s[nx])[swap]


def _landed(ta, da, va, tb, db, vb) -> np.ndarray:
    """Whether a mover lost at (ta, da, va) can be the body seen at (tb, db, vb) (s, m,
    m/s; arrays) beyond objects.seen_again's trapezoid: from motion to rest, or from
    rest to motion, where a body can move so (`_costs` finite), for a landing's
    trapezoid misses by the rest of its flight. `_swaps` takes it only where the swap
    costs within RATIO times the mover's own course plus FLOOR (a leg lost at -4.94 m/s
    157.6 mm, landed 50 ms later at 76.7 mm: 42.6 mm off the trapezoid, cost 30, while
    the other leg's, 4 mm beside, was 27 mm off, cost 54: 34 valid pairs of one leg's
    rest on the other; not a foot's 1 ms gap at rest against a leg lost 48 ms before)."""
    slow = (np.abs(va) < fixed_echoes.MOVING_MPS) != (np.abs(vb) < fixed_echoes.MOVING_MPS)
    return slow & np.isfinite(_costs(ta, da, va, tb, db, vb))


def _least(ta, da, va, tb, db, vb) -> np.ndarray:
    """`least_acceleration` times the root of the time between (m/s^1.5, `_cost`'s
    measure, without its bounds)."""
    return least_acceleration(ta, da, va, tb, db, vb) * np.sqrt(np.abs(tb - ta))


def crossing_cuts(scene: list[SceneObject]) -> list[np.ndarray]:
    """For each object, the times (s) at which to cut it: its gaps across which another
    mover, lost at once, could have come back as it or it as the other (`_swaps`; a
    leg's tracker lost for good as the legs cross while the other's comes back on it),
    or across which a fixed object first seen after could have been it (come to rest:
    a rail lost, its tracker back on a glide 7 ms later, 494 valid pairs). None for a
    fixed object."""
    seen = [k for k, o in enumerate(scene) if o.track.valid.any()]
    cuts = [[] for _ in scene]
    for i in seen:
        for j in seen:
            if i != j and scene[i].moving:
                cuts[i] += list(_swaps(scene[i].track, scene[j].track, fixed=not scene[j].moving))
    return [np.unique(c) for c in cuts]


def parted(scene: list[SceneObject], crossings: bool = False,
           asked: handovers.Asked | None = None) -> list[SceneObject]:
    """Each object whose verified pairs no one body can have made split into objects of
    one body each (objects.bodies), a mover's where its tracker passed to another echo
    at once (fmcw_cl.handovers), and with `crossings`, at its `crossing_cuts` (`split`);
    parts that one body can join again are joined by `rejoined`, never across a
    handover."""
    cuts = crossing_cuts(scene) if crossings else [np.zeros(0)] * len(scene)
    out = []
    for o, cut in zip(scene, cuts, strict=True):
        bodies = objects.bodies(o.track)
        handed = np.mean((asked or handovers.handovers)(o.track), axis=0) if o.moving else np.zeros(0)
        crossed = cut_at(bodies, cut, o.track.time_s)
        parts = cut_at(crossed, handed, o.track.time_s)
        if len(parts) < 2:
            out.append(o)
            continue
        why = " or ".join([w for w, n in (("no body moves between them", len(bodies) > 1),
                                        ("lost while another mover was", len(crossed) > len(bodies)),
                                        ("its tracker passed to another echo", len(parts) > len(crossed)))
                           if n])
        out += split(o, parts, why)
    return out


def cut_at(masks: list[np.ndarray], cut: np.ndarray, time_s: np.ndarray) -> list[np.ndarray]:
    """Each of the pair masks `masks` cut at the times `cut` (s, sorted; pairs at
    `time_s`): a mask per span between cuts that holds pairs."""
    if not cut.size:
        return masks
    k = np.searchsorted(cut, time_s)                # the span between cuts each pair lies in
    return [p & (k == s) for p in masks for s in np.unique(k[p])]


def split(o: SceneObject, parts: list[np.ndarray], why: str) -> list[SceneObject]:
    """Object `o` as an object per part (pair masks `parts`), the others' pairs
    `discontinuous` (another body's); each part's kind its own (objects.moves; a
    mover's part that runs as its velocities say, however briefly, moves: objects.runs),
    each knowing the track it was cut from (`whole`), its note saying `why`."""
    out = []
    for k, mask in enumerate(parts, 1):
        track = objects.invalidated(o.track, ~mask, faults.DISCONTINUOUS)
        moving = objects.moves(track) or (o.moving and objects.runs(track))
        out.append(SceneObject(0, moving, track, f"{o.note}; part {k} of {len(parts)}: {why}",
                               o.track if o.whole is None else o.whole))
    return out


def rejoined(scene: list[SceneObject], contests: bool = False, asked: handovers.Asked | None = None,
             touched: touches.Touched | None = None) -> list[SceneObject]:
    """The objects with those seen again joined (objects.returns): one object. Only
    objects of one kind: a fixed object that a mover crossed is not the mover after it
    (a swaying cable that a rail passed, the rail beyond it). Two parts of one track
    joined again are still parts of it (`whole`): its tuning and its rest are that
    conversion's. With `contests` (several movers), the least acceleration's join first,
    and only where not `contested` and, between two moving ends, reachable; then parts of
    one conversion across kinds where one body's steady course crosses the gap
    (`least_acceleration` within ACCEL_FLOOR: a sway's turn, too slow to move, between
    its swings; not a leg's part 33 ms later 10 mm off the trapezoid). Joined first, a
    glide's rest would have started before a later part's contest: the other glide's
    part 90 ms before took a part of it. Never into a part whose first verified pairs,
    or out of one whose last, another mover's path touches (`touched`, touches.ends):
    either body can be the one before (after) them."""
    asked = asked or handovers.Asked()
    scene = list(scene)
    for across_kinds in (False, True) if contests else (False,):
        ends = [_Ends.row(o) for o in scene]
        while len(scene) > 1:
            e = _Ends(ends, scene, asked, across_kinds, touched)
            i, j = np.nonzero(np.triu(e.returns, 1))                 # (i, j) in order, i < j
            if contests:
                keep = np.isfinite(e.cost[i, j])
                i, j = i[keep], j[keep]
                order = np.argsort(e.cost[i, j], kind="stable")      # the cheapest join first
                i, j = i[order], j[order]
                first = _uncontested(e, i, j)
            else:
                first = 0 if i.size else None
            if first is None:
                break
            i, j = int(i[first]), int(j[first])
            a, b = scene[i], scene.pop(j)
            far = abs(np.nanmedian(a.track.distance_m) - np.nanmedian(b.track.distance_m)) > objects.GATE_M
            scene[i] = SceneObject(0, a.moving or b.moving or far, objects.joined(a.track, b.track),
                                   f"{a.note}; seen again: {b.note}", a.whole if a.whole is b.whole else None)
            ends.pop(j)
            ends[i] = _Ends.row(scene[i])
    return scene


def _uncontested(e: _Ends, i: np.ndarray, j: np.ndarray) -> int | None:
    """The first of the joins of parts i and j (arrays, the cheapest first) that is not
    `contested`, weighed BLOCK at a time; None if all are."""
    for k in range(0, i.size, BLOCK):
        free = np.flatnonzero(~contested(e, i[k:k + BLOCK], j[k:k + BLOCK]))
        if free.size:
            return k + int(free[0])
    return None


class _Ends:
    """Every part's first and last verified pair, and from them every two parts' joins
    at once: whether the later is the earlier seen again (objects.returns, of one kind,
    or `across_kinds` alone, of one conversion on a steady course: `returns`; symmetric), the
    join's `_cost` (`cost`; symmetric, inf where no body moves so) and the parts'
    verified times (for `contested`)."""

    def __init__(self, rows: list[tuple], scene: list[SceneObject], asked: handovers.Asked,
                 across_kinds: bool = False, touched: touches.Touched | None = None):
        self.moving, i0, i1, *pairs = (np.array(c) for c in zip(*rows, strict=True))
        self.t0, self.d0, self.v0, self.t1, self.d1, self.v1, self.a1 = pairs
        has = i0 >= 0
        # [e, l]: e's last verified pair before l's first; seen: l seen again from e
        self.later = has[:, None] & has[None, :] & (i1[:, None] < i0[None, :])
        span = (self.t1[:, None], self.d1[:, None], self.v1[:, None],
                self.t0[None, :], self.d0[None, :], self.v0[None, :])
        self.seen = objects.seen_again(*span)
        self.goes = self.later & goes_on(*span[:3], self.a1[:, None], *span[3:])
        back = self.later & self.seen
        kind = self.moving[:, None] == self.moving[None, :]
        if across_kinds:
            # one conversion's parts, one body's course across the gap: a sway's turn
            whole = np.array([id(o.whole) if o.whole is not None else -1 - k for k, o in enumerate(scene)])
            steady = least_acceleration(*span) <= ACCEL_FLOOR
            kind = (whole[:, None] == whole[None, :]) & np.where(self.later, steady, steady.T)
        self.returns = (back | back.T) & kind & ~handovers.across(scene, self.t1, self.t0, asked)
        if touched is not None:
            self.returns &= ~touched.barred([o.track for o in scene], self.later)
        cost = _costs(*span)
        self.cost = np.where(self.later, cost, cost.T)
        # every part's verified times in one sorted array: part k's shifted by k wide spans
        times = [o.track.time_s[o.track.valid] for o in scene]
        low = min((t[0] for t in times if t.size), default=0.0)
        self.width = 1.0 + max((t[-1] - low for t in times if t.size), default=0.0)
        self.times = np.concatenate([k * self.width + (t - low) for k, t in enumerate(times)])
        self.low = low

    @staticmethod
    def row(o: SceneObject) -> tuple:
        """Part `o`'s kind, its first and last verified pairs' indices (-1: none),
        their (time s, distance m, velocity m/s) and its acceleration at its end
        (`_trend`)."""
        k = np.flatnonzero(o.track.valid)
        if not k.size:
            return (o.moving, -1, -1) + (0.0,) * 7
        t, d, v = pairs_at(o.track, k[[0, -1]])
        return (o.moving, k[0], k[-1], t[0], d[0], v[0], t[-1], d[-1], v[-1], _trend(o.track, k[[-1]])[0])

    def within(self, start: np.ndarray, end: np.ndarray) -> np.ndarray:
        """Which parts (columns) hold a verified pair from `start` to `end` (s; rows)."""
        shift = self.width * np.arange(self.moving.size)
        lo = np.searchsorted(self.times, shift + (start[:, None] - self.low), "left")
        return np.searchsorted(self.times, shift + (end[:, None] - self.low), "right") > lo


def contested(e: _Ends, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """Whether another part could be the one seen instead, for each join of parts i and
    j (arrays; `_Ends`): a mover's part seen wholly between them that could join either
    (it comes first: a leg lost for 88 ms, seen again 9 ms on, then the other leg's
    landing 8 mm off its course), or one seen from the earlier's first verified pair to
    the later's last that could join either within RATIO * their `_cost` + FLOOR (its
    motion tells as much as theirs), or one its tracker can have passed to or from at
    the later's start or the earlier's end (`_handed`), or an object of the other kind
    that could be a part between them (`_other_kind`). Rows: the joins; columns: the
    other parts."""
    ahead = e.later[i, j]
    a, b = np.where(ahead, i, j), np.where(ahead, j, i)             # the earlier part, the later
    seen = e.within(e.t0[a], e.t1[b])
    seen[np.arange(i.size), i] = seen[np.arange(i.size), j] = False
    bar = (RATIO * e.cost[i, j] + FLOOR)[:, None]
    inside = e.moving & (e.t0 > e.t1[a, None]) & (e.t1 < e.t0[b, None])
    joins = ((e.returns[i] & (inside | (e.cost[i] <= bar)))
             | (e.returns[j] & (inside | (e.cost[j] <= bar))))     # (symmetric)
    # first seen between them, the earlier going on as it; last seen between them, going
    # on as the later (`goes_on`): as good a course as theirs, however cheap a long gap's
    joins |= e.moving & (e.t0 > e.t1[a, None]) & (e.t0 < e.t0[b, None]) & e.goes[a]
    joins |= e.moving & (e.t1 > e.t1[a, None]) & (e.t1 < e.t0[b, None]) & e.goes[:, b].T
    joins |= _handed(e.t1, e.d1, e.v1, e.t0[b, None], e.d0[b, None], e.v0[b, None])    # it is the later, or
    joins |= _handed(e.t1[a, None], e.d1[a, None], e.v1[a, None], e.t0, e.d0, e.v0)    # the earlier goes on
    same = e.moving == e.moving[i, None]
    return (seen & np.where(same, joins, _other_kind(e, a, b, bar))).any(axis=1)


def _handed(ta, da, va, tb, db, vb) -> np.ndarray:
    """Whether a tracker can have passed from one part, last seen at (ta s, da m, va m/s),
    to another first seen at (tb, db, vb) between two bodies that nothing tells apart:
    within KINEMATIC_S after it, objects.GATE_M of it and velocities alike as one body's
    (objects.alike). A leg's landing, its tracker ending on the other
    leg at rest 1.8 mm beside it, then on the first as it bounced (-0.51, +0.31 m/s): a
    part that ends so contests the later one's every other join, a part that begins so
    the earlier one's (166 valid pairs of the bounce on the other leg); not two movers
    crossing at +1.9 and -2.9 m/s, whose motions tell."""
    dt = tb - ta
    return (dt >= 0) & (dt <= KINEMATIC_S) & (np.abs(db - da) <= objects.GATE_M) & objects.alike(dt, va, vb)


def _other_kind(e: _Ends, a: np.ndarray, b: np.ndarray, bar: np.ndarray) -> np.ndarray:
    """Which parts (columns) could be one of parts a and b (the earlier and the later;
    rows) instead, were they of the other kind (it comes first): first seen between them
    and seen again from the earlier (a rail come to rest 10 mm on, 45 ms later, and a
    glide at 182 ms whose start the rail's trapezoid reaches within 20 mm over 142 ms: 752
    valid pairs of the glide joined to the rail; a foot at rest and a hand come down 13 mm
    from it 200 ms later, the foot taking off 2.5 ms after its rest), or last seen between
    them or within KINEMATIC_S before the earlier's end (lost at once: a rail lost 0.1 ms
    before a glide at rest it passed, its next 23 pairs too short to run, so fixed, were
    joined to the rest: 101 valid pairs), the later seen again from it; or first seen
    while the later is, within `bar` of `_costs` (a rail come to rest 11 mm on while a
    glide it had passed was followed: 494; not a swaying cable seen before a rail that
    passed it is seen again, nor a weak wall's last pairs before a landing's gap: a
    wall's echo fades)."""
    last, first = e.t1[a, None], e.t0[b, None]
    became = (last < e.t0) & ((e.t0 < first) | ((e.t0 <= e.t1[b, None]) & (e.cost[a] <= bar))) & e.seen[a]
    becomes = (last - KINEMATIC_S < e.t1) & (e.t1 < first) & e.seen[:, b].T
    return became | becomes


def _cost(a, b) -> float:
    """`_costs` of `a`'s and `b`'s ends (objects.ends: the earlier's last verified pair
    and the later's first)."""
    return float(_costs(*objects.ends(a, b)[2]))


def _costs(ta, da, va, tb, db, vb) -> np.ndarray:
    """How unlikely one body makes a part's last verified pair (ta, da, va) and a later
    part's first (tb, db, vb) (s, m, m/s; arrays): the least acceleration between them
    times the root of the time between (m/s^1.5; a white-noise acceleration's chi: 0.5 ms
    of a leg at 100 m/s^2 is likelier than 12.6 ms at 148); inf where no body moves so:
    between two moving ends, beyond verification.reachable's bound; from or to rest (a
    landing, hidden), further than the faster end's speed and ACCEL_MAX carry it (a leg
    at rest, then 0.3 ms later the other leg 19 mm away)."""
    dt = tb - ta
    fast = np.maximum(np.abs(va), np.abs(vb))
    possible = np.where(np.minimum(np.abs(va), np.abs(vb)) >= fixed_echoes.MOVING_MPS,
                        reachable(ta, da, va, tb, db, vb),
                        np.abs(db - da) <= JUMP_MAX_M + fast * dt + 0.5 * ACCEL_MAX * dt * dt)
    return np.where(possible, _least(ta, da, va, tb, db, vb), np.inf)


def untangled(scene: list[SceneObject], several: bool, paths: list | None = None) -> list[SceneObject]:
    """The scene's objects `parted` and `rejoined` (none across a touch of the movers'
    `paths`, the echo tables' bodies: touches.Touched), each cut at crossings where it
    holds `several` movers or a mover beside another object, joined by contests where it
    holds `several` or its parts do (a sway at its turn a fixed candidate, its tracker and a
    glide's passing between them: a join 33 mm off the trapezoid, the velocity turned
    from +0.65 to -0.61 m/s, gave 171 valid pairs of the sway to the glide), and those
    cut at crossings alone and joined whole `restored` (a new list; `scene` is left as
    it was)."""
    seen = [o for o in scene if o.track.valid.any()]
    asked = handovers.Asked()
    parts = parted(scene, several or (len(seen) >= 2 and any(o.moving for o in seen)), asked)
    several = several or sum(p.moving and p.track.valid.any() for p in parts) >= 2
    return restored(rejoined(parts, several, asked, touches.Touched(paths) if paths else None), scene)


def restored(parts: list[SceneObject], scene: list[SceneObject]) -> list[SceneObject]:
    """`parts` with each object of `scene` that crossings alone cut (objects.bodies keeps
    it one) and that is whole again (the same verified pairs) as it was: its pairs, its
    displacement (a joined track keeps one part's) and its note."""
    was = {id(o.track): o for o in scene if len(objects.bodies(o.track)) == 1}
    return [was[id(p.whole)] if p.whole is not None and id(p.whole) in was
            and np.array_equal(p.track.valid, p.whole.valid) else p for p in parts]
