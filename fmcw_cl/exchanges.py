"""A body at rest stays where it came to rest: where a mover is lost beside a body at
rest and that rest lies elsewhere after, another body may have left it.

A rail decelerating onto the spot where a glide stood (0.8 mm from it), the glide
setting off as the rail arrived: the rail's tracker lost both within the fixed echo's
span and came back on the glide leaving, whose motion (+1.40 then -0.83 m/s 26 ms
later, 84 m/s^2 on a rail decelerating at 60) one body makes as well (280 valid pairs
of the glide on the rail). Their echoes' strengths do not tell (the rail's own pairs
swing 7 dB across a gap); the rest does. A fixed echo's tracker measures its distance to
tens of micrometres over a few milliseconds: 0.35129 m before the visit, 0.35064 m
after. A body at rest that moved by a third of the resolution while another was there
is not the one that stood there, so the mover that left is not known to be the one
that came: its part after the gap is an object of its own. A foot landing at a window's
distance and taking off again leaves the window where it was; nothing is cut.
"""

from __future__ import annotations

import numpy as np

from .fixed_echoes import MOVING_MPS
from .identities import cut_at, split
from .objects import SceneObject
from .stages.verification import KINEMATIC_S
from .track import Track

WINDOW_S = 0.01       # a rest is measured over this long before a mover's gap, and after it ...
LOOK_S = 0.05         # ... the nearest such window within this of the gap where it holds one
CLUSTER_M = 2e-4      # ... as the densest span this wide of its half-sweeps' distances
HOLD_SHARE = 0.5      # ... holding this share of them, and at least
HOLD_ROWS = 40        # ... this many (1 ms: a blend's or a passing echo's rows are not a rest)
SHIFT_M = 3e-4        # a rest this far from where it was is another body's (a third of c / 2B) ...
MERGED_M = 2e-3       # ... up to this (two resolution cells: further, two rests are two echoes, and
                      # a rest's tracker that holds one, then the other, tells nothing of the mover)
REACH_M = 0.03        # a mover lost this close to a rest (at both ends of its gap) was lost beside it


def rest_at(track: Track, lo_s: float, hi_s: float) -> float | None:
    """Where the body at rest that `track`'s tracker follows lies between `lo_s` and
    `hi_s` (s): the median of the densest CLUSTER_M span of its half-sweeps'
    distances (m) there, None where that span holds fewer than HOLD_SHARE of them or
    HOLD_ROWS (its tracker on something passing, or nothing at rest)."""
    a, b = np.searchsorted(track.sweep_time_s, [lo_s, hi_s], side="left")
    d = track.sweep_distance_m[a:b]
    d = np.sort(d[np.isfinite(d)])
    if d.size < HOLD_ROWS:
        return None
    end = np.searchsorted(d, d + CLUSTER_M, side="right")
    k = int(np.argmax(end - np.arange(d.size)))
    held = end[k] - k
    if held < HOLD_ROWS or held < HOLD_SHARE * d.size:
        return None
    return float(np.median(d[k:end[k]]))


def _nearest(track: Track, t_s: float, step_s: float) -> float | None:
    """`rest_at` over the window nearest `t_s` (s) that holds a rest, stepping by
    `step_s` (s; back where negative) within LOOK_S (the rest's tracker may have followed
    the mover as it came near)."""
    for k in range(round(LOOK_S / abs(step_s))):
        a, b = t_s + k * step_s, t_s + (k + 1) * step_s
        if (r := rest_at(track, min(a, b), max(a, b))) is not None:
            return r
    return None


def _towards(d: float, v: float, rest_m: float) -> bool:
    """Whether a pair at `d` (m) moving at `v` (m/s) lies within REACH_M of a rest at
    `rest_m` (m) and is at rest too (under fixed_echoes.MOVING_MPS) or moves towards it."""
    return bool(abs(d - rest_m) <= REACH_M and (abs(v) < MOVING_MPS or (rest_m - d) * v > 0))


def exchanged(mover: Track, rests: list[Track]) -> np.ndarray:
    """The times (s) at which to cut `mover`: the middles of its gaps (verified pairs
    KINEMATIC_S or more apart with unverified ones between) that came towards a body at
    rest and left it again (`_towards`; one of the fixed objects' tracks `rests`,
    `_nearest` before the gap and after it) that lies SHIFT_M to MERGED_M elsewhere
    after it. A glide lost as it left its own rest, a rail come to rest there while it
    was lost, is not cut (seed 3, 26: it never came back)."""
    ok = np.flatnonzero(mover.valid)
    t = mover.time_s[ok]
    gap = np.flatnonzero((np.diff(ok) > 1) & (np.diff(t) >= KINEMATIC_S))     # sooner, one body's or none
    cuts = []
    for a, b in zip(ok[gap], ok[gap + 1], strict=True):
        ta, tb = mover.time_s[a], mover.time_s[b]
        for r in rests:
            before, after = _nearest(r, ta, -WINDOW_S), _nearest(r, tb, WINDOW_S)
            if (before is not None and after is not None and SHIFT_M <= abs(after - before) <= MERGED_M
                    and _towards(mover.distance_m[a], mover.velocity_mps[a], before)       # came, and
                    and _towards(mover.distance_m[b], -mover.velocity_mps[b], after)):    # left again
                cuts.append(0.5 * (ta + tb))
                break
    return np.array(cuts)


def apart(scene: list[SceneObject], rests: list[Track]) -> list[SceneObject]:
    """`scene` with each mover cut at its `exchanged` gaps beside the bodies at rest
    `rests` (fixed objects' tracks): an object per part, each knowing the track it was
    cut from (`whole`)."""
    out = []
    for o in scene:
        cut = exchanged(o.track, rests) if o.moving and o.track.valid.any() else np.zeros(0)
        if not cut.size:
            out.append(o)
            continue
        out += split(o, cut_at([o.track.valid], cut, o.track.time_s),
                     "lost beside a body at rest that lay elsewhere after")
    return out
