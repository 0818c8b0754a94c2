"""A mover that shares a lone candidate's band but that no tracker held.

Two movers within one moving span are one candidate (fmcw_cl.objects): its tracker
follows one echo at a time, and a weaker mover it never held leaves no part to tell
apart (a hand 3.3 dB under the jump at -1.5 to -2 m/s across it: one object, the hand
in none of its periods). A mover faster than about 1 m/s leaves no plain peak, but the
velocity bank (fmcw_cl.fast_echoes) sees it; a slower one leaves the echo table a body
that travels (`bodies_of`): its bodies that lie on no verified pair of the candidate's
(along._untracked) are an object of their own, holding no pair yet,
converted along their course once the identities are told, as a candidate no tracker
held is (along.converted_along). Not where the tables show several candidates: a leg's
take-off so made an object (seed 1 of benchmarks/objects.py's two legs 40 ms apart)
and the legs' coherence cuts then left them in pieces (80 / 40 -> 43 / 31 %).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from . import along, course_bodies, fixed_echoes, moving_echoes, objects
from .stages import faults
from .track import Track

SLOW_TRAVEL_M = fixed_echoes.MIN_TRAVEL_M   # an echo table's body that travels this far is a mover's


def bodies_of(fast: list[tuple[np.ndarray, np.ndarray, np.ndarray]],
              plain: list[tuple[np.ndarray, np.ndarray, np.ndarray]], held: list[Track]
              ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The bodies a mover no tracker held may leave: the velocity bank's `fast`, and the
    echo table's `plain` (course_bodies.bodies_of) that travel SLOW_TRAVEL_M or more and
    lie on no harmonic of a `held` track (2 and 3 times its distance, within
    fixed_echoes.APART_M, for most of their points): a sway 5.4 dB under a glide, 35-39
    mm beyond it at 0.1-0.5 m/s, too slow to smear its plain peak (movers.py seed 1,
    capture 19)."""
    slow = [b for b in plain if np.ptp(b[1]) >= SLOW_TRAVEL_M and not _harmonic(b[0], b[1], held)]
    return list(fast) + slow


def _harmonic(t: np.ndarray, d: np.ndarray, held: list[Track]) -> bool:
    """Whether most of a body's distances `d` (m, at `t` s) lie within
    fixed_echoes.APART_M of two or three times a `held` track's verified distance then."""
    on = np.zeros(t.size, bool)
    for track in held:
        ok = track.valid
        if ok.sum() < 2:
            continue
        on |= moving_echoes.on_multiples(d, np.interp(t, track.time_s[ok], track.distance_m[ok]),
                                         moving_echoes.HARMONICS)
    return bool(on.mean() > 0.5)


def unheld(loose: list[tuple[np.ndarray, np.ndarray, np.ndarray]],
           plain: Callable[[], list[tuple[np.ndarray, np.ndarray, np.ndarray]]], held: list[Track],
           band_m: tuple[float, float | None], moving: list[bool], k: tuple[float, float]
           ) -> objects.SceneObject | None:
    """A moving object holding no pair (`bare`) where the bodies `loose` (`bodies_of`: the
    velocity bank's and the echo table's that travel) in `band_m` (m) lie on none of the
    `held` tracks, clear of
    them (course_bodies.clear), and go on as none of the movers among them (`moving`;
    course_bodies.continuing, with the echo table's bodies `plain()`, course_bodies.bodies_of:
    a glide's own body beyond its part's end, which its course then took, made a second
    object of it and the crossing check left both `ambiguous` there: 96 -> 28 % of its
    periods, movers.py seed 1, capture 16; a fixed part is converted along no course, and
    a weak glide's 2 ms held as one kept the bank's body of its next 100 ms: 1 % of its
    periods, seed 2, capture 33); else None."""
    clear = [b for b in loose if course_bodies.clear(*b[:2], held, b[2], k)] if held else []
    if not clear:            # the common case
        return None
    goes = [t if m else None for t, m in zip(held, moving, strict=True)]
    # the slow ones among them are the echo table's own (`bodies_of`): each body once
    table = plain()
    found = table + [b for b in clear if not any(b is p for p in table)]
    rests = [t for t, m in zip(held, moving, strict=True) if not m]
    taken = [c[0] for c in course_bodies.continuing(goes, found, held, rests) if c is not None]
    if taken:
        clear = [b for b in clear if np.mean(np.isin(b[0], np.concatenate(taken))) < 0.5]
    if along._untracked(clear, held, band_m, k) is None:
        return None
    return objects.SceneObject(0, True, bare(held[0]),
                               "a mover no tracker held: its bodies in the echo tables")


def with_unheld(scene: list[objects.SceneObject], loose: list, plain: Callable[[], list],
                band_m: tuple[float, float | None], k: tuple[float, float],
                convert: Callable[[list[objects.SceneObject]], list[objects.SceneObject]]
                ) -> list[objects.SceneObject]:
    """`convert(scene)` (its objects converted along their courses, along.objects_along)
    with, last, a bare object of the bodies `loose` (`bodies_of`) that go on as none
    of its movers (`unheld`; `plain`, `band_m` as there), converted along its course with
    them, unless it is a twin (`without_twin`)."""
    kept = [o for o in scene if o.track.valid.any()]
    bare = unheld(loose, plain, [o.track for o in kept], band_m, [o.moving for o in kept], k)
    return convert(scene) if bare is None else without_twin(convert(scene + [bare]))


def without_twin(scene: list[objects.SceneObject]) -> list[objects.SceneObject]:
    """`scene` without its last object (the bare one, once converted along its course)
    where it holds no pair, or half its verified pairs or more lie within
    objects.GATE_M of another object (along._apart): that object's twin, its course the
    bank's bodies that went on as a part (a glide's 123 pairs, 1871 along its course,
    1123 of them on the bare object: the crossing check left both `ambiguous` there, 57
    -> 22 % of its periods; movers.py seed 1, capture 1; seed 2, capture 27, the foot
    91 -> 56 %). A mover of its own lies apart but where it crosses (two hands: under 1 %
    of their 1507 and 1112 pairs)."""
    *rest, last = scene
    ok = last.track.valid
    if not ok.any():
        return rest
    near = ~along._apart(last.track, [(o.track, o.moving) for o in rest])
    return rest if np.mean(near[ok]) >= 0.5 else scene


def bare(track: Track) -> Track:
    """A copy of `track` holding no pair: each one `no_echo`, without a value."""
    out = objects.invalidated(track, track.valid, faults.NO_ECHO)
    for name in objects.VALUES:
        if getattr(out, name) is not None:
            setattr(out, name, np.full(out.pairs, np.nan))
    out.reason = np.full(out.pairs, faults.NO_ECHO, np.uint8)
    if out.sweep_reason is not None:
        out.sweep_reason = np.full(out.sweep_reason.size, faults.NO_ECHO, out.sweep_reason.dtype)
    objects.no_displacement(out)
    objects.recount(out)
    return out
