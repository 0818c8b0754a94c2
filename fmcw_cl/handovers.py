"""Where a conversion's tracker left one echo for another while both were there.

Its path (the mean of each pair's de-chirped half-sweep peaks, verified or not, where
they agree within JUMP_MAX_M) holds one echo in `stretches`: no step beyond STEP_M
between consecutive pairs, no kink (its velocity turning by KINK_MPS and beyond its
noise, as where it runs onto another echo it crosses). A stretch of LONG_PAIRS pairs or
more is an echo (noise peaks do not go on so), and one that goes on as an earlier one,
within LINK_S, where and as fast as it moved, is that echo again (`chains`: a few pairs of noise or of
another echo between them do not part them). Where a gap of the verified pairs holds a
step from the chain of the verified pair before it straight onto the chain of the one
after (`handovers`; across pairs whose two peaks part, each on one echo, or from a
chain the earlier one's body can be), the tracker passed from one echo to another at
once: two echoes at one time, so two bodies, however well one body's motion joins the
pairs either side (a rail decelerating at 45 m/s^2, its tracker onto a glide at rest
21 mm beyond it, held as the glide set off: 30 ms on, the glide's pairs at -0.95 m/s
lay where the rail slowing at 90 m/s^2 would be; 47 valid pairs of the glide).
"""

from __future__ import annotations

import numpy as np

from .objects import SceneObject, per_pair, seen_again
from .stages.verification import ACCEL_MAX, JUMP_MAX_M, KINEMATIC_S
from .track import Track

STEP_M = 2e-3            # a step between consecutive pairs beyond any body's (40 m/s at 20 kHz)
KINK_MPS = 0.5           # the path's velocity turning this much at a pair (TREND_PAIRS either side): another
                         # echo's (a sway at +1.9 m/s onto a glide at +0.4 it crossed)
KINK_SIGMAS = 5.0        # ... and this many times the two slopes' noise (their windows' residuals)
LONG_PAIRS = 20          # a stretch without steps or kinks this long is an echo (1 ms at 20 kHz)
LINK_S = KINEMATIC_S     # a stretch goes on as an earlier chain across at most this ...
TREND_PAIRS = 8          # ... moved on at the velocity of the chain's last this many pairs


def stretches(time_s: np.ndarray, path_m: np.ndarray) -> np.ndarray:
    """Where the path `path_m` (m, at `time_s` s) starts a new stretch of one echo (a
    boolean per pair): a step beyond STEP_M from the pair before (or NaN), or a kink,
    its least-squares velocities over TREND_PAIRS before and from it, both free of
    steps, KINK_MPS apart or more and KINK_SIGMAS times their noise (a glide's path at
    29 dB broke into stretches of 1-16 pairs at KINK_MPS alone, movers.py seed 20,
    capture 21)."""
    n, k = path_m.size, TREND_PAIRS
    out = np.zeros(n, bool)
    out[1:] = ~(np.abs(np.diff(path_m)) <= STEP_M)            # NaN steps too
    if n < 2 * k + 1:
        return out
    w = np.arange(k) - 0.5 * (k - 1)
    dt = float(np.median(np.diff(time_s)))
    sxx = dt * dt * np.sum(w * w)                              # the windows' times about their mean, squared
    y = np.nan_to_num(path_m - np.nanmedian(path_m))
    slope = np.correlate(y, w, "valid") * dt / sxx              # over [m, m + k)
    # each window's residual variance about its line, so its slope's (a noisy path's
    # slopes scatter by more than KINK_MPS: 0.1 mm at 20 dB)
    sums = [np.convolve(x, np.ones(k), "valid") for x in (y, y * y)]
    spread = np.maximum(sums[1] - sums[0] ** 2 / k - slope ** 2 * sxx, 0.0)
    var = spread / (k - 2) / sxx
    count = np.cumsum(out)
    whole = count[k - 1:] - count[:n - k + 1] == 0             # no step inside [m, m + k)
    slope[~whole] = np.nan
    i = np.arange(k, n - k + 1)                                # left window [i - k, i), right [i, i + k)
    bar = np.maximum(KINK_MPS, KINK_SIGMAS * np.sqrt(var[i] + var[i - k]))
    out[i] |= np.abs(slope[i] - slope[i - k]) >= bar
    return out


def chains(time_s: np.ndarray, path_m: np.ndarray) -> np.ndarray:
    """Each pair's chain (-1: none; a stretch shorter than LONG_PAIRS) of the path
    `path_m` (m) at `time_s` (s): `stretches` of LONG_PAIRS or more, each joined to the
    chain whose last stretch it goes on within LINK_S (that stretch's `_end` moved on
    at its velocity, within STEP_M + ACCEL_MAX dt^2 / 2, its velocity within KINK_MPS +
    ACCEL_MAX dt), the nearest such; else a chain of its own."""
    n = path_m.size
    out = np.full(n, -1)
    starts = np.r_[0, np.flatnonzero(stretches(time_s, path_m)[1:]) + 1]
    stops = np.r_[starts[1:], n]
    long = stops - starts >= LONG_PAIRS
    recent: dict[int, tuple[float, float, float]] = {}    # chains' last (time, distance, velocity)
    count = 0
    for a, b in zip(starts[long], stops[long], strict=True):
        t, d = time_s[a:b], path_m[a:b]
        t0, d0, v0 = _end(t[::-1], d[::-1])                 # its start
        best, miss = -1, np.inf
        for k, (te, de, ve) in list(recent.items()):
            dt = t0 - te
            if dt > LINK_S:
                del recent[k]                               # ended too long ago for any later
                continue
            m = _off(d0, de, ve, dt)
            if 0 < dt and m <= _reach(dt) and abs(v0 - ve) <= KINK_MPS + ACCEL_MAX * dt and m < miss:
                best, miss = k, m
        if best < 0:
            best, count = count, count + 1
        recent[best] = _end(t, d)
        out[a:b] = best
    return out


def _off(d, d0, v0, dt):
    """How far (m) distance `d` lies from `d0` moved on at `v0` (m/s) for `dt` (s)."""
    return np.abs(d - (d0 + v0 * dt))


def _reach(dt):
    """How far (m) one echo can lie from where its velocity carries it over `dt` (s):
    STEP_M + ACCEL_MAX dt^2 / 2."""
    return STEP_M + 0.5 * ACCEL_MAX * dt * dt


def _end(t: np.ndarray, d: np.ndarray) -> tuple[float, float, float]:
    """A stretch's end (time s, distance m, velocity m/s; its start, given in reverse)
    that its last pairs' noise does not move: the medians of its last TREND_PAIRS pairs
    and of the TREND_PAIRS before them (a fade's first pair 1.2 mm off, in the stretch,
    read -6.6 m/s)."""
    k = min(TREND_PAIRS, d.size // 2)
    last, before = np.median(d[-k:]), np.median(d[-2 * k:-k])
    v = (last - before) / float(np.median(t[-k:]) - np.median(t[-2 * k:-k]))
    return float(t[-1]), float(last + v * (t[-1] - np.median(t[-k:]))), float(v)


class Asked:
    """`handovers` of tracks, each taken once while they are asked about (the tracks
    held, so that no other takes one's id)."""

    def __init__(self) -> None:
        self._of: dict[int, tuple[Track, tuple[np.ndarray, np.ndarray]]] = {}

    def __call__(self, track: Track) -> tuple[np.ndarray, np.ndarray]:
        got = self._of.get(id(track))
        if got is None or got[0] is not track:
            got = self._of[id(track)] = (track, handovers(track))
        return got[1]


def handovers(track: Track) -> tuple[np.ndarray, np.ndarray]:
    """The times (s) of the verified pairs either side of each gap of `track` across
    which its tracker passed from one echo to another at once (a step from the earlier's
    chain straight onto the later's, `chains`): (before, after)."""
    ok = np.flatnonzero(track.valid)
    gap = np.flatnonzero(np.diff(ok) > 1)
    if not gap.size:
        return np.zeros(0), np.zeros(0)
    a, b = ok[gap], ok[gap + 1]
    peaks = per_pair(track, "sweep_distance_dechirped_m")
    path = np.where(np.abs(peaks[0] - peaks[1]) <= JUMP_MAX_M, np.mean(peaks, axis=0), np.nan)
    lab = chains(track.time_s, path)
    on = np.flatnonzero(lab >= 0)
    if not on.size:
        return np.zeros(0), np.zeros(0)
    # the chains of the verified pairs either side, or of the pairs on chains nearest them
    # within 2 TREND_PAIRS (a pair whose peaks part is on none, nor are the pairs before
    # it within a kink's windows)
    xa = on[np.maximum(np.searchsorted(on, a, "right") - 1, 0)]
    yb = on[np.minimum(np.searchsorted(on, b), on.size - 1)]
    x = np.where((xa <= a) & (a - xa <= 2 * TREND_PAIRS) & _near(track, path, a, xa), lab[xa], -1)
    y = np.where((yb >= b) & (yb - b <= 2 * TREND_PAIRS) & _near(track, path, b, yb), lab[yb], -1)
    handed = np.zeros(a.size, bool)
    t = track.time_s
    for i in np.flatnonzero((x >= 0) & (y >= 0) & (x != y)):
        # the first pair after the earlier's on the later's chain, and the last on a chain before it
        first = xa[i] + 1 + int(np.argmax(lab[xa[i] + 1:yb[i] + 1] == y[i]))
        last = on[np.searchsorted(on, first) - 1]
        w = lab[last]
        if w == y[i] or first - last > 2 * TREND_PAIRS + 1:
            continue
        if not (_stepped(t, path, lab == w, last, first) or _turned(t, path, lab, last, first)):
            continue
        handed[i] = w == x[i] or _goes_on(t, path, lab, xa[i], w)
    return track.time_s[a[handed]], track.time_s[b[handed]]


def _near(track: Track, path: np.ndarray, k: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Whether the path at pairs `at` lies where the verified pairs `k` move on at their
    velocities (within STEP_M + ACCEL_MAX dt^2 / 2): the same echo, not one the tracker
    stepped to after it."""
    dt = track.time_s[at] - track.time_s[k]
    return _off(path[at], track.distance_m[k], track.velocity_mps[k], dt) <= _reach(dt)


def _goes_on(time_s: np.ndarray, path: np.ndarray, lab: np.ndarray, last: int, w: int) -> bool:
    """Whether chain `w`, after pair `last`, can be the body of `last`'s chain seen
    again (objects.seen_again, from that chain's `_end` before w to w's first pairs'):
    not where chain w starts within 2 TREND_PAIRS of that end (a step or a kink off it
    at once: another echo). A rail's tracker left it for a glide at rest 8 mm beyond
    it, then held the rail coming to rest there, then stepped onto the glide setting
    off: 1372 valid pairs of the glide on the rail's object (benchmarks/movers.py seed
    20, capture 21)."""
    theirs = np.flatnonzero(lab == w)
    theirs = theirs[theirs > last][:2 * TREND_PAIRS]
    if not theirs.size:
        return False
    mine = np.flatnonzero(lab[:theirs[0]] == lab[last])[-2 * TREND_PAIRS:]
    if theirs[0] - mine[-1] <= 2 * TREND_PAIRS + 1:
        return False
    return bool(seen_again(*_end(time_s[mine], path[mine]), *_end(time_s[theirs][::-1], path[theirs][::-1])))


def _turned(time_s: np.ndarray, path: np.ndarray, lab: np.ndarray, last: int, first: int) -> bool:
    """Whether the chain of pair `first` starts at a velocity that the chain of pair
    `last` before it cannot reach: their least-squares slopes over 2 TREND_PAIRS pairs
    (the end of one, the start of the other) apart by more than ACCEL_MAX allows
    between their windows' centres (at least KINK_MPS) plus KINK_SIGMAS times their
    noise. Two legs crossed 0.5 mm apart at +0.41 and -0.80 m/s, the tracker from one
    onto the other: 112 valid pairs of one leg on the other's object (movers.py seed
    15, capture 20); a landing's foot at -4.8 m/s, its path 0.1 m/s noisy, is no turn."""
    mine = np.flatnonzero(lab[:last + 1] == lab[last])[-2 * TREND_PAIRS:]
    theirs = np.flatnonzero(lab[first:] == lab[first])[:2 * TREND_PAIRS] + first
    if mine.size < 3 or theirs.size < 3:
        return False
    (te, ve, se), (t0, v0, s0) = _slope(time_s[mine], path[mine]), _slope(time_s[theirs], path[theirs])
    bar = max(KINK_MPS, ACCEL_MAX * (t0 - te)) + KINK_SIGMAS * np.hypot(se, s0)
    return bool(abs(v0 - ve) > bar)


def _slope(t: np.ndarray, d: np.ndarray) -> tuple[float, float, float]:
    """The least-squares line of distances `d` (m) at times `t` (s, three or more):
    (its mean time s, slope m/s, the slope's standard error from the residuals)."""
    tc = float(np.mean(t))
    dt = t - tc
    sxx = float(np.sum(dt * dt))
    v = float(np.sum(dt * (d - np.mean(d)))) / sxx
    residual = d - np.mean(d) - v * dt
    return tc, v, float(np.sqrt(np.sum(residual * residual) / (t.size - 2) / sxx))


def _stepped(time_s: np.ndarray, path: np.ndarray, mine: np.ndarray, last: int, first: int) -> bool:
    """Whether the path steps from pair `last` (on a chain, `mine` its pairs) to pair
    `first` beyond STEP_M + ACCEL_MAX dt^2 / 2 from where the chain's end (`_end`) moves
    on at its velocity. Between them lie pairs whose two half-sweeps' peaks part (one on
    each echo: a glide's rising peak held as its falling one followed it, 2.4 mm apart
    where it passed onto a glide at rest 8 mm beyond, benchmarks/movers.py seed 19,
    capture 23) or none."""
    k = np.flatnonzero(mine[:last + 1])[-2 * TREND_PAIRS:]
    te, de, ve = _end(time_s[k], path[k])
    dt = time_s[first] - te
    return bool(_off(path[first], de, ve, dt) > _reach(dt))


def across(parts: list[SceneObject], t1: np.ndarray, t0: np.ndarray, asked: Asked) -> np.ndarray:
    """[e, l] (symmetric): whether parts e and l of one conversion's track (`whole`) lie
    either side of a gap its tracker crossed by passing to another echo at once (e's
    last verified pair at `t1`, l's first at `t0`, s)."""
    out = np.zeros((len(parts), len(parts)), bool)
    of: dict[int, tuple] = {}
    for k, o in enumerate(parts):
        whole = o.track if o.whole is None else o.whole
        of.setdefault(id(whole), (whole, []))[1].append(k)
    for whole, ks in of.values():
        if len(ks) > 1:
            for ta, tb in zip(*asked(whole), strict=True):
                out[np.ix_([k for k in ks if t1[k] == ta], [k for k in ks if t0[k] == tb])] = True
    return out | out.T
