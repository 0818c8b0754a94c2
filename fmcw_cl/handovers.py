"""Where a conversion's tracker left one echo for another while both were there.

Its path (the mean of each pair's de-chirped half-sweep peaks, verified or not) steps
between consecutive pairs by less than STEP_M while it holds one echo; a stretch of
LONG_PAIRS such pairs or more is an echo (noise peaks do not go on so), and a stretch
that goes on as an earlier one, within LINK_S and as it moved, is that echo again
(`chains`: a few pairs on another echo between them do not part them). Where a gap of
the verified pairs holds a step from the chain of the verified pair before it straight
onto the chain of the one after (`handovers`), the tracker passed from one echo to
another at once: two echoes at one time, so two bodies, however well one body's motion
joins the pairs either side (a rail decelerating at 45 m/s^2, its tracker onto a glide
at rest 21 mm beyond it, held as the glide set off: 30 ms on, the glide's pairs at -0.95
m/s lay where the rail slowing at 90 m/s^2 would be; 47 valid pairs of the glide).
"""

from __future__ import annotations

import numpy as np

from .objects import per_pair
from .stages.verification import ACCEL_MAX, JUMP_MAX_M, KINEMATIC_S
from .track import Track

STEP_M = 2e-3            # a step between consecutive pairs beyond any body's (40 m/s at 20 kHz)
LONG_PAIRS = 20          # a stretch of steps within STEP_M this long is an echo (1 ms at 20 kHz)
LINK_S = KINEMATIC_S     # a stretch goes on as an earlier chain across at most this ...
TREND_PAIRS = 8          # ... moved on at the velocity of the chain's last this many pairs


def chains(time_s: np.ndarray, path_m: np.ndarray) -> np.ndarray:
    """Each pair's chain (-1: none; a stretch shorter than LONG_PAIRS) of the path
    `path_m` (m) at `time_s` (s): stretches of steps within STEP_M, each LONG_PAIRS or
    more joined to the chain whose last stretch it goes on within LINK_S (that stretch's
    end moved on at its velocity, within JUMP_MAX_M + ACCEL_MAX dt^2 / 2), the nearest
    such; else a chain of its own."""
    n = path_m.size
    out = np.full(n, -1)
    step = ~(np.abs(np.diff(path_m)) <= STEP_M)            # NaN steps too
    starts = np.r_[0, np.flatnonzero(step) + 1]
    stops = np.r_[starts[1:], n]
    long = stops - starts >= LONG_PAIRS
    ends: list[tuple[float, float, float]] = []           # each chain's last (time, distance, velocity)
    for a, b in zip(starts[long], stops[long], strict=True):
        t, d = time_s[a:b], path_m[a:b]
        best, miss = -1, np.inf
        for k, (te, de, ve) in enumerate(ends):
            dt = t[0] - te
            if 0 < dt <= LINK_S:
                m = abs(d[0] - (de + ve * dt))
                if m <= JUMP_MAX_M + 0.5 * ACCEL_MAX * dt * dt and m < miss:
                    best, miss = k, m
        if best < 0:
            best = len(ends)
            ends.append((0.0, 0.0, 0.0))
        k = min(TREND_PAIRS, b - a)
        ends[best] = (t[-1], d[-1], (d[-1] - d[-k]) / max(t[-1] - t[-k], 1e-12))
        out[a:b] = best
    return out


def handovers(track: Track) -> tuple[np.ndarray, np.ndarray]:
    """The times (s) of the verified pairs either side of each gap of `track` across
    which its tracker passed from one echo to another at once (the earlier's chain, then
    straight the later's, `chains`): (before, after)."""
    ok = np.flatnonzero(track.valid)
    gap = np.flatnonzero(np.diff(ok) > 1)
    if not gap.size:
        return np.zeros(0), np.zeros(0)
    a, b = ok[gap], ok[gap + 1]
    lab = chains(track.time_s, np.mean(per_pair(track, "sweep_distance_dechirped_m"), axis=0))
    x, y = lab[a], lab[b]
    # the first pair after a on the later's chain, and whether the pair before it is on the earlier's
    first = np.array([a[i] + 1 + int(np.argmax(lab[a[i] + 1:b[i] + 1] == y[i])) for i in range(a.size)])
    handed = (x >= 0) & (y >= 0) & (x != y) & (lab[first - 1] == x)
    return track.time_s[a[handed]], track.time_s[b[handed]]
