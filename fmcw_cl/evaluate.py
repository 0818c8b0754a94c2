"""Accuracy of a track against a capture's /truth (used by tests and benchmarks)."""

from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicSpline

from . import fixed_echoes
from .capture_format import Truth
from .stages import faults
from .track import Track
from .uncertainty import crb_m, peak_eta


def truth_at(truth: Truth, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """True distance, velocity and acceleration at times t (cubic interpolation)."""
    return tuple(CubicSpline(truth.time_s, y)(t) for y in
                 (truth.distance_m, truth.velocity_mps, truth.acceleration_mps2))


def valid_errors(track: Track, truth: Truth) -> np.ndarray:
    """|distance - true distance| (m) of each valid pair."""
    r, _, _ = truth_at(truth, track.time_s[track.valid])
    return np.abs(track.distance_m[track.valid] - r)


def covered(track: Track, errors: np.ndarray) -> str:
    """The share (%) of valid pairs whose distance error (`valid_errors`) lies within
    their expanded uncertainty, as printed in a benchmark's row ("-" without pairs)."""
    if not errors.size or track.distance_uncertainty_m is None:
        return "-"
    return f"{100 * np.mean(errors <= track.distance_uncertainty_m[track.valid]):.1f}"


def invalid_reasons(track: Track) -> str:
    """The invalid pairs' count by reason ("no_echo 12, unstable 3"; empty when none)."""
    return ", ".join(f"{faults.REASONS[k]} {int(np.sum(track.reason == k))}"
                     for k in np.unique(track.reason) if k)


def accuracy(track: Track, truth: Truth) -> dict:
    """Error figures of the valid pairs (SI units).

    Returns valid share, distance bias/std/p95/max, velocity p95/max, acceleration
    p95/max (acceleration where defined).
    """
    v = track.valid
    r, vel, acc = truth_at(truth, track.time_s[v])
    ed = track.distance_m[v] - r
    ev = track.velocity_mps[v] - vel
    ea = track.acceleration_mps2[v] - acc
    ea = ea[np.isfinite(ea)]

    def p95(x):
        return float(np.percentile(np.abs(x), 95)) if x.size else float("nan")

    def mx(x):
        return float(np.max(np.abs(x))) if x.size else float("nan")

    return {
        "pairs": int(track.pairs),
        "valid_share": float(np.mean(v)) if track.pairs else 0.0,
        "distance_bias_m": float(np.mean(ed)) if ed.size else float("nan"),
        "distance_std_m": float(np.std(ed)) if ed.size else float("nan"),
        "distance_p95_m": p95(ed), "distance_max_m": mx(ed),
        "velocity_p95_mps": p95(ev), "velocity_max_mps": mx(ev),
        "acceleration_p95_mps2": p95(ea), "acceleration_max_mps2": mx(ea),
    }


def crb_pair_m(eta: float, points: int, bandwidth_hz: float, refractive_index: float = 1.0) -> float:
    """Cramer-Rao bound (m, standard deviation) of one pair's distance from the N resampled
    points of per-point SNR eta (`uncertainty.crb_m`): a pair averages two half-sweeps."""
    return float(crb_m(eta, points, bandwidth_hz, refractive_index) / np.sqrt(2))


def eta_from_peak_snr(snr_db, points: int) -> float:
    """Per-point SNR eta of the resampled half-sweeps from their peaks' median SNR (dB;
    `uncertainty.peak_eta`)."""
    return float(peak_eta(np.median(np.asarray(snr_db, float)), points))


WRONG_M = 2e-3   # a valid pair further than this from its own object's truth is wrong


def truth_visible(truth: Truth, t: np.ndarray, span_s: float = 0.0) -> np.ndarray:
    """Whether the object of `truth` can be seen at times `t` (s), or anywhere within
    +-`span_s` / 2 of them (a pair that integrates half-sweeps over `span_s`)."""
    if truth.visible is None:
        return np.ones(np.shape(t), bool)
    seen = np.r_[0, np.cumsum(truth.visible)]
    lo = np.clip(np.searchsorted(truth.time_s, np.asarray(t) - span_s / 2), 0, truth.time_s.size - 1)
    hi = np.clip(np.searchsorted(truth.time_s, np.asarray(t) + span_s / 2), 0, truth.time_s.size - 1)
    return seen[hi + 1] - seen[lo] > 0


def _misses(track: Track, truths: list[Truth]) -> np.ndarray:
    """(truths, valid pairs): each valid pair's distance from each truth object (m),
    inf where that object is not visible then (within the span of half-sweeps it
    integrates)."""
    t, d = track.time_s[track.valid], track.distance_m[track.valid]
    span = float(track.attrs.get("time_resolution_s", 0.0))
    err = np.full((len(truths), t.size), np.inf)
    for k, tr in enumerate(truths):
        err[k] = np.where(truth_visible(tr, t, span), np.abs(d - truth_at(tr, t)[0]), np.inf)
    return err


def on_objects(track: Track, truths: list[Truth]) -> np.ndarray:
    """For each valid pair of `track`, the index of the truth object (of `truths`)
    within WRONG_M of its distance, visible then (within the span of half-sweeps it
    integrates; the nearest where several are), or -1 where none is."""
    return _nearest(_misses(track, truths))


def _nearest(err: np.ndarray) -> np.ndarray:
    """`on_objects` of the pairs' `_misses`."""
    best = np.argmin(err, axis=0) if err.shape[0] else np.zeros(err.shape[1], np.int64)
    return np.where(np.min(err, axis=0, initial=np.inf) <= WRONG_M, best, -1)


def followed(track: Track, truths: list[Truth]) -> int:
    """The truth object (index of `truths`) that `track`'s valid pairs follow: the one
    most of them lie on alone (within WRONG_M of it and of no other), else the one most
    lie on (`on_objects`), else 0. Two legs at rest at one distance: the pairs of both
    tell neither; those before the second came there tell which (an object's first three
    pairs 0.0 mm from the leg it held, 2.1 mm from the other, were counted "wrong" when
    the tie went to the other)."""
    err = _misses(track, truths)
    near = err <= WRONG_M
    alone = near & (near.sum(axis=0) == 1)
    if alone.any():
        return int(np.argmax(alone.sum(axis=1)))
    on = _nearest(err)
    return int(np.bincount(on[on >= 0], minlength=len(truths)).argmax()) if (on >= 0).any() else 0


def periods_tracked(track: Track, truth: Truth) -> float:
    """The share of the pairs where `truth`'s object is visible (the whole pair) at
    which `track` holds a valid pair within WRONG_M of it."""
    half = 0.5 * (track.period_s or 50e-6)
    t = track.time_s
    seen = truth_visible(truth, t - half) & truth_visible(truth, t + half)
    near = track.valid & (np.abs(track.distance_m - truth_at(truth, t)[0]) <= WRONG_M)
    return float(np.sum(near & seen) / max(1, np.sum(seen)))


def object_scores(track: Track, truths: list[Truth]) -> list[dict]:
    """Per object of `track` (`Track.objects`; the track alone where it lists none): its
    id, the truth it follows (the index of `truths`, `followed`; None without valid
    pairs), its valid pairs more than WRONG_M from that truth or while it is hidden
    ("wrong"), and the share of that truth's visible periods it holds ("tracked",
    `periods_tracked`)."""
    out = []
    for o in track.objects or [None]:
        t = track if o is None else o.track
        ident = int(track.attrs.get("target_object", 1)) if o is None else o.id
        if not t.valid.any():
            out.append({"id": ident, "truth": None, "wrong": 0, "tracked": 0.0})
            continue
        own = followed(t, truths)
        when = t.time_s[t.valid]
        err = np.abs(t.distance_m[t.valid] - truth_at(truths[own], when)[0])
        seen = truth_visible(truths[own], when, float(t.attrs.get("time_resolution_s", 0.0)))
        out.append({"id": ident, "truth": own, "wrong": int(np.sum((err > WRONG_M) | ~seen)),
                    "tracked": periods_tracked(t, truths[own])})
    return out


def best_held(scores: list[dict], truths: int) -> list[float]:
    """Per truth (0 .. `truths` - 1), the largest share of its visible periods one object
    holds (`object_scores`' "tracked" of the objects that follow it; 0 where none does)."""
    return [max((s["tracked"] for s in scores if s["truth"] == k), default=0.0) for k in range(truths)]


def objects_cell(track: Track, truths: list[Truth]) -> str:
    """A benchmark's cell for the scene: the objects found and, in brackets, their valid
    pairs off the truth each follows (`object_scores`; "?" where the capture holds no
    truth of its other echoes: written before /truth/objects)."""
    n = len(track.objects or [None])
    if n > 1 and len(truths) < 2:
        return f"{n} (?)"
    return f"{n} ({sum(s['wrong'] for s in object_scores(track, truths))})"


UNTRACKED = ("held", "as one", "beside", "elsewhere", "outside", "unverified", "missed")
ONE_M = fixed_echoes.ONE_M     # two echoes this close make one peak (two range resolutions)


def untracked(track: Track, truths: list[Truth], gate_m: float = 0.01) -> list[dict]:
    """Where each truth object's visible periods (the whole pair, as `periods_tracked`)
    went, as shares of them, each period counted under the first of UNTRACKED that
    holds: its best object held a valid pair within WRONG_M ("held"); another truth lay
    within ONE_M (one peak: no measurement tells the two apart, "as one"), or within
    `gate_m` (m; "beside": the scene's rules do not tell them apart); another object held
    it ("elsewhere": one body in two ids); no object's band (attribute target_band_m)
    held its distance ("outside"); an object's path (the mean of its pair's de-chirped
    peaks) lay within WRONG_M, unverified or ambiguous ("unverified"); none did
    ("missed": every tracker elsewhere). One dict per truth, also "periods" and
    "apart_held": the share of its periods not "as one" that its best object held."""
    from .objects import per_pair

    objs = [o.track for o in track.objects] if track.objects else [track]
    t = track.time_s
    half = 0.5 * (track.period_s or 50e-6)
    where = [truth_at(tr, t)[0] for tr in truths]
    near = np.array([[o.valid & (np.abs(o.distance_m - d) <= WRONG_M) for o in objs] for d in where])
    paths = [np.mean(per_pair(o, "sweep_distance_dechirped_m"), axis=0) for o in objs]
    bands = [np.nan_to_num(np.asarray(o.attrs.get("target_band_m", (0.0, np.inf)), float), nan=np.inf)
             for o in objs]
    out = []
    for k, (tr, d) in enumerate(zip(truths, where, strict=True)):
        seen = truth_visible(tr, t - half) & truth_visible(tr, t + half)
        best = int(np.argmax(near[k].sum(axis=1)))
        others = [np.abs(d - e) for j, e in enumerate(where) if j != k]
        gap = np.min(others, axis=0) if others else np.full(t.size, np.inf)
        steps = [near[k][best], gap < ONE_M, gap < gate_m, near[k].any(axis=0),
                 ~np.any([(d >= b[0]) & (d <= b[1]) for b in bands], axis=0),
                 np.any([np.abs(p - d) <= WRONG_M for p in paths], axis=0), np.ones(t.size, bool)]
        left, row = seen.copy(), {"periods": int(seen.sum())}
        for name, hit in zip(UNTRACKED, steps, strict=True):
            row[name] = float(np.sum(left & hit) / max(1, seen.sum()))
            left &= ~hit
        apart = seen & (gap >= ONE_M)
        row["apart_held"] = float(np.sum(apart & near[k][best]) / max(1, apart.sum()))
        out.append(row)
    return out
