"""Each mover converted again along its own course: a band per pair (fmcw_cl.course).

A candidate's band is fixed in range, so two movers whose ranges cross share it and its
tracker holds the stronger of them wherever both are in it (a glide through a swaying
object: its candidate's band ended at the sway's, and its lower stretch, in the sway's
band, was the sway tracker's to lose). Once the scene's conversions are made, each
mover's verified pairs say where it is; between them (gaps of up to GAP_S) and beyond
its ends (END_S) a body can only have moved so far (ACCEL_MPS2). So each pair's band in
each direction is the mover's interval there, from its distance to its plain peak
(Doppler-shifted by k v; the de-chirped peak lies at the distance), widened by WIDTH_M
and by what an acceleration could have moved it since its nearest verified pair (at
most MAX_WIDTH_M), and cut half way to every other object's interval there (its plain
peak and its image de-chirped at the mover's velocity) that lies wholly on one side;
where the two intervals overlap, a pair first measured de-chirped at the mover's
velocity (SEED_MPS or faster) is cut half way between its distance and the other's
image, where those are told apart (crossings.MOVERS_M): two sways 13-21 mm apart at 1.2
and 0.85 m/s, their peaks 3-11 mm apart in one direction, which the whole band held,
the tracker passing between them.
Where nothing is known of the mover, or the others overlap it (the two cannot be told
apart; their pairs end `ambiguous`, fmcw_cl.crossings), the candidate's own band stands.
The runs of RUN_PAIRS or more new verified pairs join the mover's old track
(objects.joined); a few new pairs in a crossing would move its parts' ends, which the
scene's rules read (identities). Those rules then judge it as any.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from . import conversions, crossings, fast_echoes, numeric, objects
from .capture import Capture
from .chunks import capture_parts
from .conversions import Converted, First
from .course import Course, lanes, merged
from .course_bodies import ACCEL_MPS2, GAP_S, bodies_of, continuing, fast_bodies_of, going_on
from .processor import ChunkProcessor
from .stages import bank
from .stages.spectrum import GUARD_BINS
from .track import Track

END_S = 0.005         # its course goes on this long beyond its first and last verified pairs
WIDTH_M = 0.006       # the band's half-width about the course at a verified pair
MAX_WIDTH_M = 0.03    # beyond this, the course is not known: the candidate's own band
MAX_SPEED_MPS = 10.0  # ... nor where it runs faster than a robot's leg (a pair of two bodies)
ONE_BODY_M = 0.001    # a gap is bridged where one body can have crossed it (fmcw_cl.stages.verification)
OTHER_GAP_S = 0.005   # another object is where its verified pairs say, across gaps this long
FLOOR_BINS = 16       # bins of a peak's noise floor beyond its guard on each side, where nothing is cut
RUN_PAIRS = 40        # a run of new verified pairs this long (2 ms) is the mover's own stretch
SEED_MPS = bank.MIN_MPS  # a course this fast is first measured de-chirped at its velocity (course.Course)
COURSE_ATTR = "band_along_course"     # a track's attribute: 1 where pairs were taken from its course


def course_of(track: Track, others: list[tuple[Track, bool]], k: tuple[float, float],
              band_m: tuple[float, float | None], room_m: float,
              lines: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> tuple | None:
    """The course of the mover of `track` (its verified pairs, and where it has none
    the points (time s, distance m, velocity m/s) of the echo table's `lines` that go on
    as it: course_bodies.continuing) at each of its pairs' times, in each direction of Doppler
    factors `k` (m per m/s: rising, falling), at least `room_m` (m) either side (the
    peak's noise floor lies beyond its guard), cut half way to each of `others` (track,
    moving) wholly on one side of it (or, at a pair first measured de-chirped, between
    its distance and the other's image there, told apart); `band_m` (m) where it is not
    known. With which pairs it knows, and where the mover can be there (its distance and
    the half-width about it, m); None where it knows none."""
    t, ok = track.time_s, track.valid
    if ok.sum() + (0 if lines is None else lines[0].size) < 2:
        return None
    at = [t[ok], track.distance_m[ok], track.velocity_mps[ok]]
    if lines is not None and lines[0].size:
        order = np.argsort(np.r_[at[0], lines[0]], kind="stable")
        at = [np.r_[a, b][order] for a, b in zip(at, lines, strict=True)]
    r, v, width, known = _bridged(t, at[1], at[2], at[0])
    if not known.any():
        return None
    present = [_where(o, t, moving) for o, moving in others]
    lo_m, hi_m = np.empty((2, t.size)), np.empty((2, t.size))
    # a mover fast enough to smear its plain peak is first measured de-chirped at its velocity
    seed = np.where(known & (np.abs(v) >= SEED_MPS), v, 0.0)
    for j, kj in enumerate(k):
        a, b = np.minimum(r, r + kj * v), np.maximum(r, r + kj * v)
        lo, hi = a - np.maximum(width, room_m), b + np.maximum(width, room_m)
        for seen, r_o, v_o in present:
            p, i = r_o + kj * v_o, r_o + kj * (v_o - v)         # plain peak, image at the mover's velocity
            oa, ob = np.minimum(p, i), np.maximum(p, i)
            below, above = seen & (ob < a), seen & (oa > b)
            lo = np.where(below, np.maximum(lo, 0.5 * (ob + a)), lo)
            hi = np.where(above, np.minimum(hi, 0.5 * (oa + b)), hi)
            # the intervals overlap, but a seeded pair is measured de-chirped, where its
            # peak and the other's image, told apart, are cut half way between them
            both = seen & (seed != 0) & ~below & ~above & (np.abs(i - r) > crossings.MOVERS_M)
            lo = np.where(both & (i < r), np.maximum(lo, 0.5 * (i + r)), lo)
            hi = np.where(both & (i > r), np.minimum(hi, 0.5 * (i + r)), hi)
        lo_m[j] = np.where(known, lo, band_m[0])
        hi_m[j] = np.where(known, hi, np.inf if band_m[1] is None else band_m[1])
    return Course(t, lo_m, np.minimum(hi_m, 1e3), seed), known, (r, width)


def _bridged(t: np.ndarray, r_ok: np.ndarray, v_ok: np.ndarray, t_ok: np.ndarray) -> tuple:
    """Distance, velocity and half-width at times `t` from verified pairs (t_ok, r_ok,
    v_ok): a cubic (Hermite) across gaps of up to GAP_S, straight on at the end's velocity
    for END_S beyond the ends; and whether each time is known (the width at most
    MAX_WIDTH_M)."""
    n = t_ok.size
    b = np.clip(np.searchsorted(t_ok, t), 1, n - 1)      # the verified pairs about each time
    a = b - 1
    ta, tb = t_ok[a], t_ok[b]
    h = np.maximum(tb - ta, 1e-12)
    s = np.clip((t - ta) / h, 0.0, 1.0)
    h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2
    r = h00 * r_ok[a] + h10 * h * v_ok[a] + h01 * r_ok[b] + h11 * h * v_ok[b]
    v = ((6 * s**2 - 6 * s) * r_ok[a] + (3 * s**2 - 4 * s + 1) * h * v_ok[a]
         + (-6 * s**2 + 6 * s) * r_ok[b] + (3 * s**2 - 2 * s) * h * v_ok[b]) / h
    width = WIDTH_M + 0.5 * ACCEL_MPS2 * (t - ta) * (tb - t)
    # one body across the gap: its ends' trapezoid within the verification's bound
    one = np.abs(r_ok[b] - r_ok[a] - 0.5 * (v_ok[a] + v_ok[b]) * h) <= ONE_BODY_M + ACCEL_MPS2 * h**2 / 8
    inside = (t >= t_ok[0]) & (t <= t_ok[-1]) & (h <= GAP_S) & one
    before, after = t < t_ok[0], t > t_ok[-1]
    for end, side in ((0, before), (n - 1, after)):
        dt = t[side] - t_ok[end]
        r[side] = r_ok[end] + v_ok[end] * dt
        v[side] = v_ok[end]
        width[side] = WIDTH_M + 0.5 * ACCEL_MPS2 * dt**2
    known = (inside | ((before | after) & (np.minimum(np.abs(t - t_ok[0]), np.abs(t - t_ok[-1])) <= END_S))
             ) & (width <= MAX_WIDTH_M) & (np.abs(v) <= MAX_SPEED_MPS)
    return r, v, width, known


def _where(track: Track, t: np.ndarray, moving: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where another object is at times `t`: (seen, distance m, velocity m/s), as its
    verified pairs say (interpolated, held beyond its ends): a mover where they lie
    within OTHER_GAP_S of each other about the time; a fixed object all along (its
    band may hold a foot at rest that sets off: it moves there)."""
    ok = track.valid
    if not ok.any():
        return np.zeros(t.size, bool), np.zeros(t.size), np.zeros(t.size)
    t_ok = track.time_s[ok]
    if not moving:
        return (np.ones(t.size, bool), np.interp(t, t_ok, track.distance_m[ok]),
                np.interp(t, t_ok, track.velocity_mps[ok]))
    b = np.clip(np.searchsorted(t_ok, t), 0, t_ok.size - 1)
    a = np.clip(b - 1, 0, t_ok.size - 1)
    near = np.minimum(np.abs(t - t_ok[a]), np.abs(t - t_ok[b]))
    seen = (near <= OTHER_GAP_S) | ((t >= t_ok[a]) & (t <= t_ok[b]) & (t_ok[b] - t_ok[a] <= OTHER_GAP_S))
    return (seen, np.interp(t, t_ok, track.distance_m[ok]), np.interp(t, t_ok, track.velocity_mps[ok]))


def converted_along(cap: Capture, first: First, done: list[Converted], moving: list[bool],
                    processor: ChunkProcessor, seconds, progress, packed: bool = False,
                    lined: bool = False, found: list | None = None, unheld: list | None = None
                    ) -> list[Converted]:
    """`done` with each mover (`moving`; not a track joined of several conversions)
    that another object's path enters converted again along its course (`course_of`;
    with the echo table's lines that go on as it, course_bodies.continuing), in the user's band, on
    its own kind of rows (Plan.still_half), and joined with the runs of RUN_PAIRS or
    more verified pairs that gives where its track had none. `packed` (one
    conversion's plan and choice for all): movers whose courses are known at other
    times share a conversion (course.lanes), each pair in the course known there. `lined`:
    only the movers that lines go on as, and, with `unheld`, those no tracker held.
    `found`: the table's bodies (course_bodies.bodies_of, with fast_bodies_of), where
    already known. A mover that no tracker held (no verified pair) is converted along
    the course of the bodies its band holds (`_untracked`): `unheld`'s
    (unheld_movers.bodies_of), else the velocity bank's."""
    if len(done) < 2 and not lined:
        return done
    m = first.plan.model
    user = first.plan.options.band_m
    room = (GUARD_BINS + FLOOR_BINS) * m.metres_per_bin
    doppler = m.k
    mine = [moving[i] and not d.joined and d.track.valid.any() for i, d in enumerate(done)]
    bare = [moving[i] and not d.joined and not d.track.valid.any() for i, d in enumerate(done)]
    if found is None:
        found = bodies_of(first) + fast_bodies_of(first) if any(mine) else []
    lines = continuing([d.track if w else None for d, w in zip(done, mine, strict=True)], found,
                       [d.track for d in done], [d.track for d, w in zip(done, moving, strict=True) if not w])
    if any(bare) and (not lined or unheld is not None):
        loose = fast_bodies_of(first) if unheld is None else unheld
        short = [] if first.track.echoes is None else fast_echoes.fragments(first.track.echoes.fast)
        held = [d.track for d in done if d.track.valid.any()]
        for i in np.flatnonzero(bare):
            lines[i] = _untracked(loose, held, done[i].choice.band_m, doppler, short)
    wanted = []
    for i, d in enumerate(done):
        if not (mine[i] or (bare[i] and lines[i] is not None)) or (lined and lines[i] is None):
            continue
        others = [(o.track, mv) for o, mv in zip(done, moving, strict=True) if o is not d]
        got = course_of(d.track, others, doppler, d.choice.band_m, room, lines[i])
        if got is None or not (bare[i] or _entered(d.track, others, got[0], got[1], d.choice.band_m)):
            continue
        if conversions.searchable(replace(d.plan.with_band(user), course=got[0]), user):
            wanted.append((i, others, got))
    out = list(done)
    one_each = [[k] for k in range(len(wanted))]
    for lane in lanes([got[1] for _, _, got in wanted], RUN_PAIRS) if packed else one_each:
        if not any(_could_gain(done[j].track, got[1], _run_pairs(bare[j])) for j, _, got in
                   (wanted[k] for k in lane)):
            continue                    # the conversion would change nothing
        d = done[wanted[lane[0]][0]]
        plan = replace(d.plan.with_band(user), course=merged([wanted[k][2][:2] for k in lane]))
        parts = capture_parts(cap, plan, processor, progress=progress)
        # one object's course: the moving spans the target's rule could not choose among
        # (Choice.ambiguous_spans_m) are not its to avoid; the others' paths are cut (`_apart`)
        choice = replace(d.choice, band_m=user, ambiguous_spans_m=np.zeros((0, 2)))
        track = conversions.assembled(plan, parts, processor, seconds, choice, None)
        for i, others, got in (wanted[k] for k in lane):
            # where the course is not known its band is the candidate's own: its own verdict
            # stands; a pair further off than the mover can be is another's, not its; one
            # beside another object is a crossing's, which the parts' ends tell (identities)
            r, width = got[2]
            near = got[1] & (np.abs(track.distance_m - r) <= width) & _apart(track, others, doppler)
            gained = _runs(track.valid & ~done[i].track.valid & near, _run_pairs(bare[i]))
            if gained.any():
                joined = objects.joined(done[i].track, objects.invalidated(track, track.valid & ~gained))
                joined.attrs[COURSE_ATTR] = 1
                out[i] = replace(done[i], plan=plan, parts=parts, track=joined, joined=True)
    return out


def _untracked(fast: list[tuple[np.ndarray, np.ndarray, np.ndarray]], held: list[Track],
               band_m: tuple[float, float | None], k: tuple[float, float] | None = None,
               fragments: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = ()
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The points (time s, distance m, velocity m/s) of the velocity bank's bodies `fast`
    (fast_echoes.bodies) that a mover's `band_m` (m) holds (most of each) and that lie
    on none of the `held` tracks (most of each more than objects.GATE_M from their
    verified pairs, where those lie within OTHER_GAP_S; with the Doppler factors `k`,
    m per m/s, or told apart from them as two movers are), none two at once (the longer
    kept), with those beyond the band that go on as them (objects.seen_again), and the
    bank's `fragments` (fast_echoes.fragments) on none of them that carry that on across
    a fade (fast_echoes.carried): the course of a candidate that no tracker held (its
    plain peaks smeared, or shifted out of its band by their Doppler term). None where
    there are none."""
    hi = np.inf if band_m[1] is None else band_m[1]

    def free(grid: np.ndarray, at: np.ndarray, v: np.ndarray) -> bool:
        on = np.zeros(grid.size, bool)
        for track in held:
            seen, r, v_o = _where(track, grid, True)
            on |= seen & crossings.indistinct(at - r, v - v_o, k)
        return bool(on.mean() < 0.5)

    left = [b for b in sorted(fast, key=lambda b: -b[0].size) if free(*b)]
    mine: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    for grid, at, v in left:
        if np.mean((at >= band_m[0]) & (at <= hi)) >= 0.8 and not any(
                g[0] <= grid[-1] and grid[0] <= g[-1] for g, _, _ in mine):
            mine.append((grid, at, v))
    if not mine:
        return None
    mine += going_on(mine, [b for b in left if not any(b[0] is c[0] for c in mine)])   # not itself again
    course = _in_order(mine)
    more = fast_echoes.carried(course, [f for f in fragments if free(*f)])
    return _in_order([course, *more]) if more else course


def _in_order(parts: list[tuple[np.ndarray, np.ndarray, np.ndarray]]
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The points (time s, distance m, velocity m/s) of `parts`, in time order."""
    t, d, v = (np.concatenate(x) for x in zip(*parts, strict=True))
    order = np.argsort(t, kind="stable")
    return t[order], d[order], v[order]


def objects_along(cap: Capture, first: First, own: list[Converted], scene: list[objects.SceneObject],
                  processor: ChunkProcessor, seconds, progress, lined: bool = False,
                  found: list | None = None, unheld: list | None = None) -> list[objects.SceneObject]:
    """The objects told apart and joined (identities.untangled; `own`: the conversion of
    each), each mover converted again along its course as several candidates'
    conversions are (`converted_along`; `lined`: only those the echo table's lines go
    on as), after the identities: a run gained inside a crossing would move its parts'
    ends, which they read. A lone candidate's parts share one conversion's plan: packed.
    `found`: as `converted_along`'s."""
    done = [replace(d, track=o.track, joined=False, whole=None) for o, d in zip(scene, own, strict=True)]
    done = converted_along(cap, first, done, [o.moving for o in scene], processor, seconds, progress,
                           packed=len({id(d) for d in own}) == 1, lined=lined, found=found, unheld=unheld)
    return [replace(o, track=d.track) for o, d in zip(scene, done, strict=True)]


def _apart(track: Track, others: list[tuple[Track, bool]], k: tuple[float, float] | None = None
           ) -> np.ndarray:
    """Which pairs of `track` lie more than objects.GATE_M from every other object where
    it is (`_where`), or, with the Doppler factors `k` (m per m/s), from every mover
    they are told apart from as two movers are (crossings.movers_apart)."""
    out = np.ones(track.pairs, bool)
    for o, moving in others:
        seen, r_o, v_o = _where(o, track.time_s, moving)
        out &= ~(seen & crossings.indistinct(track.distance_m - r_o, track.velocity_mps - v_o,
                                             k if moving else None))
    return out


def _run_pairs(bare: bool) -> int:
    """The new verified pairs in a row that join a mover's track: RUN_PAIRS (a few in a
    crossing would move its parts' ends, which the identities read), or any where no
    tracker held it (`bare`: it has no parts yet; a sway 5.4 dB under a glide, 35-39 mm
    beyond it at 0.3-0.5 m/s, its pairs `unstable` one in three: movers.py seed 1, capture
    19, 33 -> 52 % of its periods)."""
    return 1 if bare else RUN_PAIRS


def _could_gain(track: Track, known: np.ndarray, pairs: int) -> bool:
    """Whether a conversion along a course known at the pairs `known` can gain `track` a
    run of `pairs` (`_run_pairs`): only the known pairs its tracker did not verify can
    join it (a sway crossed by a glide stronger than itself, verified throughout: 0.2 s
    of a 2.5 s capture's CPU for nothing)."""
    return bool(_runs(known & ~track.valid, pairs).any())


def _runs(new: np.ndarray, pairs: int) -> np.ndarray:
    """The pairs of `new` in runs of at least `pairs` consecutive ones."""
    out = np.zeros(new.size, bool)
    for a, b in numeric.runs(new):
        if b - a >= pairs:
            out[a:b] = True
    return out


def _entered(track: Track, others: list[tuple[Track, bool]], course: Course, known: np.ndarray,
             band_m: tuple[float, float | None]) -> bool:
    """Whether the course reaches where its band does not (beyond the candidate's band)
    or another object's verified pairs lie inside the candidate's band (the band is
    shared)."""
    hi = np.inf if band_m[1] is None else band_m[1]
    beyond = known & ((course.lo_m.min(axis=0) < band_m[0]) | (course.hi_m.max(axis=0) > hi))
    if beyond.any():
        return True
    for o, _ in others:
        d = o.distance_m[o.valid]
        if np.any((d >= band_m[0]) & (d < hi)):
            return True
    return False
