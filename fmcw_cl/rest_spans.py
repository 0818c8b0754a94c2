"""When a body's rest is there: a fixed echo that a mover came to, or set off from.

A fixed echo of the tables is taken to be there all capture long (a wall, a window): a
mover's pairs within fixed_echoes.GATE_M of it are `ambiguous` whenever they lie there.
A body's rest is there only while the body rests. Two glides resting 2.6 mm apart in
turn (benchmarks/movers.py seed 3, capture 8: one at 0.368 m until it set off at 0.05
s, the other come to rest at 0.371 m at 0.11 s) made one fixed candidate, and the
first glide's 1000 pairs at rest were `ambiguous` beside an echo that came 60 ms later.

A fixed conversion first verified ABSENT_S or more after the capture's start, where a
mover's verified pair within CAME_S before it moved towards it, fast enough to
reach it, and the mover was not verified beyond it since, came with that mover: it
was there from that pair on, no earlier (`there`); so too, time reversed, one a mover
set off from. A window that a foot rests on at the start is first verified as the
foot leaves it: nothing came to it, it stays there all along. Nor where a mover moving
the other way could have left it (time reversed, reached it) in between: two bodies
swapping places at one spot are not told apart by its span.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from . import conversions
from .conversions import Converted
from .fixed_echoes import APART_M, GATE_M, MOVING_MPS
from .numeric import median
from .processor import ChunkProcessor
from .track import Track

ABSENT_S = 0.01     # a fixed conversion unverified this long at the capture's start or end may be a rest
CAME_S = 0.1        # ... of a body whose verified pair this close in time came to it (or set off from it:
                    # a glide setting off at 13 m/s^2, within GATE_M for 40 ms, first verified 56 ms after)
SEEN_S = 0.02       # ... where its verified pairs span this long (2.5 ms, 7 mm from two bodies' rests: none)
SWAP_MPS = 0.03     # a body moving the other way this fast could have left it (a set-off's first pairs)


def bounded(done: list[Converted], moving: list[bool], processor: ChunkProcessor, seconds: Callable[[], float]
            ) -> list[Converted]:
    """`done` with each fixed conversion that is a body's rest (`there`) given its time
    span (target.Choice.there_s), and each moving conversion ambiguous about it
    assembled again, ambiguous there only within that span (target.Choice.rests_s)."""
    movers = [d.track for d, m in zip(done, moving, strict=True) if m]
    out, rests = list(done), []
    for k, (d, m) in enumerate(zip(done, moving, strict=True)):
        if m or d.choice.at_rest_m is None:
            continue
        span = there(d.track, movers)
        if np.isfinite(span).any():
            out[k] = replace(d, choice=replace(d.choice, there_s=span))
            rests.append((d.choice.at_rest_m, *span))
    for k, (d, m) in enumerate(zip(done, moving, strict=True)):
        rows = [r for r in rests if np.any(np.abs(d.choice.ambiguous_m - r[0]) <= APART_M)]
        if m and rows:
            choice = replace(d.choice, rests_s=np.asarray(rows))
            out[k] = replace(d, choice=choice, track=conversions.again(d, choice, processor, seconds))
    return out


def there(rest: Track, movers: list[Track]) -> tuple[float, float]:
    """The times (s) from and to which a fixed conversion's echo `rest` was there:
    from the verified pair of a mover of `movers` that came to it (`_came`) where its
    own are first verified ABSENT_S or more after the capture's start, to that of one
    that set off from it where they end ABSENT_S or more before its end; -inf and inf
    otherwise, and where its verified pairs span less than SEEN_S (a fixed conversion
    verified for 2.5 ms, 7 mm from where a glide set off and a rail came to rest: no
    rest's span; tests/test_objects.py, the rail that left one mover for another)."""
    ok = np.flatnonzero(rest.valid)
    if not ok.size or rest.time_s[ok[-1]] - rest.time_s[ok[0]] < SEEN_S:
        return -np.inf, np.inf
    t = rest.time_s
    f = median(rest.distance_m[ok])
    lo = _came(f, t[ok[0]], movers, 1.0) if t[ok[0]] - t[0] >= ABSENT_S else -np.inf
    hi = _came(f, t[ok[-1]], movers, -1.0) if t[-1] - t[ok[-1]] >= ABSENT_S else np.inf
    return lo, hi


def _came(f: float, at: float, movers: list[Track], way: float) -> float:
    """The time (s) of the last verified pair within CAME_S before `at` (`way` 1;
    -1: the first after, time reversed) of a mover moving towards `f` (m) at
    MOVING_MPS or more, near enough to reach it by then at that speed (GATE_M more), and
    not verified more than GATE_M beyond it since; -inf (way -1: inf) where none, or
    where, between that pair and `at`, a mover's verified pair moving the other way
    could have left `f` since that pair (or, time reversed, reached it by then): two
    bodies that swap places at the rest are not told apart by its span (a rail come to
    rest 0.8 mm from where a glide set off, crossing it 5 mm from there: the rail's
    object took 98 of the glide's pairs; movers.py seed 5, capture 11)."""
    best = -way * np.inf
    for m in movers:
        dt = way * (at - m.time_s)
        ok = np.flatnonzero(m.valid & (dt > 0) & (dt <= CAME_S))
        towards = _heading(f, m.distance_m[ok], m.velocity_mps[ok], dt[ok], way, MOVING_MPS)
        if not towards.any():
            continue
        k = ok[towards][np.argmin(dt[ok][towards])]
        side = np.sign(f - m.distance_m[k])
        since = m.valid & (way * (m.time_s - m.time_s[k]) > 0) & (dt > -CAME_S)
        if np.any(side * (m.distance_m[since] - f) > GATE_M):
            continue
        best = max(best, m.time_s[k]) if way > 0 else min(best, m.time_s[k])
    if np.isfinite(best) and any(_swapped(f, best, at, m, way) for m in movers):
        return float(-way * np.inf)
    return float(best)


def _swapped(f: float, t_k: float, at: float, m: Track, way: float) -> bool:
    """Whether mover `m` has a verified pair between `t_k` and `at` (s) moving away from
    `f` (m; `way` -1: towards it) at SWAP_MPS or more, near enough to have left it
    after `t_k` (to reach it by `t_k`) at that speed, GATE_M more."""
    after = way * (m.time_s - t_k)
    ok = np.flatnonzero(m.valid & (after > 0) & (way * (at - m.time_s) > 0))
    return bool(np.any(_heading(f, m.distance_m[ok], m.velocity_mps[ok], after[ok], -way, SWAP_MPS)))


def _heading(f: float, d: np.ndarray, v: np.ndarray, dt: np.ndarray, way: float, speed: float) -> np.ndarray:
    """Which pairs (distances `d` m, velocities `v` m/s) move towards `f` (m; `way` -1:
    away from it) at `speed` (m/s) or more, near enough to reach it in `dt` (s; or to
    have left it that long before) at that speed, GATE_M more."""
    return (way * v * (f - d) > 0) & (np.abs(v) >= speed) & (np.abs(f - d) <= np.abs(v) * dt + GATE_M)
