"""Two rests at one spot: a fixed object cut where the body at rest left, or one came.

A fixed object's tracker holds whatever rests at its distance. Two feet resting at one
spot in turn, 130 ms apart, both in the air between, were one object (173 valid pairs of
one foot's rest on the other's): nothing in where a body rests tells which body it is.
So where a fixed object's gap of more than verification.KINEMATIC_S was left moving, or
come back to moving (the median velocity of END_PAIRS verified pairs before or after it,
LEAVING_MPS or more, away from the other side's pairs), at rest either side, while one of
two movers or more was seen, the object is cut there (`rests_parted`). So too, in a
scene of two movers or more, whether one was seen in the gap or not, where it set off
faster than a rest (fixed_echoes.MOVING_MPS), away, and is at rest after (two feet
landing 2-7 mm apart: one setting off at 0.43 m/s, the other at rest 3.8 mm nearer 4.5
ms later), or was at rest either side MOVED_M further apart than their velocities carry
(one foot's rest 6.6 mm from the other's, 9 ms later). A wall's echo fades at rest (its
velocities at its gaps: 0.006 m/s at most); a glide slowing onto its rest comes towards
it; a scene of one mover keeps its rest whole (a foot's own return).
"""

from __future__ import annotations

import numpy as np

from . import fixed_echoes
from .identities import cut_at, gaps, pairs_at, split
from .numeric import median
from .objects import SceneObject
from .stages.verification import KINEMATIC_S

LEAVING_MPS = 0.03    # a fixed object's rest ending or starting this fast (median of END_PAIRS) ...
END_PAIRS = 16        # ... left or came (walls' at their gaps: 0.006 at most; a foot setting off 0.063)
MOVED_M = 0.005       # rests this far apart across a gap: a body moved in it, or another came


def rests_parted(scene: list[SceneObject]) -> list[SceneObject]:
    """Each fixed object cut where it was left or come to (`_left`) while one of two
    movers or more was seen: which body rested after is not told (objects of their
    own; a scene of one mover keeps its rest whole)."""
    movers = [o.track for o in scene if o.moving and o.track.valid.any()]
    out = []
    for o in scene:
        others = [m for m in movers if m is not o.track]
        fixed = not o.moving and o.track.valid.any() and len(others) >= 2
        cut = _left(o.track, others) if fixed else np.zeros(0)
        parts = cut_at([o.track.valid], cut, o.track.time_s)
        out += split(o, parts, "left or come to while movers passed") if len(parts) > 1 else [o]
    return out


def _left(x, movers: list) -> np.ndarray:
    """The times (s) at which to cut fixed object `x`: the middles of its gaps of more
    than KINEMATIC_S at rest either side (under fixed_echoes.MOVING_MPS, `_velocities`),
    that it left moving away (LEAVING_MPS or more, going on at it takes it further from
    where the later pairs start) or came back to moving from away (so, back from where
    they start), while a mover of `movers` was seen: a body at rest that set off, or
    one that came to rest, is not told from another by where it rests (two feet resting
    in turn at one spot, 130 ms apart, both in the air between: 173 valid pairs of one
    foot's rest on the other's). A wall's echo fades at rest; a glide slowing onto its
    rest comes towards it (a slow glide's short parts, too short to run, are fixed
    parts at 0.3-1.5 m/s). Also, mover seen or not, gaps set off from faster than a rest,
    away, to a rest, and rests further apart than their velocities carry."""
    p, n = gaps(x)
    keep = (p >= 0) & (n >= 0) & (x.time_s[n] - x.time_s[p] > KINEMATIC_S)   # so soon, one body's rest
    p, n = p[keep], n[keep]
    if not p.size:
        return np.zeros(0)
    (t0, d0, _), (t1, d1, _) = pairs_at(x, p), pairs_at(x, n)
    v0, v1 = _velocities(x, p, n)
    rest0, rest1 = np.abs(v0) < fixed_echoes.MOVING_MPS, np.abs(v1) < fixed_echoes.MOVING_MPS
    dt, apart = t1 - t0, np.abs(d1 - d0)
    left = (np.abs(v0) >= LEAVING_MPS) & (np.abs(d0 + v0 * dt - d1) > apart)
    came = (np.abs(v1) >= LEAVING_MPS) & (np.abs(d1 - v1 * dt - d0) > apart)
    # a side faster than a rest went away from the other (a glide slowing onto its rest
    # comes towards it): a foot setting off at 0.4 m/s, the other come to rest 4 mm nearer
    left &= rest0 | (v0 * (d0 - d1) > 0)
    came &= rest1 | (v1 * (d1 - d0) < 0)
    # at rest either side, further apart than their velocities carry them: a body moved
    # unseen, or another came (one foot's rest 6.6 mm from the other's, 9 ms apart)
    moved = rest0 & rest1 & (apart > MOVED_M + 0.5 * (np.abs(v0) + np.abs(v1)) * dt)
    passed = np.zeros(p.size, bool)
    for m in movers:
        tm = m.time_s[m.valid]
        passed |= np.searchsorted(tm, t1, "left") > np.searchsorted(tm, t0, "right")
    # left to a rest (or come from one) while a mover passed, or faster than a rest, or
    # moved: which body rests after is not told (in 4.5 ms one foot would turn at -570
    # m/s^2 and not be at rest; longer, it may be either)
    cut = (left & rest1 & (passed | ~rest0)) | (came & rest0 & (passed | ~rest1)) | moved
    return 0.5 * (t0 + t1)[cut]


def _velocities(x, p: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The velocity (m/s, median) of `x`'s END_PAIRS verified pairs up to each pair `p`
    and from each pair `n` (indices of verified pairs)."""
    ok = np.flatnonzero(x.valid)
    v = x.velocity_mps[ok]
    rp, rn = np.searchsorted(ok, p), np.searchsorted(ok, n)
    return (np.array([median(v[max(r - END_PAIRS + 1, 0): r + 1]) for r in rp]),
            np.array([median(v[r: r + END_PAIRS]) for r in rn]))
