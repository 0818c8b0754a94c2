"""Each object of the scene converted in a band of its own (fmcw_cl.objects says the rules).

`objects_of` takes the first conversion (its track, measurements and tables) and the
target's conversion, converts every other candidate in its own band, and returns the
objects, the target among them by the user's rule.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from functools import cache

import numpy as np

from . import (
    along,
    coherence,
    conversions,
    course_bodies,
    crossings,
    exchanges,
    fast_echoes,
    fixed_echoes,
    identities,
    lone_bodies,
    meeting,
    moving_echoes,
    objects,
    rest_spans,
    rests,
    target,
    unheld_movers,
)
from .capture import Capture
from .conversions import Converted, First
from .processor import ChunkMeasurements, ChunkProcessor
from .stages import faults, phase
from .track import Track


def objects_of(cap: Capture, first: First, choice: target.Choice, own: Converted, processor: ChunkProcessor,
               seconds: Callable[[], float], progress=None
               ) -> tuple[list[objects.SceneObject], int, Converted]:
    """The scene's objects, the index of the target among them and its conversion: the
    candidates of `first`'s tables (objects.candidates), the target's own conversion
    `own` (made under `choice`) standing for the one it holds, each other one converted
    by `processor` in its band (`seconds()`: the time spent so far, for the tracks)."""
    options = first.plan.options
    tr = first.track
    band = options.band_m
    spans = sorted(fixed_echoes.moving_spans(tr.time_s, tr.distance_m, tr.velocity_mps, tr.valid,
                                             fixed_echoes.smeared(tr.echoes, band)) + list(first.beside))
    m = first.plan.model
    fast = fast_echoes.bodies(fast_echoes.outside(tr.echoes.fast, spans))
    spans = moving_echoes.joined(spans, moving_echoes.unheld(tr.echoes, m.k_rise, m.k_fall, tr, band, spans,
                                                             fast))
    made: dict[tuple, list[ChunkMeasurements]] = {first.plan.options.band_m: first.parts,
                                                 own.plan.options.band_m: own.parts}
    extra: list[tuple[float, float]] = []
    two = bool(objects.parts_of(own.track))       # the target's conversion held two echoes
    for _ in range(2):                   # once more where a tracker still held two echoes
        cands = objects.candidates(first.fixed, sorted(spans + extra), choice, band)
        if len(cands) <= 1 and not extra and not two:
            return _lone(cap, first, own, bool(choice.moving), processor, seconds, progress)
        # the target's conversion stands for the candidate it holds, unless it held two echoes
        share = [objects.holds(own.track, c) for c in cands]
        held = int(np.argmax(share)) if share and max(share) >= 0.5 and not two else None
        mine = held if held is not None and _stands_for(own, cands[held], first.beside) else None
        done = [own if i == mine else conversions.convert(cap, first, c, spans + extra, made, processor,
                                                          seconds, progress, own if i == held else None)
                for i, c in enumerate(cands)]
        # a fixed object's measurements without its rest's bounds: what else its band holds
        loose = {id(d.track): conversions.again(d, replace(d.choice, at_rest_m=None), processor, seconds)
                 for d in done if d.choice.at_rest_m is not None}
        movers = [(c.lo, c.hi) for c in cands if c.moving]
        found = [s for d in done for s in objects.parts_of(d.track) + _passing(d, loose.get(id(d.track)))
                 if not fixed_echoes.beside_span(0.5 * (s[0] + s[1]), movers)]
        if not found or extra:
            break
        extra = found
    done = _at_rest(cap, done, loose, first, made, processor, seconds, progress)
    done = _distinct(done, first, seconds, processor)
    done = rest_spans.bounded(done, [_moving(d) for d in done], processor, seconds)
    moving = any(_moving(d) for d in done)
    table = cache(lambda: course_bodies.bodies_of(first))
    plain = table() if moving else []
    done = along.converted_along(cap, first, done, [_moving(d) for d in done], processor, seconds, progress,
                                 found=plain)
    # the velocity bank's bodies carry courses once the identities are told: before, the
    # pairs they gained moved the parts' ends that the joins read (a glide split in two)
    fast = course_bodies.fast_bodies_of(first)
    lines = []
    if plain or any(_moving(d) for d in done):
        lines = table() + fast
    unseen = {(i, j) for i, d in enumerate(done) for j in _unseen(d, done, first)}
    done = _unveiled(done, unseen, seconds, processor)
    done = _exclusive(done, unseen, first, seconds, processor)
    found = [objects.SceneObject(0, _moving(d), d.track, d.choice.note) for d in done]
    several = sum(o.moving and o.track.valid.any() for o in found) >= 2
    of = {id(d.track): d for d in done}

    # a mover no tracker held, which the velocity bank saw or whose echo table's body
    # travels, as beside a lone candidate (`_lone`)
    k = first.plan.model.k
    loose = unheld_movers.bodies_of(fast, table(), [d.track for d in done], _fixed_m(first), k) \
        if options.dechirp else []

    def lined(scene: list[objects.SceneObject]) -> list[objects.SceneObject]:
        conv = [of.get(id(o.track if o.whole is None else o.whole), own) for o in scene]
        return along.objects_along(cap, first, conv, scene, processor, seconds, progress, lined=True,
                                   found=lines, unheld=loose)

    return _told_apart(found, done, own, options, several, courses=lambda scene: (
        unheld_movers.with_unheld(scene, loose, table, own.choice.band_m, k, lined)), paths=lines)


def _fixed_m(first: First) -> np.ndarray:
    """The distances (m) of every fixed echo `first`'s tables list."""
    return np.array([d for d, _ in first.fixed.listed], float)


def _lone(cap: Capture, first: First, own: Converted, moving: bool, processor: ChunkProcessor,
          seconds: Callable[[], float], progress) -> tuple[list[objects.SceneObject], int, Converted]:
    """`objects_of` where the tables show one candidate, held by `own`: one object, or its
    parts where its tracker held two bodies or more (lone_bodies), or a mover its tracker
    never held (unheld_movers) beside it."""
    options = first.plan.options
    # without the de-chirp (the paper's method) a mover's peaks smear over centimetres
    # and pass between bodies within one: the test is the de-chirped tracker's
    bodies, body = lone_bodies.count(own.track, moving) if options.dechirp else (1, own.track)
    # a mover its tracker never held, which the velocity bank saw or whose echo table's
    # body travels (none on the paper's method); the echo table's bodies (a loop in
    # Python: 10 ms on the 0.3 s jump alone, up to 0.2 s on a full table) sought once
    fast = course_bodies.fast_bodies_of(first) if options.dechirp else []
    plain = cache(lambda: course_bodies.bodies_of(first))
    k = first.plan.model.k
    loose = unheld_movers.bodies_of(fast, plain(), [own.track], _fixed_m(first), k) if options.dechirp else []
    bare = unheld_movers.unheld(loose, plain, [own.track], own.choice.band_m, [moving], k)
    if body is own.track and bodies < 2 and bare is None:
        return [objects.SceneObject(1, moving, own.track, "the target: no other echo")], 0, own
    if bodies < 2 and bare is None:     # another echo held briefly: its pairs ambiguous
        return ([objects.SceneObject(1, moving, body, "the target: another echo held at once "
                                     "is ambiguous")], 0, replace(own, track=body, whole=own.track))
    # one candidate, two bodies or more: its parts are the objects, as two
    # candidates' are, its tuning and its rest still the conversion's (`whole`)
    found = [objects.SceneObject(0, moving, own.track if bodies >= 2 else body,
                                 f"{own.choice.note}: two bodies or more" if bodies >= 2
                                 else own.choice.note)]

    def courses(scene: list[objects.SceneObject]) -> list[objects.SceneObject]:
        held = any(o.moving and o.track.valid.any() for o in scene)    # as converted_along asks
        return along.objects_along(cap, first, [own] * len(scene), scene, processor, seconds, progress,
                                   found=plain() + fast if held else [], unheld=loose)

    return _told_apart(found, [own], own, options, True, lone=True, courses=lambda scene: (
        unheld_movers.with_unheld(scene, loose, plain, own.choice.band_m, k, courses)),
        paths=plain() + fast)


def _told_apart(found: list[objects.SceneObject], done: list[Converted], own: Converted, options,
                several: bool, lone: bool = False,
                courses: Callable[[list[objects.SceneObject]], list[objects.SceneObject]] | None = None,
                paths: list | None = None) -> tuple[list[objects.SceneObject], int, Converted]:
    """`objects_of`'s objects from the conversions `done` (`found`: an object each):
    bodies told apart (identities.untangled, by contests where `several` movers may be,
    none joined across a touch of the echo tables' bodies `paths`), with pairs along
    their `courses` where given (along.objects_along: a lone candidate's parts;
    several conversions' movers the echo table's lines go on as) and
    the parts those carried to meet joined (meeting.met), numbered in the order they
    were seen, the target chosen by the user's rule. Each object's pairs are `ambiguous`
    where another's course passes within objects.GATE_M (crossings.passing); a `lone`
    candidate's, whose one tracker held one echo at a time, also where another's path
    does (crossings.conflicts, as `_exclusive` for several conversions: two legs landing
    0.3 mm apart, the tracker passing from one to the other, 183 valid pairs on the
    other), a still part's only while it is seen (a body at rest while held, not a fixed
    echo there all along: two sways' turns so taken spanned the other's path); and where
    its pairs' phases do not move as one body's (coherence.two_bodies: a rail's
    Doppler-shifted peak in one direction, a glide's in the other, made 74 valid pairs
    46 mm from both as they crossed); and where a half-sweep's peak could be another
    object's de-chirped image (crossings.images, as `_exclusive` across conversions, but
    on the objects told apart; not a still object's in rows without still echoes); and
    where a fixed object's pairs read moving (crossings.read_moving)."""
    of = {id(d.track): d for d in done}
    scene = exchanges.apart(rests.rests_parted(identities.untangled(found, several, paths)),
                           [o.track for o in found if not o.moving])
    if courses is not None:       # pairs along a body's course, once its identity is told
        scene = meeting.met(courses(scene))
    tracks, moving = [o.track for o in scene], [o.moving for o in scene]
    rad_per_m = phase.radians_per_metre(own.plan.lut.nu_hz, own.plan.info.refractive_index)
    two = [coherence.two_bodies(t, rad_per_m) for t in tracks]
    doppler = own.plan.model.k
    clash = crossings.passing(tracks, doppler, [not m for m in moving])
    # the objects' own images of each other (`_exclusive` looked across conversions,
    # before their parts were told apart): a sway's part de-chirped at -3.48 m/s held a
    # glide's image, 18 pairs
    image = crossings.images(tracks, own.plan.model, own.plan.window, _calm_unseen(scene, of, own))
    clash = [c | m | r for c, m, r in zip(clash, image, crossings.read_moving(tracks, moving), strict=True)]
    if lone:
        paths = crossings.conflicts(tracks, k=doppler)
        clash = [c | p for c, p in zip(clash, paths, strict=True)]
    clash = [c | _brief_rest(o, c | w) for o, c, w in zip(scene, clash, two, strict=True)]
    movers = [o.track for o in scene if o.moving]
    cut = [coherence.cuts(o.track, w, [t for t in movers if t is not o.track])
           for o, w in zip(scene, two, strict=True)]
    scene = [p for o, c, w, k in zip(scene, clash, two, cut, strict=True) for p in _taken(o, c, w, k)]
    scene.sort(key=lambda o: (o.attrs()["first_seen_s"] if o.track.valid.any() else np.inf,
                              o.attrs()["distance_span_m"][0]))
    for k, o in enumerate(scene, 1):
        o.id = k
    try:
        pick = objects.choose(scene, options.target, options.target_near)
    except ValueError:
        pick = 0
    if pick < 0:                # the target's choice told one (6c): the object its pairs lie on stands
        on = [_same_echo(o.track, own.track) for o in scene]
        pick = int(np.argmax(on)) if max(on) else pick
    # a target joined of two conversions is re-converted by neither: the plan, the tuning
    # and the rest of the one holding most of its pairs stand (the other's unverified
    # stretches are not its echo: a glide joined across two read 7.5x the window's width)
    mine = scene[max(pick, 0)]
    origin = mine.track if mine.whole is None else mine.whole
    conv = of.get(id(origin))
    if conv is None:
        conv = max(done, key=lambda d: (_same_echo(d.track, mine.track), d.track.valid.any()), default=own)
        return scene, pick, replace(conv, track=mine.track, whole=conv.track)
    return scene, pick, replace(conv, track=mine.track, whole=mine.whole)


def _calm_unseen(scene: list[objects.SceneObject], of: dict, own: Converted) -> set[tuple[int, int]]:
    """(i, j): object i was converted on rows without still echoes (Plan.still_half) and
    object j is still (crossings.still): no image of j lies in i's rows (`_unseen`)."""
    wl = own.plan.lut.wavelength_m
    calm = [j for j, o in enumerate(scene) if not o.moving and crossings.still(o.track, wl)]
    conv = [of.get(id(o.track if o.whole is None else o.whole)) for o in scene]
    free = [i for i, d in enumerate(conv) if d is not None and d.plan.still_half]
    return {(i, j) for i in free for j in calm if i != j}


def _brief_rest(o: objects.SceneObject, taken: np.ndarray) -> np.ndarray:
    """The verified pairs of `o` not `taken` where it is a still part cut from a moving
    track with fewer of them than the phases' window (coherence.WINDOW): nothing vouches
    that one body made them. Where a mover's peak in one direction and another's in the other
    coincide, pairs of the two read still there (movers.py seed 22, capture 7: the jump
    falling at 1.84 m/s and a hand rising at 2.41 m/s, both shifted to 0.24 m; four
    sparse pairs at 0.245 m, 47 mm from either, a fixed object of their own)."""
    left = o.track.valid & ~taken
    brief = not o.moving and o.whole is not None and left.sum() < coherence.WINDOW
    return left if brief and objects.moves(o.whole) else np.zeros(o.track.pairs, bool)


def _taken(o: objects.SceneObject, clash: np.ndarray, two: np.ndarray,
           cut: np.ndarray) -> list[objects.SceneObject]:
    """`o` with its valid pairs `clash` (another's echo beside them) and `two` (two
    bodies' phases: coherence.two_bodies, a subset of its valid pairs) `ambiguous`;
    where `two` took any, the pairs left verified again among themselves, and the
    object cut at the times `cut` (s: coherence.cuts, where its tracker came out of two
    bodies on one, nothing telling which)."""
    if not ((clash | two) & o.track.valid).any():
        return [o]
    track = objects.invalidated(o.track, clash | two)
    if not two.any():
        return [replace(o, track=track)]
    track = coherence.verified_again(track)
    parts = identities.cut_at([track.valid], cut, track.time_s)
    if len(parts) < 2:
        return [replace(o, track=track)]
    whole = replace(o, track=track, whole=o.track if o.whole is None else o.whole)
    return identities.split(whole, parts, "it held two bodies between its parts")


def _same_echo(a: Track, b: Track) -> int:
    """How many pairs both tracks verify on one echo (within objects.GATE_M): verified
    at one instant alone, a wall's pairs and a foot's are not the same (a landing
    beside two walls: its rest was the target's, the wall verified all along was
    /track, 999 pairs 150-210 mm off the foot; benchmarks/hunt.py seed 1, capture 59)."""
    both = a.valid & b.valid
    return int(np.sum(np.abs(a.distance_m[both] - b.distance_m[both]) <= objects.GATE_M))


def _stands_for(own: Converted, c: objects.Candidate, beside: list[tuple[float, float]]) -> bool:
    """Whether the target's own conversion `own`, which holds candidate `c` alone, is
    its conversion: its band covers the candidate's span, no fixed object lies inside
    that span (a moving echo is then tracked on each side of them) and no second look
    found it (`beside`; then on rows without still echoes: `conversions.convert`)."""
    lo, hi = own.choice.band_m
    covered = lo <= c.lo and (hi is None or hi >= c.hi)
    return covered and not (c.moving and own.choice.ambiguous_m.size) and not conversions.looked(c, beside)


def _moving(d: Converted) -> bool:
    """A moving span's object moves; an echo of the mean spectra moves where its track does."""
    return d.candidate.moving or (not d.candidate.fixed and objects.moves(d.track))


def _at_rest(cap: Capture, done: list[Converted], loose: dict[int, Track], first: First, made: dict,
             processor: ChunkProcessor, seconds, progress) -> list[Converted]:
    """`done` with each mover whose choice left a fixed echo ambiguous that is its own
    rest (`_rests`), that ambiguity holding as many of its pairs as it verified,
    assembled on its band's plain rows without it (a foot at rest by a stronger wall,
    which the first conversion followed, so that the rest was "seen while the target
    was away"; then off 7 mm in 9 ms: every pair `ambiguous`, the wall taken for the
    target), and each fixed echo that is a mover's rest, no mover holding it, as that
    mover (its pairs without the rest's bounds: the foot moving 3 mm, every pair faster
    than MOVING_MPS `ambiguous`; `loose`: each fixed conversion's pairs without its
    rest's bounds, by id of its track). `_distinct` then drops twins."""
    out, rests = list(done), set()
    for k, o in enumerate(done):
        if not (o.candidate.moving and np.sum(o.track.reason == faults.AMBIGUOUS) >= o.track.valid.sum()):
            continue
        for m, d in enumerate(done):
            near = np.abs(o.choice.ambiguous_m - d.candidate.centre_m) <= fixed_echoes.APART_M
            if not (d.candidate.fixed and near.any()):
                continue
            plan, parts = conversions.measured(cap, first, o.choice.band_m, 0, made, processor, progress)
            said = o.choice.note.removesuffix(target.passes(o.choice.ambiguous_m)) + _rest(d)
            choice = replace(o.choice, ambiguous_m=o.choice.ambiguous_m[~near],
                             note=said + target.passes(o.choice.ambiguous_m[~near]))
            plain = conversions.assembled(plan, parts, processor, seconds, choice, None)
            if _rests(d.track, plain):
                out[k] = Converted(o.candidate, choice, plan, parts, plain)
                rests.add(m)
                break
    for m, d in enumerate(done):
        free = loose.get(id(d.track))
        if d.candidate.fixed and d.track.valid.any() and m not in rests and _rests(d.track, free):
            choice = replace(d.choice, at_rest_m=None, note=d.choice.note + _rest(d))
            track = replace(free, attrs={**free.attrs, **choice.attrs()})
            out[m] = Converted(replace(d.candidate, moving=True, fixed=False), choice, d.plan, d.parts, track)
    return out


def _rest(d: Converted) -> str:
    return f"; the fixed echo at {d.candidate.centre_m:.3f} m is its rest"


def _rests(rest: Track, mover: Track) -> bool:
    """Whether `mover` runs as its velocities say (objects.runs) and holds SAME_SHARE of
    `rest`'s verified pairs within SAME_M (if any: else nothing stays there to be told
    from it): `rest` is where it lay."""
    held = mover.valid & (np.abs(mover.distance_m - rest.distance_m) <= objects.SAME_M)
    share = held[rest.valid].mean() if rest.valid.any() else 1.0
    return objects.runs(mover) and bool(share >= objects.SAME_SHARE)


def _passing(d: Converted, loose: Track | None) -> list[tuple[float, float]]:
    """The spans (m) of what moves through a fixed object's band: its measurements
    assembled without the fixed object's bounds (target.Choice.at_rest_m: `loose`), the
    moving spans of their verified pairs more than APART_M from it (a rail passing a
    swaying cable, beyond it)."""
    if loose is None:
        return []
    away = np.abs(loose.distance_m - d.choice.at_rest_m) > fixed_echoes.APART_M
    return fixed_echoes.moving_spans(loose.time_s, loose.distance_m, loose.velocity_mps, loose.valid & away,
                                     np.zeros(0))


def _distinct(done: list[Converted], first: First, seconds, processor) -> list[Converted]:
    """The conversions less those that follow the same echo as another (objects.same):
    the moving one kept, else the one with more verified pairs. A kept moving echo that
    a fixed one's track followed (a target slowing onto its plateau, a fixed echo of the
    tables) is no longer ambiguous where it passes that fixed echo: assembled again."""
    out: list[Converted] = []
    for d in sorted(done, key=lambda d: (not d.candidate.moving, -int(d.track.valid.sum()))):
        twin = next((k for k, o in enumerate(out) if objects.same(d.track, o.track)), None)
        if twin is None:
            out.append(d)
            continue
        o = out[twin]
        if d.candidate.fixed and o.choice.ambiguous_m.size and not o.joined:
            keep = np.abs(o.choice.ambiguous_m - d.candidate.centre_m) > fixed_echoes.APART_M
            choice = replace(o.choice, ambiguous_m=o.choice.ambiguous_m[keep])
            out[twin] = replace(o, choice=choice, track=conversions.again(o, choice, processor, seconds))
    return out


def _exclusive(done: list[Converted], unseen: set[tuple[int, int]], first: First, seconds, processor
               ) -> list[Converted]:
    """Each conversion assembled again where another object's path comes within
    objects.GATE_M of its own, a harmonic of another's (crossings.harmonics) or its
    de-chirped image (crossings.images): those pairs `ambiguous` (target.Choice.taken_s),
    and so is a pair verified only once they are taken out (not checked against the others).
    Not by an object that the conversion's rows hold nothing of (`unseen`: (i, j), `_unseen`)."""
    tracks, moving = [d.track for d in done], [_moving(d) for d in done]
    model = first.plan.model
    clash = crossings.conflicts(tracks, [not m for m in moving], unseen, model.k,
                                [d.choice.there_s for d in done])
    ghost = crossings.harmonics(tracks, first.plan.lut.unambiguous_range_m)
    image = crossings.images(tracks, model, first.plan.window, unseen)
    out = []
    for d, c, g, m in zip(done, clash, ghost, image, strict=True):
        c = (c | g | m) & d.track.valid
        if c.any() and d.joined:            # several bands' track: its pairs taken as they stand
            d = replace(d, track=objects.invalidated(d.track, c))
        elif c.any():
            choice = replace(d.choice, taken_s=np.sort(d.track.time_s[c]))
            again = conversions.again(d, choice, processor, seconds)
            # the tests above saw the pairs valid before: one verified only now is unchecked
            objects.invalidate(again, again.valid & ~d.track.valid)
            d = replace(d, choice=choice, track=again)
        out.append(d)
    return out


def _unseen(d: Converted, done: list[Converted], first: First) -> list[int]:
    """The objects among `done` that conversion `d`'s rows hold nothing of: where its
    rows are without still echoes (Plan.still_half; not a track joined of several
    conversions), the still objects (crossings.still) near which its own echo table
    lists no fixed object (`conversions.held`: a cable that trembles a micrometre stays in these
    rows)."""
    if not d.plan.still_half or d.joined:
        return []
    there = conversions.held(d.track, first)
    wl = first.plan.lut.wavelength_m
    return [k for k, o in enumerate(done) if o is not d and not _moving(o) and crossings.still(o.track, wl)
            and np.all(np.abs(there - objects.where_m(o.track)) > fixed_echoes.APART_M)]


def _unveiled(done: list[Converted], unseen: set[tuple[int, int]], seconds, processor) -> list[Converted]:
    """The conversions on rows without still echoes assembled again without the gate
    about the objects their rows hold nothing of (`unseen`: (i, j), `_unseen`): a foot
    that moves 2 mm from a window is the foot's."""
    out = []
    for i, d in enumerate(done):
        calm = [objects.where_m(done[j].track) for k, j in unseen if k == i]
        if calm and d.choice.ambiguous_m.size:
            keep = np.array([all(abs(f - c) > fixed_echoes.APART_M for c in calm)
                             for f in d.choice.ambiguous_m])
            if not keep.all():
                choice = replace(d.choice, ambiguous_m=d.choice.ambiguous_m[keep])
                d = replace(d, choice=choice, track=conversions.again(d, choice, processor, seconds))
        out.append(d)
    return out
