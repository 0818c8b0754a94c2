"""Movers too fast for a plain peak: the velocity bank's echoes as bodies.

A mover faster than about 1 m/s leaves no CFAR echo in the plain spectra (its Doppler
chirp smears it), so no line of the echo table carries it (fmcw_cl.moving_echoes). The
first conversion's surveyed half-sweeps, every BANK_STRIDE-th of them (32 periods, 1.6
ms apart at 20 kHz), are de-chirped at each trial velocity (stages.bank) and their CFAR
echoes listed. At one trial velocity u a mover at v shows in the rising half-sweep at
d_r = R + k_r (v - u) and in the falling one at d_f = R + k_f (v - u), sharp where
|v - u| is small: each rising echo with each falling echo of the pair at u solves for R
and v (doppler.solve_pair), kept where v lies within ACCEPT_MPS of u (beyond it the
echo is smeared there and another trial shows it sharper) and is MIN_MPS or faster (a
still wall solves to 0 m/s at every trial; the slower movers are the lines'). Of the
points of a pair within SAME_M of each other, the strongest stands (`points`).

`bodies` links the points in time: a point goes on the chain whose last point, moved on
at the mean of its velocity and the point's, reaches it within LINK_M + ACCEL_MAX dt^2
/ 8, its velocity within AGREE_MPS + ACCEL_MAX dt, across at most GAP_S; a chain of
MIN_POINTS or more over MIN_SPAN_S whose velocities are its distances' slope (within
AGREE_MPS, the median) is a body, in moving_echoes.bodies' form (its points at
moving_echoes.STEP_S steps): two bodies' echoes paired, or noise, do not run so.
A shorter chain of FRAGMENT_POINTS or more that runs so (`fragments`) only carries a
known body's course on across a fade (`carried`), as its points would link.
"""

from __future__ import annotations

import numpy as np

from .coherence import slope
from .moving_echoes import AGREE_MPS, STEP_S, off_spans
from .numeric import nearest_first
from .stages.bank import POINT_KEYS
from .stages.verification import ACCEL_MAX

LINK_M = 0.001             # a point this far from where its chain's motion carries it goes on it
GAP_S = 0.005              # ... after at most this without one
MIN_POINTS = 6             # a chain of this many points ...
MIN_SPAN_S = 0.006         # ... over this long is a body's
SLOPE_S = 0.004            # a chain's distance slope: least squares within this either side (5 picks)
FRAGMENT_POINTS = 3        # a shorter chain of this many points only carries a known body's course on
FRAGMENT_GAP_S = 0.02      # ... across at most this


def bodies(pts: dict) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """(times s, distances m, velocities m/s) at moving_echoes.STEP_S steps of each body
    the points `pts` (`points`, in time order) show."""
    out = []
    for tc, dc, vc in _running(pts):
        if tc.size >= MIN_POINTS and tc[-1] - tc[0] >= MIN_SPAN_S:
            grid = np.arange(tc[0], tc[-1], STEP_S)
            out.append((grid, np.interp(grid, tc, dc), np.interp(grid, tc, vc)))
    return out


def fragments(pts: dict) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The chains of the points `pts` too short for a body (`bodies`; FRAGMENT_POINTS or
    more points) whose velocities are their distances' slope, in its form (their last
    point too)."""
    out = []
    for tc, dc, vc in _running(pts):
        if not (tc.size >= MIN_POINTS and tc[-1] - tc[0] >= MIN_SPAN_S):
            grid = np.arange(tc[0], tc[-1] + 0.5 * STEP_S, STEP_S)
            out.append((grid, np.interp(grid, tc, dc), np.interp(grid, tc, vc)))
    return out


def _running(pts: dict) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """(times s, distances m, velocities m/s) of each chain of FRAGMENT_POINTS or more
    of the points `pts` (`_chains`) whose velocities are its distances' slope (within
    AGREE_MPS, the median)."""
    t, d, v = (np.asarray(pts[k]) for k in POINT_KEYS[:3])
    order = np.argsort(t, kind="stable")
    t, d, v = t[order], d[order], v[order]
    out = []
    for c in _chains(t, d, v):
        tc, dc, vc = t[c], d[c], v[c]
        if c.size >= FRAGMENT_POINTS and np.median(np.abs(vc - slope(tc, dc, tc, SLOPE_S))) <= AGREE_MPS:
            out.append((tc, dc, vc))
    return out


def carried(course: tuple[np.ndarray, np.ndarray, np.ndarray],
            frags: list[tuple[np.ndarray, np.ndarray, np.ndarray]]) -> list:
    """The fragments of `frags` that go on as `course` (time s, distance m, velocity m/s;
    sorted) before its first point or after its last, one after another, as a chain's
    points do (`_links`) across FRAGMENT_GAP_S at most."""
    got = []
    pool = list(frags)
    first = (course[0][0], course[1][0], course[2][0])
    last = (course[0][-1], course[1][-1], course[2][-1])
    while pool:
        best, key = None, np.inf
        for n, f in enumerate(pool):
            for a, z in (((f[0][-1], f[1][-1], f[2][-1]), first), (last, (f[0][0], f[1][0], f[2][0]))):
                dt = z[0] - a[0]
                if not 0 < dt <= FRAGMENT_GAP_S:
                    continue
                miss = abs(z[1] - a[1] - 0.5 * (a[2] + z[2]) * dt)
                if _links(miss, z[2] - a[2], dt) and dt < key:
                    best, key = n, dt
        if best is None:
            break
        f = pool.pop(best)
        got.append(f)
        if f[0][0] < first[0]:
            first = (f[0][0], f[1][0], f[2][0])
        else:
            last = (f[0][-1], f[1][-1], f[2][-1])
    return got


def _chains(t: np.ndarray, d: np.ndarray, v: np.ndarray) -> list[np.ndarray]:
    """The points (time s, distance m, velocity m/s; in time order) linked into chains,
    nearest first, one point a chain at each time."""
    open_: list[list[int]] = []
    out: list[list[int]] = []
    starts = np.r_[0, np.flatnonzero(np.diff(t) > 0) + 1, t.size] if t.size else np.zeros(1, int)
    for a, b in zip(starts[:-1], starts[1:], strict=True):
        now = float(t[a])
        going = [now - t[c[-1]] <= GAP_S for c in open_]
        out += [c for c, g in zip(open_, going, strict=True) if not g]
        open_ = [c for c, g in zip(open_, going, strict=True) if g]
        taken = np.zeros(b - a, bool)
        if open_:
            last = np.array([c[-1] for c in open_])
            dt = now - t[last]
            at = d[last][None, :] + 0.5 * (v[last][None, :] + v[a:b, None]) * dt[None, :]
            miss = np.abs(d[a:b, None] - at)
            fits = _links(miss, v[a:b, None] - v[last][None, :], dt)
            miss[~fits] = np.inf
            for i, n in nearest_first(miss):
                open_[n].append(a + i)
                taken[i] = True
        open_ += [[a + int(i)] for i in np.flatnonzero(~taken)]
    return [np.asarray(c) for c in out + open_]


def _links(miss, dv, dt):
    """Whether a point `miss` (m) off where a chain's motion carries it across `dt` (s),
    its velocity `dv` (m/s) off the chain's, goes on the chain: within LINK_M + ACCEL_MAX
    dt^2 / 8 and AGREE_MPS + ACCEL_MAX dt (arrays, or one of each)."""
    return (miss <= LINK_M + ACCEL_MAX * dt * dt / 8) & (np.abs(dv) <= AGREE_MPS + ACCEL_MAX * dt)


def outside(pts: dict, spans: list[tuple[float, float]]) -> dict:
    """The points `pts` beside no known moving echo of `spans` (m; moving_echoes.off_spans,
    as unheld's detections)."""
    keep = off_spans(np.asarray(pts[POINT_KEYS[1]]), spans)
    return {k: np.asarray(x)[keep] for k, x in pts.items()}
