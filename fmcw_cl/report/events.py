"""The event table (the paper's Table 1), found in a track without being told where.

Events of a trajectory sampled every pair:
- ``apex``: the largest prominent maximum of the distance;
- ``velocity_peak`` / ``velocity_valley``: prominent extrema of the velocity;
- ``acceleration_peak`` / ``acceleration_valley``: prominent extrema of the acceleration;
- ``impact``: an acceleration peak that stops an approach (the target moves towards
  the sensor, velocity < 0, and is braked, acceleration > 0): a foot striking the
  ground under a LiDAR mounted on the leg.

Each extremum is refined by a least-squares cubic through the samples of its top (a
cubic, because the peaks of a jump are not symmetric), so its time is not limited to
the 50 us pair spacing. Extrema are kept when their prominence is at least
`PROMINENCE` of the series' largest magnitude (that keeps the paper's second strike,
78 m/s^2 beside 365 m/s^2) and at least `NOISE_FACTOR` times the series' noise, the
spread of its quietest stretch (that drops the noise of a resting target).

Only verified stretches are used (`verified_stretches`): runs of valid pairs at least
as long as the acceleration's Savitzky-Golay window (stages.kinematics.WINDOW_PAIRS),
so that an isolated pair is never an event. An extremum within half that window of the
data's edge or of a gap is not an event: what happened may lie outside the data (a
take-off whose capture ends while the foot still rises has its largest distance at
its last pair, and no apex). The true events are found the same way on the truth's
own trajectory over the capture's span.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from scipy.signal import find_peaks

from ..numeric import runs
from ..stages.kinematics import WINDOW_PAIRS

PROMINENCE = 0.1     # of the largest magnitude of the series
REFINE_S = 5e-3      # largest half-width of the cubic fitted around an extremum
TOP = 0.9            # the cubic is fitted where |y| is above this share of the extremum
NOISE_FACTOR = 10.0
NOISE_BLOCK = 100    # samples per stretch of the noise estimate
MATCH_S = 5e-3       # a measured event and a true one are the same within this
EDGE_S = (WINDOW_PAIRS // 2) * 50e-6   # no event this near an edge (s): half the window at 20 kHz


@dataclass(frozen=True)
class Event:
    """One event: what, when (s) and the value (SI unit of its quantity)."""

    kind: str
    quantity: str    # distance_m, velocity_mps or acceleration_mps2
    time_s: float
    value: float


def verified_stretches(valid: np.ndarray, min_pairs: int = WINDOW_PAIRS) -> np.ndarray:
    """The valid pairs that lie in runs of at least `min_pairs` consecutive valid pairs."""
    out = np.zeros(np.size(valid), bool)
    for a, b in runs(valid):
        if b - a >= min_pairs:
            out[a:b] = True
    return out


def left_out(valid: np.ndarray, used: np.ndarray) -> dict:
    """Pairs an event table left out, by why: invalid, or valid in too short a run."""
    return {"pairs": int(valid.size), "invalid": int(np.sum(~valid)),
            "short_stretches": int(np.sum(valid & ~used)), "min_stretch_pairs": WINDOW_PAIRS}


def _refine(t: np.ndarray, y: np.ndarray, i: int, width: float) -> tuple[float, float]:
    """Extremum of a least-squares cubic through the top of the extremum at t[i].

    The top is where |y| stays above TOP of |y[i]| (broad peaks get many samples,
    sharp ones few), at most `width` either side.
    """
    level = TOP * abs(y[i])
    lo = i
    while lo > 0 and abs(y[lo - 1]) >= level and t[i] - t[lo - 1] <= width:
        lo -= 1
    hi = i
    while hi < y.size - 1 and abs(y[hi + 1]) >= level and t[hi + 1] - t[i] <= width:
        hi += 1
    if hi - lo < 5:
        return float(t[i]), float(y[i])
    x = t[lo:hi + 1] - t[i]
    poly = np.polynomial.Polynomial.fit(x, y[lo:hi + 1], 3)
    roots = poly.deriv().roots()
    roots = roots[np.isreal(roots)].real
    roots = roots[(roots >= x[0]) & (roots <= x[-1])]
    if roots.size == 0:                  # no extremum inside the top: keep the sample
        return float(t[i]), float(y[i])
    dx = roots[np.argmin(np.abs(roots))]
    return float(t[i] + dx), float(poly(dx))


def _noise(y: np.ndarray) -> float:
    """Standard deviation of the quietest stretch of y (NaN-free)."""
    blocks = y.size // NOISE_BLOCK
    if blocks == 0:
        return float(np.std(y))
    return float(np.min(np.std(y[:blocks * NOISE_BLOCK].reshape(blocks, NOISE_BLOCK), axis=1)))


def _extrema(t: np.ndarray, y: np.ndarray, sign: int, width: float, edge_s: float,
             prominence: float = PROMINENCE) -> list[tuple[float, float]]:
    """Prominent maxima (sign +1) or minima (sign -1) of y(t), none within `edge_s` of
    an end of y's runs of finite values (the data's edges, its gaps)."""
    ok = np.isfinite(y)
    if ok.sum() < 5:
        return []
    spans = runs(ok)
    ends = np.concatenate([t[spans[:, 0]], t[spans[:, 1] - 1]])         # each run's first and last time
    tt, yy = t[ok], y[ok]
    scale = float(np.max(np.abs(yy)))
    if scale == 0:
        return []
    idx, _ = find_peaks(sign * yy, prominence=max(prominence * scale, NOISE_FACTOR * _noise(yy)))
    inner = [int(i) for i in idx if np.min(np.abs(ends - tt[i])) > edge_s]
    return [_refine(tt, yy, i, width) for i in inner]


def find_events(time_s: np.ndarray, distance_m: np.ndarray, velocity_mps: np.ndarray,
                acceleration_mps2: np.ndarray, refine_s: float = REFINE_S,
                edge_s: float = EDGE_S) -> list[Event]:
    """The events of one trajectory (NaN marks invalid pairs), sorted by time.

    Parameters
    ----------
    time_s : pair times (s).
    distance_m, velocity_mps, acceleration_mps2 : the track's values at those times.
    refine_s : largest half-width (s) of the cubic fitted around each extremum; a
        noise-free trajectory on a fine grid needs little.
    edge_s : no extremum within this of the data's edges or gaps is an event (s).
    """
    t = np.asarray(time_s, dtype=np.float64)
    d, v, a = (np.asarray(x, dtype=np.float64) for x in (distance_m, velocity_mps, acceleration_mps2))
    events: list[Event] = []
    ok = np.isfinite(d)
    if ok.sum() > 1 and np.ptp(d[ok]) > NOISE_FACTOR * _noise(d[ok]):   # not at rest
        tops = _extrema(t, d, 1, refine_s, edge_s, prominence=0.0)
        if tops:
            events.append(Event("apex", "distance_m", *max(tops, key=lambda top: top[1])))
    for sign, name in ((1, "peak"), (-1, "valley")):
        for tm, val in _extrema(t, v, sign, refine_s, edge_s):
            events.append(Event(f"velocity_{name}", "velocity_mps", tm, val))
        for tm, val in _extrema(t, a, sign, refine_s, edge_s):
            events.append(Event(f"acceleration_{name}", "acceleration_mps2", tm, val))
    vel_at = _interp_finite(t, v)
    for e in [e for e in events if e.kind == "acceleration_peak"]:
        if e.value > 0 and vel_at(e.time_s) < 0:
            events.append(Event("impact", "acceleration_mps2", e.time_s, e.value))
    return sorted(events, key=lambda e: (e.time_s, e.kind))


def _interp_finite(t: np.ndarray, y: np.ndarray):
    ok = np.isfinite(y)

    def at(x: float) -> float:
        return float(np.interp(x, t[ok], y[ok])) if ok.any() else float("nan")
    return at


def compare(measured: list[Event], truth: list[Event]) -> list[dict]:
    """Each measured event with the nearest true event of its kind (within MATCH_S).

    Returns dicts with the event's fields plus ``true_time_s``, ``true_value``,
    ``time_error_s``, ``value_error`` and ``value_error_rel`` (None when unmatched).
    """
    rows = []
    for e in measured:
        same = [g for g in truth if g.kind == e.kind and abs(g.time_s - e.time_s) <= MATCH_S]
        row = asdict(e)
        g = min(same, key=lambda g: abs(g.time_s - e.time_s)) if same else None
        row.update({
            "true_time_s": g.time_s if g else None,
            "true_value": g.value if g else None,
            "time_error_s": e.time_s - g.time_s if g else None,
            "value_error": e.value - g.value if g else None,
            "value_error_rel": (e.value - g.value) / abs(g.value) if g and g.value else None,
        })
        rows.append(row)
    return rows
