"""The scene as objects: every persistent echo, fixed or moving, tracked on its own.

The first conversion's tables list the scene's echoes (fmcw_cl.target): fixed echoes
(walls, windows, a target at rest) and moving spans (a leg, a swaying cable), with the
echoes its mean spectra hold, the verified pairs found elsewhere and the moving echoes
no tracker held (fmcw_cl.moving_echoes: a slow glide's lines). Each is a
*candidate*; each is converted in a band of its own, the others' nearer ends left out
(`target.choose` with `near_m`), so that its tracker cannot follow another, and its
pairs are verified as the target's are. Then:

- a tracker that still holds two echoes (a scene whose first conversion saw one of
  them only) is split (`parts_of`): its verified pairs part where fixed_echoes.APART_M
  of range holds none and it passes between the parts faster than a body moves; each part
  is a candidate of its own (once);
- two candidates whose verified pairs agree (within SAME_M at SAME_SHARE of the pairs
  both hold) are one echo (a target slowing onto its plateau is also a fixed echo);
- a fixed object's pairs are its own only at rest (under fixed_echoes.MOVING_MPS), within
  GATE_M of its distance and close to its median (target.ambiguous): anything else its
  band holds is something passing, or a blend with an echo beside it;
- where two objects lie within GATE_M of each other at one time, or a pair lies on
  another's harmonic or de-chirped image (fmcw_cl.crossings), their echoes cannot be
  told apart there: ``ambiguous`` on both, never given to the wrong one;
- an object whose verified pairs pass where no body moves (`bodies`: between two
  consecutive ones, verification.reachable's bound) is one object per part; so is a
  mover lost while another was, where either could have come back as the other (a
  crossing: fmcw_cl.identities);
- a mover lost beside a body at rest whose rest lies elsewhere after is cut there:
  another body stood there (fmcw_cl.exchanges);
- a pair whose two half-sweeps' phases do not move as one body's (two movers'
  Doppler-shifted peaks as they cross, a blend) is ``ambiguous`` (fmcw_cl.coherence);
- an object last seen where another of its kind is first seen, within RETURN_M (moved
  on at its velocities, or as it lay where one end is at rest; within KINEMATIC_S, only
  where one body moves so), the two never seen at once, is one object that was hidden or
  faded (`returns`, `joined`); among several movers, only where their motions tell that
  join from every other (identities.contested);
- the target is the object the rule names (`choose`): `auto` takes a moving one before
  a fixed one, the one that travels furthest (a leg before a swaying cable); where no
  object moves and several hold verified pairs, nothing tells which is the target, and
  /track's pairs are ``ambiguous`` (each object keeps its own).

A scene of one candidate costs what the target's conversion costs; each further one a
conversion in its own band (none where its band is the user's: the first conversion's
measurements are assembled again).
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np

from . import fixed_echoes, numeric, target
from .stages import faults
from .stages.verification import ACCEL_MAX, KINEMATIC_S, reachable
from .track import Track

GATE_M = fixed_echoes.GATE_M   # two objects this close at one time cannot be told apart
SAME_M = 5e-4            # two candidates' verified pairs this close ...
SAME_SHARE = 0.8         # ... at this share of the pairs both hold: one echo
RETURN_M = 0.04          # an object seen again within this of where it was last seen is the same one
STEADY_S = 5e-4          # the tracker's running median's reach (+-8 pairs at 20 kHz) ...
STEADY_MPS = 1.0         # ... over which one body's valid velocities differ by at most this + ACCEL_MAX dt
                         # (`one_body`: 2 CONSISTENT_MPS of noise and a median a blend pulls: a leg's
                         # apex 20 mm from the other leg read +0.27 then -0.33 m/s)
RUN_M = 3e-3             # a part of a mover that runs this far as its velocities say moves (`runs`)
STILL_ATTR = "still_echoes_removed_s"   # a track's attribute: its rows' running mean's span (s; 0: none)
MAX_OBJECTS = 8          # candidates converted at most (the nearest first)
KINDS = ("fixed", "moving")
# a pair's values, NaN where it is not valid
VALUES = ("distance_m", "velocity_mps", "acceleration_mps2", "distance_uncertainty_m",
          "velocity_uncertainty_mps", "acceleration_uncertainty_mps2")


@dataclass(frozen=True)
class Candidate:
    """An echo of the first conversion's tables: its distances (lo, hi m) and kind
    (`fixed`: a fixed echo of the tables; else a moving span, or an echo of the mean
    spectra, whose track says whether it moves)."""

    lo: float
    hi: float
    moving: bool
    fixed: bool = False

    @property
    def centre_m(self) -> float:
        return 0.5 * (self.lo + self.hi)


@dataclass
class SceneObject:
    """One object of the scene: its id, kind and track (the datasets of /track)."""

    id: int
    moving: bool
    track: Track
    note: str = ""
    whole: Track | None = None      # the conversion's track, where `track` is one body's part of it

    @property
    def kind(self) -> str:
        return KINDS[int(self.moving)]

    def attrs(self) -> dict:
        """The object's attributes: kind, first and last time seen (s), distance span
        (1st-99th percentile of its verified pairs, m), strength (median de-chirped SNR
        of their half-sweeps, dB) and how it was found."""
        t = self.track
        ok = t.valid
        seen = t.time_s[ok]
        snr = t.sweep_snr_dechirped_db
        strength = level(t) if snr is not None and snr.size else float(t.attrs.get("strength_db", np.nan))
        return {"object_id": self.id, "object_kind": self.kind,
                "first_seen_s": float(seen[0]) if seen.size else float("nan"),
                "last_seen_s": float(seen[-1]) if seen.size else float("nan"),
                "distance_span_m": np.percentile(t.distance_m[ok], [1, 99]) if ok.any()
                else np.full(2, np.nan),
                "strength_db": strength, "valid_pairs": int(ok.sum()), "object_note": self.note}


def level(t: Track) -> float:
    """An object's strength: the median de-chirped SNR (dB) of its verified pairs'
    half-sweeps (NaN with none)."""
    return float(np.nanmedian(per_pair(t, "sweep_snr_dechirped_db")[:, t.valid])) if t.valid.any() \
        else float("nan")


def candidates(fixed: fixed_echoes.Fixed, spans: list[tuple[float, float]], choice: target.Choice,
               band: tuple[float, float | None]) -> list[Candidate]:
    """The scene's echoes in the user's `band`: the `fixed` echoes (less those inside a
    moving span that fade when the target leaves them: the target at rest), the moving
    `spans` (m), and the other echoes the `choice` found ambiguous with the target
    (echoes of the mean spectra, verified pairs elsewhere), nearest first."""
    lo, hi = band[0], band[1] or np.inf
    out = [Candidate(a, b, True) for a, b in spans]
    for f, own in zip(fixed.distance_m, fixed.objects, strict=True):
        if lo <= f < hi and (own or not fixed_echoes.beside_span(f, spans)):
            out.append(Candidate(float(f), float(f), False, True))
    for f in choice.ambiguous_m:
        if lo <= f < hi and all(abs(f - c.centre_m) >= fixed_echoes.APART_M for c in out if c.fixed):
            out.append(Candidate(float(f), float(f), False))
    for a, b in np.asarray(choice.ambiguous_spans_m).reshape(-1, 2):
        if not fixed_echoes.beside_span(0.5 * (a + b), [(c.lo, c.hi) for c in out]):
            out.append(Candidate(float(a), float(b), True))
    return sorted(out, key=lambda c: (c.lo, c.hi))[:MAX_OBJECTS]


def moves(track: Track) -> bool:
    """Whether a track's verified pairs move: some faster than fixed_echoes.MOVING_MPS, and
    travelling fixed_echoes.MIN_TRAVEL_M (1st-99th percentile)."""
    fast = track.valid & (np.abs(track.velocity_mps) >= fixed_echoes.MOVING_MPS)
    return bool(fast.sum() >= 3 and _travel(track) >= fixed_echoes.MIN_TRAVEL_M)


def runs(track: Track) -> bool:
    """Whether a track's verified pairs run as their velocities say, however briefly (a
    foot's 26 pairs at 4.8 m/s between a wall's run and its apex): some faster than
    fixed_echoes.MOVING_MPS, and the first and last of them RUN_M or more apart, within
    1 mm + 25 % of their velocities' integral (trapezoids; a wall's blend at a steady
    biased velocity stays where it is)."""
    ok = np.flatnonzero(track.valid)
    if np.sum(np.abs(track.velocity_mps[ok]) >= fixed_echoes.MOVING_MPS) < 3:
        return False
    along, ran = numeric.follows(track.time_s[ok], track.distance_m[ok], track.velocity_mps[ok], 1e-3)
    return abs(ran) >= RUN_M and along


def holds(track: Track, c: Candidate) -> float:
    """The share of `track`'s verified pairs on candidate `c` (within GATE_M of its span)."""
    ok = track.valid
    if not ok.any():
        return 0.0
    d = track.distance_m[ok]
    return float(np.mean((d >= c.lo - GATE_M) & (d <= c.hi + GATE_M)))


def parts_of(track: Track) -> list[tuple[float, float]]:
    """The spans (m) of the echoes a track's verified pairs hold, where they hold more
    than one: the pairs part where APART_M of range holds none, and two parts are two
    echoes where the track passes from one to the other faster than a body moves (the
    trapezoid of the two pairs' velocities misses by more than 1 mm + 500 m/s^2 dt^2 / 8,
    verification.reachable). [] for one echo."""
    ok = np.flatnonzero(track.valid)
    if ok.size < 6:
        return []
    d = track.distance_m[ok]
    order = np.argsort(d, kind="stable")
    cuts = np.flatnonzero(np.diff(d[order]) > fixed_echoes.APART_M)
    if not cuts.size:
        return []
    label = np.empty(ok.size, np.int64)
    label[order] = np.searchsorted(cuts, np.arange(ok.size), side="left")
    # consecutive verified pairs in time that change part: can the body have moved so?
    t, v = track.time_s[ok], track.velocity_mps[ok]
    step = np.flatnonzero(label[1:] != label[:-1])
    apart = ~reachable(t[step], d[step], v[step], t[step + 1], d[step + 1], v[step + 1])
    low = np.minimum(label[step], label[step + 1])
    high = np.maximum(label[step], label[step + 1])
    # neighbouring parts are one echo where the track passed between them, and always could
    groups = list(range(cuts.size + 1))
    for k in range(cuts.size):
        between = (low == k) & (high == k + 1)
        if between.any() and not apart[between].any():
            groups[k + 1] = groups[k]
    spans = []
    for g in sorted(set(groups)):
        x = d[np.isin(label, [k for k, h in enumerate(groups) if h == g])]
        if x.size >= 3:
            spans.append((float(np.percentile(x, 1)), float(np.percentile(x, 99))))
    return spans if len(spans) > 1 else []


def bodies(track: Track) -> list[np.ndarray]:
    """The track's verified pairs as the parts one body can have made (boolean masks,
    in time; one where the track is one body's): cut between two verified pairs,
    consecutive among them, that no body moves between (verification.reachable: its
    tracker, its anchors and its bands' choice all passed one that did, a wall's run
    and a foot's 81 mm away 0.15 ms apart) or whose velocities no body holds so soon
    (`one_body`), or across a gap where the later is not the earlier `seen_again` (its
    tracker's going on is no better evidence than a join: a landing lost 8 mm above its
    rest at -1.83 m/s, its tracker back 130 ms later on a hand rising past it at +0.70
    m/s: 69 valid pairs of the hand)."""
    ok = np.flatnonzero(track.valid)
    t, d, v = track.time_s[ok], track.distance_m[ok], track.velocity_mps[ok]
    ends = (t[:-1], d[:-1], v[:-1], t[1:], d[1:], v[1:])
    cut = np.flatnonzero(~one_body(*ends) | ~seen_again(*ends)) + 1
    out = []
    for part in np.split(ok, cut):
        mask = np.zeros(track.pairs, bool)
        mask[part] = True
        out.append(mask)
    return out


def one_body(ta, da, va, tb, db, vb) -> np.ndarray:
    """Whether one body can make pairs (ta, da, va) and (tb, db, vb) (s, m, m/s;
    arrays): verification.reachable, and within STEADY_S, where each valid pair's
    velocity lies within verification.CONSISTENT_MPS of its neighbours' median, the
    velocities within ACCEL_MAX |dt| + STEADY_MPS (two glides crossing at +1.74 and
    -1.87 m/s, the tracker passing from one to the other 0.8 mm on in 0.15 ms: 59
    valid pairs on the other; a landing's impact in a fade is not bounded so: 5 m/s
    to rest within 2 ms)."""
    dt = np.abs(tb - ta)
    return reachable(ta, da, va, tb, db, vb) & ((dt > STEADY_S) | alike(dt, va, vb))


def alike(dt, va, vb) -> np.ndarray:
    """Whether velocities `va` and `vb` (m/s) `dt` apart (s, >= 0) can be one body's
    within STEADY_S: within ACCEL_MAX dt + STEADY_MPS."""
    return np.abs(vb - va) <= ACCEL_MAX * dt + STEADY_MPS


def invalidated(track: Track, where: np.ndarray, code: int = faults.AMBIGUOUS) -> Track:
    """A copy of `track` with its valid pairs `where` invalid with `code` (`invalidate`)."""
    out = replace(track, attrs=dict(track.attrs))
    invalidate(out, where, code)
    return out


def same(a: Track, b: Track) -> bool:
    """Whether two tracks follow one echo: their verified pairs agree within SAME_M at
    SAME_SHARE of the pairs both hold (and they hold some)."""
    both = a.valid & b.valid
    if both.sum() < 20:
        return False
    return bool(np.mean(np.abs(a.distance_m[both] - b.distance_m[both]) <= SAME_M) >= SAME_SHARE)


def per_pair(t: Track, name: str) -> np.ndarray:
    """A per-half-sweep array of `t` (`name`) as (rising, falling) per pair (NaN where
    the pair has no half-sweeps: a gap)."""
    x = getattr(t, name)
    out = np.full((2, t.pairs), np.nan)
    if x is None:
        return out
    k = _pair_of_sweeps(t)
    out[0, k], out[1, k] = x[::2], x[1::2]
    return out


def _pair_of_sweeps(t: Track) -> np.ndarray:
    """The pair index of each owned pair of half-sweeps (by the pair's centre time)."""
    mid = 0.5 * (t.sweep_time_s[::2] + t.sweep_time_s[1::2])
    return np.clip(np.searchsorted(t.time_s, mid), 0, t.pairs - 1)


def returns(a: Track, b: Track) -> bool:
    """Whether `b` is `a` seen again: never verified at one time, and the first of the
    later one's verified pairs `seen_again` after the last of the earlier one's (a rail
    that crossed a swaying cable 60 mm on; a foot that landed while hidden)."""
    e = ends(a, b)
    return e is not None and bool(seen_again(*e[2]))


def ends(a: Track, b: Track) -> tuple[Track, Track, tuple] | None:
    """`a` and `b` in the order they were seen, with the earlier one's last verified pair
    and the later one's first as (ta, da, va, tb, db, vb) (s, m, m/s); None where either
    holds none or their verified pairs interleave (seen at one time)."""
    ia, ib = np.flatnonzero(a.valid), np.flatnonzero(b.valid)
    if not ia.size or not ib.size:
        return None
    if ib[-1] < ia[0]:
        a, b, ia, ib = b, a, ib, ia
    if ia[-1] >= ib[0]:
        return None
    p, q = ia[-1], ib[0]
    return a, b, (a.time_s[p], a.distance_m[p], a.velocity_mps[p],
                  b.time_s[q], b.distance_m[q], b.velocity_mps[q])


def seen_again(ta, da, va, tb, db, vb) -> np.ndarray:
    """Whether a body last seen at (ta, da, va) can be the one first seen at (tb, db, vb)
    (s, m, m/s; arrays): within RETURN_M of where the trapezoid of its two velocities
    carries it or, where one of the two is at rest (under fixed_echoes.MOVING_MPS), of
    where it lay; within verification.KINEMATIC_S, only where one body moves so
    (`one_body`: a leg at 0.0762 m, +0.2 m/s, is not the other leg 1.9 mm nearer at
    -0.8 m/s 0.35 ms later). A mover that runs on at both ends is not seen again behind
    where it ran (a foot at 7 m/s, then 8 ms later a run at 2.8 m/s 8 mm short of it: the
    foot's rising peak and a wall's image in the falling ones)."""
    moved = db - da
    run = 0.5 * (va + vb) * (tb - ta)
    still = np.minimum(np.abs(va), np.abs(vb)) < fixed_echoes.MOVING_MPS
    soon = np.abs(tb - ta) <= KINEMATIC_S       # so soon, one body's motion or none
    return (((np.abs(moved - run) <= RETURN_M) | (still & (np.abs(moved) <= RETURN_M)))
            & (~soon | one_body(ta, da, va, tb, db, vb)))


def joined(a: Track, b: Track) -> Track:
    """One track of `a` and `b` (the same object, never verified at once): each pair,
    and its half-sweeps, from the one that verified it (from `a` where neither did);
    the displacement is `a`'s (its phase's reference is its own conversion's)."""
    take = b.valid
    out = replace(a, attrs=dict(a.attrs))
    for f in fields(Track):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if f.name.startswith("displacement"):
            continue        # a's: each conversion's phase has its own reference
        if isinstance(x, np.ndarray) and isinstance(y, np.ndarray) and x.shape == y.shape:
            if x.shape[:1] == (a.pairs,):
                setattr(out, f.name, np.where(take, y, x) if x.ndim == 1 else x)
    # the half-sweeps of the pairs taken from b: matched by their pair's time
    if (a.sweep_reason is not None and b.sweep_reason is not None
            and a.sweep_time_s.shape == b.sweep_time_s.shape):
        k = _pair_of_sweeps(b)
        mid = 0.5 * (b.sweep_time_s[::2] + b.sweep_time_s[1::2])
        sweeps = np.repeat(take[k] & (np.abs(b.time_s[k] - mid) < 1e-9), 2)
        for name in ("sweep_distance_m", "sweep_snr_db", "sweep_distance_dechirped_m",
                     "sweep_snr_dechirped_db", "sweep_reason", "sweep_phase_rad"):
            x, y = getattr(a, name), getattr(b, name)
            if x is not None and y is not None:
                setattr(out, name, np.where(sweeps, y, x))
    recount(out)
    return out


def invalidate(t: Track, where: np.ndarray, code: int = faults.AMBIGUOUS) -> None:
    """Mark the valid pairs `where` invalid with `code` (their half-sweeps too)."""
    hit = where & t.valid
    if not hit.any():
        return
    t.reason = np.where(hit, code, t.reason)
    t.valid = t.valid & ~hit
    for name in ("velocity_valid", "acceleration_valid"):
        setattr(t, name, getattr(t, name) & ~hit)
    for name in VALUES:
        x = getattr(t, name)
        if x is not None:
            setattr(t, name, np.where(hit, np.nan, x))
    if t.sweep_reason is not None:
        t.sweep_reason = np.where(np.repeat(hit[_pair_of_sweeps(t)], 2), code, t.sweep_reason)
    if t.displacement_valid is not None:
        _cut_displacement(t, hit)
    recount(t)


def _cut_displacement(t: Track, hit: np.ndarray) -> None:
    """The displacement after a pair `hit` in its stretch is not valid: the phase was
    followed across that pair's velocity and phase, which may be another object's."""
    lost = hit.copy()
    for s in np.unique(t.displacement_stretch[hit & t.displacement_valid]):
        mine = t.displacement_stretch == s
        lost |= mine & (np.cumsum(hit & mine) > 0)
    t.displacement_valid = t.displacement_valid & ~lost
    t.displacement_stretch = np.where(lost, -1, t.displacement_stretch)
    for name in ("displacement_m", "displacement_uncertainty_m"):
        setattr(t, name, np.where(lost, np.nan, getattr(t, name)))


def no_displacement(t: Track) -> None:
    """No pair of `t` has a valid displacement (its phase is not to be followed)."""
    if t.displacement_valid is not None:
        _cut_displacement(t, np.ones(t.pairs, bool))


def recount(t: Track) -> None:
    """The track's counts of invalid pairs by reason and its tracked span, again."""
    for code, name in faults.REASONS.items():
        if code:
            t.attrs[f"invalid_{name}"] = int(np.sum(t.reason == code))
    t.attrs["target_tracked_m"] = (np.percentile(t.distance_m[t.valid], [1, 99]) if t.valid.any()
                                   else np.full(2, np.nan))


def choose(objects: list[SceneObject], rule: str, near_m: float | None) -> int:
    """The index in `objects` of the target (see the module): `--target-near D` the one
    whose span lies nearest D, `nearest` the one nearest the instrument, `auto` and
    `moving` a moving one before a fixed one, the mover that travels furthest; -1 where
    no object moves and several hold verified pairs (nothing tells which is the target:
    /track is then ambiguous, each object valid on its own); else the one that does."""
    if not objects:
        raise ValueError("no object")
    span = [o.attrs()["distance_span_m"] for o in objects]
    if near_m is not None:
        return int(np.argmin([max(s[0] - near_m, near_m - s[1], 0.0) if np.isfinite(s[0]) else np.inf
                              for s in span]))
    if rule == "nearest":
        return int(np.argmin([s[0] if np.isfinite(s[0]) else np.inf for s in span]))
    movers = [i for i, o in enumerate(objects) if o.moving and o.track.valid.any()]
    if movers:
        return max(movers, key=lambda i: _travel(objects[i].track))
    held = [i for i, o in enumerate(objects) if o.track.valid.any()]
    return held[0] if len(held) == 1 else (-1 if held else 0)


def _travel(t: Track) -> float:
    """The span of an object's verified distances (1st-99th percentile, m)."""
    d = t.distance_m[t.valid]
    return float(np.ptp(np.percentile(d, [1, 99]))) if d.size else 0.0


def where_m(t: Track) -> float:
    """The median of a track's verified distances (m; NaN with none)."""
    d = t.distance_m[t.valid]
    return float(np.median(d)) if d.size else float("nan")


def describe(o: SceneObject) -> str:
    """One object in a line's words: "#2 (moving, 0.404-0.436 m)"."""
    lo, hi = o.attrs()["distance_span_m"]
    if not np.isfinite(lo):
        return f"#{o.id} ({o.kind}, no verified pair)"
    where = f"{lo:.3f} m" if o.kind == "fixed" or abs(hi - lo) < 1e-3 else f"{lo:.3f}-{hi:.3f} m"
    return f"#{o.id} ({o.kind}, {where})"
