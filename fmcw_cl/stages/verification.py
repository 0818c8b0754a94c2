"""The verification of the tracked pairs: which pairs' distances agree with what their
trusted neighbours predict (`continuity`, `agreeing`, `_residuals`), and validity as a
fixed point over the whole capture (`verify`): the neighbours' test, the test of
motion within KINEMATIC_S (`_kinematic`, `disagreed`), runs that drift from their
integrated velocity (`_drifting`), runs at rest that the motion passes by
(`_bridged`) and short runs without an anchor (`_anchored`).
"""

from __future__ import annotations

import numpy as np

from .. import numeric
from ..numeric import median, padded, row_nanmedian
from ..spectrum_ops import NUMPY, SpectrumOps
from .groups import NEIGHBOURS, group_ends, group_slices

CONSISTENT_MPS = 0.1  # a velocity this far from its neighbours' median is an outlier
JUMP_M = 0.25e-3      # a distance this far from its neighbours' prediction is discontinuous
JUMP_SIGMAS = 6.0     # ... or this many robust standard deviations of the chunk's residuals
JUMP_MAX_M = 1e-3     # ... but never more than this
RESIDUAL_BLOCK = 4096      # pairs whose neighbours' predictions are taken at once
SUPPORT = 2           # trusted neighbours needed to vouch for a pair
ANCHOR_PAIRS = 2 * NEIGHBOURS + 1   # a run of valid pairs this long stands on its own
ACCEL_MAX = 500.0     # m/s^2: how far a shorter run may stray from an anchor across its gap
ANCHOR_GAP_S = 5e-3   # ... a gap at most this long (over 5 ms the bound exceeds 2.6 mm and grows as dt^2)
KINEMATIC_S = 2e-3    # pairs this close in time must agree as one body's motion (`_kinematic`)
KINEMATIC_PAIRS = 48  # half-width (pairs) of the window searched for them (2.4 ms at 50 us)
DRIFT_S = 5e-3        # a run of valid pairs this long ...
DRIFT_MPS = 0.3       # ... whose distance leaves its integrated velocity this fast is dropped (a sync
                      # delay's error leaves at most ~0.1 m/s; a wrong echo held 25 ms: 0.94 m/s)
DRIFT_PAIRS = ANCHOR_PAIRS  # a shorter run down to this many pairs (one that stands on its own) is
                      # dropped where its drift is also ...
DRIFT_SIGMAS = 5.0    # ... this many standard errors (a jackknife's over DRIFT_BLOCKS blocks: the
DRIFT_BLOCKS = 6      # distances are correlated over pairs)
REST_MPS = 0.3        # a run this slow (its median) between runs in motion ...
BRIDGE_S = 0.015      # ... that join across it, over at most this long, and joins neither, is dropped
END_PAIRS = 8         # a run's end: the medians of this many of its pairs


def _residuals(t: np.ndarray, dist: np.ndarray, vel: np.ndarray, trusted: np.ndarray,
               rows: np.ndarray | None = None, ends: tuple | None = None) -> tuple[np.ndarray, np.ndarray]:
    """For the pairs `rows` (all when None): |distance - the median prediction of its
    trusted neighbours| (inf with fewer than SUPPORT of them) and how many there are;
    `ends` (group_ends): neighbours only within a pair's group."""
    if rows is not None and every_row(rows, dist.size):
        resid, support = _residuals(t, dist, vel, trusted, ends=ends)
        return resid[rows], support[rows]
    if dist.size == 0:
        return np.zeros(0), np.zeros(0, np.int64)
    # each row's window of 2 NEIGHBOURS + 1 pairs (itself in the middle): strided views
    # of the padded arrays, taken RESIDUAL_BLOCK rows at a time (the (rows, window)
    # temporaries stay in cache), or copied for a subset of rows
    windows = [np.lib.stride_tricks.sliding_window_view(padded(np.asarray(a), NEIGHBOURS, fill),
                                                        2 * NEIGHBOURS + 1)
               for a, fill in ((trusted, False), (t, 0.0), (dist, 0.0), (vel, 0.0))]
    blocks = [rows] if rows is not None else [slice(a, a + RESIDUAL_BLOCK)
                                              for a in range(0, dist.size, RESIDUAL_BLOCK)]
    got = [_residuals_of(at, t, dist, vel, *windows, ends) for at in blocks]
    if len(got) == 1:
        return got[0]
    return np.concatenate([g[0] for g in got]), np.concatenate([g[1] for g in got])


def every_row(rows: np.ndarray | None, pairs: int) -> bool:
    """Whether `_residuals` of the pairs `rows` of `pairs` (None: all) are best taken for
    every pair (strided views) and picked."""
    return rows is None or rows.size > pairs // 4


def _residuals_of(at, t, dist, vel, ok, tj, dj, vj, ends) -> tuple[np.ndarray, np.ndarray]:
    """_residuals of the pairs `at` (a slice or indices), from the windows of the trusted
    flags, times, distances and velocities."""
    ok = np.array(ok[at])
    if ends is not None:
        ok &= numeric.window_index(dist.size, NEIGHBOURS, ends, at)[1]
    ok[:, NEIGHBOURS] = False                   # a pair does not vouch for itself
    support = ok.sum(axis=1)
    tj, dj, vj = tj[at], dj[at], vj[at]
    pred = np.where(ok, dj + (t[at, None] - tj) * 0.5 * (vel[at, None] + vj), np.nan)
    with np.errstate(invalid="ignore"):
        resid = np.where(support >= SUPPORT, np.abs(dist[at] - row_nanmedian(pred)), np.inf)
    return resid, support


def _tolerance(resid: np.ndarray, trusted: np.ndarray) -> float:
    """JUMP_M, or JUMP_SIGMAS robust standard deviations of the trusted pairs' residuals
    (a noisy capture), at most JUMP_MAX_M: when most pairs are wrong their scatter must
    not widen the test until wrong pairs pass."""
    sure = np.isfinite(resid) & trusted
    sigma = 1.4826 * median(resid[sure]) if sure.any() else 0.0
    return min(max(JUMP_M, JUMP_SIGMAS * sigma), JUMP_MAX_M)


def continuity(t: np.ndarray, dist: np.ndarray, vel: np.ndarray, trusted: np.ndarray,
               groups: np.ndarray | None = None) -> np.ndarray:
    """Which pairs' distances agree with what their trusted neighbours predict.

    Neighbour j (within NEIGHBOURS pairs) predicts d_j + (t_i - t_j) (v_i + v_j) / 2 for
    pair i (the velocities are measured to mm/s, so the prediction is as good as d_j).
    A pair agrees when the median prediction is within JUMP_M, or JUMP_SIGMAS robust
    standard deviations of all residuals (a noisy capture; at most JUMP_MAX_M), of its
    distance, and at least SUPPORT neighbours vouch for it. A noise peak in a fade, or
    both half-sweeps on another echo, moves both sweeps' distances alike: the velocity
    test cannot see it, this one does. `groups`: each group of pairs on its own
    (`group_slices`).
    """
    resid, _ = _residuals(t, dist, vel, trusted, ends=group_ends(groups, t.size))
    return agreeing(resid, trusted, groups)


def agreeing(resid: np.ndarray, trusted: np.ndarray, groups: np.ndarray | None = None) -> np.ndarray:
    """`continuity` from the pairs' residuals (`_residuals`, m): within the tolerance of
    their group's trusted pairs (`_tolerance`)."""
    if groups is None:
        return resid <= _tolerance(resid, trusted)
    out = np.empty(resid.size, bool)
    for g in group_slices(groups, resid.size):
        out[g] = resid[g] <= _tolerance(resid[g], trusted[g])
    return out


def verify(t: np.ndarray, dist: np.ndarray, vel: np.ndarray, ok: np.ndarray, ops: SpectrumOps = NUMPY,
           looks: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Validity as a fixed point: of the pairs `ok`, those that at least SUPPORT other
    pairs of the final set vouch for (`continuity`'s test, against the final set only).

    A pair vouched for by neighbours that are themselves rejected is rejected in turn,
    until nothing changes; only the pairs near a change are tested again. Between
    rounds, the pairs that most valid pairs within KINEMATIC_S disagree with are dropped
    (`_kinematic`), runs whose distance leaves their integrated velocity (`_drifting`),
    and runs at rest that the motion around them passes by (`_bridged`); last, short
    runs need an anchor (`_anchored`). `ops`: whose `residuals` and `disagreed` (a
    backend's: on its device); `looks`: per pair, the half-sweeps of a direction its
    spectra summed (stages.integrate; None: one).

    Returns
    -------
    verified : the final set.
    unsupported : pairs of `ok` dropped for too few valid neighbours (the others
        dropped disagree with theirs).
    """
    ok = np.asarray(ok, bool).copy()
    unsupported = np.zeros(ok.size, bool)
    _vouched(t, dist, vel, ok, unsupported, ops)
    while _kinematic(t, dist, vel, ok, ops) | _drifting(t, dist, vel, ok) | _bridged(t, dist, vel, ok):
        _vouched(t, dist, vel, ok, unsupported, ops)
    _anchored(t, dist, vel, ok, unsupported, looks)
    return ok, unsupported


def _agrees(ta, da, va, tb, db, vb):
    """Whether pairs (ta, da, va) predict pairs (tb, db, vb) (s, m, m/s) as one body
    whose acceleration stays within ACCEL_MAX: `reachable`, and the velocity within
    ACCEL_MAX |dt| + CONSISTENT_MPS. Symmetric in a and b."""
    steady = np.abs(vb - va) <= ACCEL_MAX * np.abs(tb - ta) + CONSISTENT_MPS
    return reachable(ta, da, va, tb, db, vb) & steady


def reachable(ta, da, va, tb, db, vb):
    """Whether one body whose acceleration stays within ACCEL_MAX moves from pairs (ta,
    da, va) to pairs (tb, db, vb) (s, m, m/s): the distance within JUMP_MAX_M + ACCEL_MAX
    dt^2 / 8 of the trapezoid d_a + dt (v_a + v_b) / 2 (its error bound for any such
    motion). Symmetric in a and b."""
    dt = tb - ta
    return np.abs(db - da - dt * 0.5 * (va + vb)) <= JUMP_MAX_M + ACCEL_MAX * dt * dt / 8


def _kinematic(t, dist, vel, ok, ops: SpectrumOps) -> bool:
    """Drop, in place, the pairs of `ok` that most of the other pairs of `ok` within
    KINEMATIC_S disagree with (`disagreed`); whether any was dropped.

    The neighbours' test spans 0.4 ms, over which a velocity a few m/s off moves the
    prediction by less than its tolerance: a wrong echo followed for a few ms (a
    Doppler image beside a wall, one direction's peak on another echo) passes it while
    its velocities disagree with its own distances' course by cm. Over 2 ms the two
    part; a right pair beside a few wrong ones keeps its majority.
    """
    drop = ops.disagreed(t, dist, vel, ok)
    ok[drop] = False
    return bool(drop.any())


def disagreed(t: np.ndarray, dist: np.ndarray, vel: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """The pairs of `ok` (times s, distances m, velocities m/s) that most of the other
    pairs of `ok` within KINEMATIC_S disagree with (`_agrees`; twin: kernels/verify.cl)."""
    agree = np.zeros(ok.size, np.int32)
    near = np.zeros(ok.size, np.int32)
    for k in range(1, min(KINEMATIC_PAIRS, ok.size - 1) + 1):      # pairs k apart, both ways at once
        a, b = slice(0, ok.size - k), slice(k, ok.size)
        both = ok[a] & ok[b] & (t[b] - t[a] <= KINEMATIC_S)
        if not both.any():                  # pairs k apart are all further apart than that
            continue
        with np.errstate(invalid="ignore"):
            yes = both & _agrees(t[a], dist[a], vel[a], t[b], dist[b], vel[b])
        near[a] += both
        near[b] += both
        agree[a] += yes
        agree[b] += yes
    return ok & (2 * agree < near)


def _runs(t, dist, vel, ok) -> list[np.ndarray]:
    """The runs of the valid pairs `ok` (indices): cut at gaps of more than NEIGHBOURS
    pairs and where the next valid pair leaves its kinematics (a wrong echo beside right
    pairs joins no run of theirs)."""
    idx = np.flatnonzero(ok)
    if idx.size == 0:
        return []
    a, b = idx[:-1], idx[1:]
    cut = np.flatnonzero((b - a > NEIGHBOURS) | ~_agrees(t[a], dist[a], vel[a], t[b], dist[b], vel[b])) + 1
    return np.split(idx, cut)


def _drifting(t, dist, vel, ok) -> bool:
    """Drop, in place, the runs (`_runs`) whose distance less the integral of their
    velocity has a least-squares slope beyond DRIFT_MPS: those of at least DRIFT_S, and
    those of at least DRIFT_PAIRS where the slope is also DRIFT_SIGMAS standard errors
    (numeric.drifts' jackknife), all runs at once; whether any was. Within 2 ms a
    velocity 1 m/s off moves the prediction by 2 mm, against a tolerance of 1.25: a
    wrong echo held at one distance for 25 ms with a velocity of 0.94 m/s passes
    `_kinematic`; over its run it drifts by 23 mm. Its last 4.95 ms, where the target
    came within 2-3.5 mm of it and the run was cut from the rest, drifted at -0.74 m/s,
    20 standard errors. Under noise at full scale, a take-off past the band's edge left
    28 pairs (1.35 ms) at 1.6 m/s and 49 mm short of the target, de-chirped 3-4 dB over
    the floor: 0.44 m/s, 6.7 standard errors."""
    runs = _runs(t, dist, vel, ok)
    if not runs:
        return False
    sizes = np.array([r.size for r in runs])
    idx = np.concatenate(runs)
    ends = np.cumsum(sizes)
    long = t[idx[ends - 1]] - t[idx[ends - sizes]] >= DRIFT_S
    tested = long | (sizes >= max(3, DRIFT_PAIRS))
    if not tested.any():
        return False
    mine = idx[np.repeat(tested, sizes)]
    slope, se = numeric.drifts(t[mine], dist[mine], vel[mine], sizes[tested], DRIFT_BLOCKS)
    limit = np.where(long[tested], DRIFT_MPS, np.fmax(DRIFT_MPS, DRIFT_SIGMAS * se))
    drifts = np.zeros(sizes.size, bool)
    drifts[tested] = np.abs(slope) > limit
    ok[idx[np.repeat(drifts, sizes)]] = False
    return bool(drifts.any())


def _bridged(t, dist, vel, ok) -> bool:
    """Drop, in place, the runs (`_runs`) at rest (median speed under REST_MPS) that the
    nearest runs on either side whose facing ends move (END_PAIRS long at least) pass
    by: those two join as one body across it (`_agrees` of their facing ends, each the
    medians of END_PAIRS pairs, at most BRIDGE_S apart) while it joins neither; whether
    any was. A wall the fixed echoes' tables miss (a rail's target passing 4 mm from one
    of 400 codes) holds the tracker for 5 ms at a time: self-consistent, its pairs at
    rest, up to 18 mm from where the target went on."""
    runs = _runs(t, dist, vel, ok)
    if len(runs) < 3:
        return False

    def end(r, last):
        k = r[-END_PAIRS:] if last else r[:END_PAIRS]
        return median(t[k]), median(dist[k]), median(vel[k])

    # the runs long enough to have ends, and those whose last (first) end moves, in order
    # (a landing's last run comes to rest: its median speed is no matter)
    sizes = np.array([r.size for r in runs])
    long = np.flatnonzero(sizes >= END_PAIRS)
    if long.size < 2:
        return False
    moves = [np.abs(np.median(vel[np.stack([runs[i][k] for i in long])], axis=1)) >= REST_MPS
             for k in (slice(-END_PAIRS, None), slice(END_PAIRS))]
    leaving, arriving = long[moves[0]], long[moves[1]]
    speed = numeric.group_median(np.repeat(np.arange(len(runs)), sizes), vel[np.concatenate(runs)], len(runs))
    dropped = False
    for i in np.flatnonzero((sizes >= 3) & ~(np.abs(speed) >= REST_MPS)):
        b, a = np.searchsorted(leaving, i), np.searchsorted(arriving, i, side="right")
        if b == 0 or a == arriving.size:
            continue
        r = runs[i]
        before, after = end(runs[leaving[b - 1]], True), end(runs[arriving[a]], False)
        if (after[0] - before[0] <= BRIDGE_S and _agrees(*before, *after)
                and not _agrees(*before, *end(r, False)) and not _agrees(*end(r, True), *after)):
            ok[r] = False
            dropped = True
    return dropped


def _vouched(t, dist, vel, ok, unsupported, ops: SpectrumOps) -> None:
    """`verify`'s fixed point of the neighbours' test, in place."""
    rows = np.flatnonzero(ok)
    tol = None
    while rows.size:
        resid, support = ops.residuals(t, dist, vel, ok, rows)
        tol = _tolerance(resid, ok[rows]) if tol is None else tol   # the capture's scatter, once
        drop = resid > tol
        if not drop.any():
            break
        gone = rows[drop]
        ok[gone] = False
        unsupported[gone] = support[drop] < SUPPORT
        hit = np.zeros(ok.size, np.int32)
        hit[gone] = 1
        reach = np.convolve(hit, np.ones(2 * NEIGHBOURS + 1, np.int32))       # pairs within reach of a drop
        near = reach[NEIGHBOURS:NEIGHBOURS + ok.size] > 0
        rows = np.flatnonzero(ok & near)


def _anchored(t, dist, vel, ok, unsupported, looks=None) -> None:
    """Runs of valid pairs (no gap wider than NEIGHBOURS pairs, each pair predicting the
    next as below) shorter than ANCHOR_PAIRS vouch for each other only: such a run stays
    valid where the anchor run nearest on either side predicts its end (`_agrees`)
    across a gap of at most ANCHOR_GAP_S; else every pair of it is unsupported (a wrong
    echo followed for a few pairs is self-consistent). Pairs whose spectra sum K
    half-sweeps (`looks`) share them with their K - 1 neighbours on each side, and one
    half-sweep's noise lifts the peaks of K of them: a run of them is an anchor with K
    + 1 pairs at least, two looks apart (18 pairs at K = 32, 0.9 ms, stood on their
    own: a noise peak integrated along the track paired with a mover's real peak in the
    other direction, 110 mm from both movers; an object passing for 8 ms, runs of 33-45
    pairs 3 ms apart, stands)."""
    runs = _runs(t, dist, vel, ok)
    if not runs:
        return

    def agrees(a, b):                           # pair a predicts pair b
        return _agrees(t[a], dist[a], vel[a], t[b], dist[b], vel[b])

    def anchor(r) -> bool:
        return r.size >= max(ANCHOR_PAIRS, 0 if looks is None else int(looks[r].max()) + 1)

    anchors = [r for r in runs if anchor(r)]
    firsts = np.array([r[0] for r in anchors])
    for r in runs:
        if anchor(r):
            continue
        k = np.searchsorted(firsts, r[0])         # anchors[k - 1] lies before r, anchors[k] after
        sides = ([(anchors[k - 1][-1], r[0])] if k > 0 else []) + \
                ([(anchors[k][0], r[-1])] if k < len(anchors) else [])
        if not any(abs(t[b] - t[a]) <= ANCHOR_GAP_S and bool(agrees(a, b)) for a, b in sides):
            ok[r] = False
            unsupported[r] = True
