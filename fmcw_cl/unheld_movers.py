"""A mover that shares a candidate's band but that no tracker held.

Two movers within one moving span are one candidate (fmcw_cl.objects): its tracker
follows one echo at a time, and a weaker mover it never held leaves no part to tell
apart (a hand 3.3 dB under the jump at -1.5 to -2 m/s across it: one object, the hand
in none of its periods). A mover faster than about 1 m/s leaves no plain peak, but the
velocity bank (fmcw_cl.fast_echoes) sees it; a slower one leaves the echo table a body
that travels (`bodies_of`): its bodies that lie on no verified pair of the candidates'
(along._untracked) are an object of their own, holding no pair yet,
converted along their course once the identities are told, as a candidate no tracker
held is (along.converted_along), beside one candidate or several (a leg landing at 5
m/s onto the ground where the other foot rests, whose moving candidate's tracker held
the resting foot: 1 -> 34 % of the landing leg's periods). A body whose plain peak in
one direction stays at a fixed echo is no body (`_image`)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from . import along, course_bodies, fixed_echoes, moving_echoes, objects
from .stages import faults
from .track import Track

SLOW_TRAVEL_M = fixed_echoes.MIN_TRAVEL_M   # an echo table's body that travels this far is a mover's
IMAGE_M = 3e-3          # a body whose plain peak in one direction lies this near a fixed echo ...
IMAGE_SHARE = 0.8       # ... at this share of its points is that echo's peak paired with another's


def bodies_of(fast: list[tuple[np.ndarray, np.ndarray, np.ndarray]],
              plain: list[tuple[np.ndarray, np.ndarray, np.ndarray]], held: list[Track],
              fixed_m=(), k: tuple[float, float] = (0.0, 0.0)
              ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The bodies a mover no tracker held may leave: the velocity bank's `fast`, and the
    echo table's `plain` (course_bodies.bodies_of) that travel SLOW_TRAVEL_M or more and
    lie on no harmonic of a `held` track (2 and 3 times its distance, within
    fixed_echoes.APART_M, for most of their points): a sway 5.4 dB under a glide, 35-39
    mm beyond it at 0.1-0.5 m/s, too slow to smear its plain peak (movers.py seed 1,
    capture 19); none that is a fixed echo's image (`_image`; `fixed_m`: the tables'
    fixed echoes, m; `k`: the Doppler factors, m per m/s, rising and falling)."""
    slow = [b for b in plain if np.ptp(b[1]) >= SLOW_TRAVEL_M and not _harmonic(b[0], b[1], held)]
    return [b for b in list(fast) + slow if not _image(b[1], b[2], fixed_m, k)]


def _image(d: np.ndarray, v: np.ndarray, fixed_m: np.ndarray, k: tuple[float, float]) -> bool:
    """Whether a body (distances `d` m, velocities `v` m/s) has its plain peak in one
    direction (d + k v, `k` that direction's m per m/s) within IMAGE_M of one of the fixed
    echoes `fixed_m` (m) at IMAGE_SHARE of its points: a fixed echo's peak in that
    direction paired with a mover's in the other solves to a body half way between them
    whose velocity can follow its distance for a while (a hand coming down at -1.3 m/s
    past a foot at rest at 0.070 m: a body 10 mm beyond the hand, 14 ms long, its falling
    peak 1-2 mm from the foot's; made an object, its course made the foot's and the
    hand's pairs `ambiguous`: 93 / 100 -> 72 / 86 % of their periods, movers.py seed 3,
    capture 12). A mover's own peak stays still so only while its velocity decays as
    exp(-t / |k|) (29 ms), and at a fixed echo's distance by chance."""
    fixed_m = np.asarray(fixed_m, float)
    if not fixed_m.size:
        return False
    for kd in k:
        peak = d + kd * v
        near = np.min(np.abs(peak[:, None] - fixed_m[None, :]), axis=1) <= IMAGE_M
        if np.mean(near) >= IMAGE_SHARE:
            return True
    return False


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
