"""Where another mover's path touches a tracked mover's: two bodies as one echo there.

Where another mover's echo lies within a range resolution of a track's (fixed_echoes.ONE_M)
at a velocity alike (objects.alike: one body's within STEADY_S), nothing in the track
tells which of the two it follows on after (a leg at rest on its plateau at 0.282 m,
the other leg arriving beside it and braking as the first set off again, their
velocities crossing at +0.35 m/s: the tracker stepped onto their one peak, then held
the second at rest, and its parts either side, seen again at rest 4.8 ms apart, were
joined: 1147 valid pairs of one leg on the other's objects, movers.py seed 33,
capture 35). The other mover's path is known where the echo tables saw it
(course_bodies.bodies_of, .fast_bodies_of): one that touches a part's first (last)
verified pairs and parts from it beyond crossings.MOVERS_M within TOUCH_S after (came
from there before), both one body's motion throughout and their separation following
their velocities, touches that end (`ends`): no part is joined across it
(fmcw_cl.identities). A body of the echo tables that touches an object, unless it
crosses it, is a piece on either side (`pieces`): its lines may have gone on from one
mover to the other there, and a course carried along it would (fmcw_cl.course_bodies).
"""

from __future__ import annotations

import numpy as np

from . import crossings, fixed_echoes, numeric, objects
from .fixed_echoes import ONE_M
from .stages.verification import KINEMATIC_S
from .track import Track

TOUCH_S = 0.02        # a path apart from the track this long before or after a touch is another body's
FOLLOW_M = 5e-4       # two bodies' separation follows their velocities within this ...
FOLLOW_SHARE = 0.1    # ... and this share of their integral (a velocity 0.05 m/s off over 10 ms)
SEEN_S = 1e-3         # a path is where its nearest point lies within this in time

Path = tuple[np.ndarray, np.ndarray, np.ndarray]    # times s, distances m, velocities m/s


class Touched:
    """`ends` of tracks, each taken once while they are asked about (the tracks held,
    so that no other takes one's id), against the moving `paths` (`moves`)."""

    def __init__(self, paths: list[Path]) -> None:
        self._paths = [p for p in paths if moves(p)]
        self._of: dict[int, tuple[Track, tuple[bool, bool]]] = {}

    def __call__(self, track: Track) -> tuple[bool, bool]:
        got = self._of.get(id(track))
        if got is None or got[0] is not track:
            got = self._of[id(track)] = (track, ends(track, self._paths))
        return got[1]

    def barred(self, tracks: list[Track], later: np.ndarray) -> np.ndarray:
        """[e, l] (symmetric): whether a join of parts e and l (`later`[e, l]: e's last
        verified pair before l's first) leaves a touched end or enters a touched start."""
        start, end = np.array([self(t) for t in tracks], bool).reshape(-1, 2).T
        out = later & (end[:, None] | start[None, :])
        return out | out.T


def ends(track: Track, paths: list[Path]) -> tuple[bool, bool]:
    """Whether one of `paths` touches `track`'s first verified pairs (within
    KINEMATIC_S) and parts from it after, or its last, having come from apart before
    (`_runs`, `through`): (first, last). Where a part starts (ends) at a touch, the
    body before (after) it may be either of the two."""
    path = path_of(track)
    t = path[0]
    if t.size < 2:
        return False, False
    first = last = False
    for a, b, came, went in _runs(path, paths, True):
        first |= bool(went) and t[a] - t[0] <= KINEMATIC_S
        last |= bool(came) and t[-1] - t[b - 1] <= KINEMATIC_S
    return bool(first), bool(last)


def path_of(track: Track) -> Path:
    """A track's verified pairs as a path (times s, distances m, velocities m/s)."""
    ok = track.valid
    return track.time_s[ok], track.distance_m[ok], track.velocity_mps[ok]


def pieces(path: Path, others: list[Path]) -> list[Path]:
    """`path` cut where one of `others` touches it (`cuts`; at rest or not, however
    either came there): a body of the echo tables that went on from one mover to the
    other where they touched (the velocity bank's chain from a leg's take-off onto the
    other leg setting off from its plateau: 310 points of a course, 339 valid pairs of
    one leg on the other's object, movers.py seed 33, capture 35)."""
    i = cuts(path, others)
    return [tuple(x[a:b] for x in path) for a, b in zip(np.r_[0, i], np.r_[i, path[0].size], strict=True)]


def cuts(path: Path, others: list[Path]) -> np.ndarray:
    """The indices i of `path`'s points before which it is cut (between i - 1 and i,
    sorted): the middle of each run where one of `others` touches it (`_runs`), not
    where it came from one side and went to the other (a crossing: a hand's body across
    a foot at 0.9 m/s apart keeps its own echo; its course cut there, 79 -> 48 % of its
    periods, movers.py seed 5, capture 37)."""
    return np.unique(np.asarray([max((a + b) // 2, 1) for a, b, came, went in _runs(path, others, False)
                                 if (came or went) and came * went >= 0], int))


def _runs(path: Path, others: list[Path], through: bool) -> list[tuple[int, int, int, int]]:
    """Each run [a, b) of `path`'s points (time s, distance m, velocity m/s) where one
    of `others` is seen (within SEEN_S) and touches it: within fixed_echoes.ONE_M, their
    velocities objects.alike; and whether the other came from, or went to, beyond
    crossings.MOVERS_M of it within TOUCH_S before (after): the side it lay on (+1
    beyond `path`, -1 nearer), 0 where it did not. `through`: only where each
    is one body's motion from there into the run (points within KINEMATIC_S of each
    other, objects.one_body), the other seen throughout, and they came together, or
    parted, as their velocities say (`_together`): a track whose tracker stepped from
    one body onto the other lies on each in turn, touching neither; so does a body of
    the echo tables whose lines did so."""
    t, d, v = path
    out: list[tuple[int, int, int, int]] = []
    if t.size < 2:
        return out
    if through:
        steady = (np.diff(t) <= KINEMATIC_S) & objects.one_body(t[:-1], d[:-1], v[:-1], t[1:], d[1:], v[1:])
    for g, at, vp in others:
        if g.size < 2:
            continue
        seen = np.abs(g[numeric.nearest(g, t)] - t) <= SEEN_S
        if not seen.any():
            continue
        sep, dv = d - np.interp(t, g, at), v - np.interp(t, g, vp)
        near = seen & (np.abs(sep) <= ONE_M) & objects.alike(0.0, dv, 0.0)
        apart = np.flatnonzero(seen & (np.abs(sep) > crossings.MOVERS_M))
        if through:     # links broken up to each point: its own, the other's about that time, or unseen
            own = np.cumsum(~np.r_[False, (np.diff(g) <= KINEMATIC_S) & objects.one_body(
                g[:-1], at[:-1], vp[:-1], g[1:], at[1:], vp[1:])])
            broken = (np.cumsum(~(seen & np.r_[False, steady]))
                      + own[np.clip(np.searchsorted(g, t, "right") - 1, 0, g.size - 1)]
                      + own[np.clip(np.searchsorted(g, t), 0, g.size - 1)])
        for a, b in numeric.runs(near):
            c = apart[(apart < a) & (t[apart] >= t[a] - TOUCH_S)][-1:]     # the nearest apart before
            w = apart[(apart >= b) & (t[apart] <= t[b - 1] + TOUCH_S)][:1]  # ... and after
            came = bool(c.size) and (not through or _together(t, sep, dv, broken, c[0], a))
            went = bool(w.size) and (not through or _together(t, sep, dv, broken, b - 1, w[0]))
            out.append((int(a), int(b), -int(np.sign(sep[c[0]])) if came else 0,
                        -int(np.sign(sep[w[0]])) if went else 0))
    return out


def _together(t: np.ndarray, sep: np.ndarray, dv: np.ndarray, broken: np.ndarray, i: int, j: int) -> bool:
    """Whether two paths `sep` (m) apart at velocities `dv` (m/s) apart came together
    (or parted) from point i to point j as two bodies do: no link `broken` between, and
    their separation following their velocities' difference (within FOLLOW_M +
    FOLLOW_SHARE of its integral; not a body of the echo tables that slid from one echo
    onto the other at a blend's velocities: 3.1 mm for 4.2 mm, movers.py seed 4,
    capture 19)."""
    ran = float(np.sum(numeric.steps(t[i:j + 1], dv[i:j + 1])))
    return bool(broken[i] == broken[j] and abs(sep[j] - sep[i] - ran) <= FOLLOW_M + FOLLOW_SHARE * abs(ran))


def moves(path: Path) -> bool:
    """Whether a path moves: three points or more faster than fixed_echoes.MOVING_MPS,
    its distances spanning fixed_echoes.MIN_TRAVEL_M (a fixed echo's line does not)."""
    g, at, vp = path
    return bool(np.sum(np.abs(vp) >= fixed_echoes.MOVING_MPS) >= 3
                and np.ptp(at) >= fixed_echoes.MIN_TRAVEL_M)
