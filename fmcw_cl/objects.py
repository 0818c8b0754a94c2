"""The scene as objects: every persistent echo, fixed or moving, tracked on its own.

The first conversion's tables list the scene's echoes (fmcw_cl.target): fixed echoes
(walls, windows, a target at rest) and moving spans (a leg, a swaying cable), with the
echoes its mean spectra hold and the verified pairs found elsewhere. Each is a
*candidate*; each is converted in a band of its own, the others' nearer ends left out
(`target.choose` with `near_m`), so that its tracker cannot follow another, and its
pairs are verified as the target's are. Then:

- a tracker that still holds two echoes (a scene whose first conversion saw one of
  them only) is split (`parts_of`): its verified pairs part where target.APART_M of
  range holds none and it passes between the parts faster than a body moves; each part
  is a candidate of its own (once);
- two candidates whose verified pairs agree (within SAME_M at SAME_SHARE of the pairs
  both hold) are one echo (a target slowing onto its plateau is also a fixed echo);
- a fixed object's pairs are its own only at rest (under target.MOVING_MPS), within
  GATE_M of its distance and close to its median (target.ambiguous): anything else its
  band holds is something passing, or a blend with an echo beside it;
- where two objects lie within GATE_M of each other at one time (`conflicts`: their
  verified pairs across gaps of up to BRIDGE_S, a fixed one's span all along), or a
  pair lies on another's harmonic (`harmonics`) or de-chirped image (`images`, along
  a mover's `course`), their echoes cannot be told apart there: ``ambiguous`` on both,
  never given to the wrong one;
- an object last seen where another of its kind is first seen, within RETURN_M (as it
  lay, or moved on at its velocities), the two never seen at once, is one object that
  was hidden or faded (`returns`, `joined`);
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

from . import target
from .stages import faults
from .stages.clutter import STILL_S
from .track import Track

GATE_M = target.GATE_M   # two objects this close at one time cannot be told apart
SAME_M = 5e-4            # two candidates' verified pairs this close ...
SAME_SHARE = 0.8         # ... at this share of the pairs both hold: one echo
RETURN_M = 0.04          # an object seen again within this of where it was last seen is the same one
BRIDGE_S = 5e-3          # an object's path is interpolated across gaps this short
COURSE_S = 0.01          # an object's images are looked for this far beyond its verified pairs
                         # (moved on at their velocity: 25 mm at 500 m/s^2, inside an image's reach)
STILL_M = 5e-4           # an object whose verified distances span at most this is still (`still`)
STILL_ATTR = "still_echoes_removed_s"   # a track's attribute: its rows' running mean's span (s; 0: none)
MAX_OBJECTS = 8          # candidates converted at most (the nearest first)
KINDS = ("fixed", "moving")


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


def candidates(fixed: target.Fixed, spans: list[tuple[float, float]], choice: target.Choice,
               band: tuple[float, float | None]) -> list[Candidate]:
    """The scene's echoes in the user's `band`: the `fixed` echoes (less those inside a
    moving span that fade when the target leaves them: the target at rest), the moving
    `spans` (m), and the other echoes the `choice` found ambiguous with the target
    (echoes of the mean spectra, verified pairs elsewhere), nearest first."""
    lo, hi = band[0], band[1] or np.inf
    out = [Candidate(a, b, True) for a, b in spans]
    for f, own in zip(fixed.distance_m, fixed.objects, strict=True):
        inside = any(a - target.APART_M <= f <= b + target.APART_M for a, b in spans)
        if lo <= f < hi and (own or not inside):
            out.append(Candidate(float(f), float(f), False, True))
    for f in choice.ambiguous_m:
        if lo <= f < hi and all(abs(f - c.centre_m) >= target.APART_M for c in out if c.fixed):
            out.append(Candidate(float(f), float(f), False))
    for a, b in np.asarray(choice.ambiguous_spans_m).reshape(-1, 2):
        if not any(c.lo - target.APART_M <= 0.5 * (a + b) <= c.hi + target.APART_M for c in out):
            out.append(Candidate(float(a), float(b), True))
    return sorted(out, key=lambda c: (c.lo, c.hi))[:MAX_OBJECTS]


def moves(track: Track) -> bool:
    """Whether a track's verified pairs move: some faster than target.MOVING_MPS, and
    travelling target.MIN_TRAVEL_M (1st-99th percentile)."""
    fast = track.valid & (np.abs(track.velocity_mps) >= target.MOVING_MPS)
    return bool(fast.sum() >= 3 and _travel(track) >= target.MIN_TRAVEL_M)


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
    verification's bound: stages.pairing). [] for one echo."""
    ok = np.flatnonzero(track.valid)
    if ok.size < 6:
        return []
    d = track.distance_m[ok]
    order = np.argsort(d, kind="stable")
    cuts = np.flatnonzero(np.diff(d[order]) > target.APART_M)
    if not cuts.size:
        return []
    label = np.empty(ok.size, np.int64)
    label[order] = np.searchsorted(cuts, np.arange(ok.size), side="left")
    # consecutive verified pairs in time that change part: can the body have moved so?
    t, v = track.time_s[ok], track.velocity_mps[ok]
    step = np.flatnonzero(label[1:] != label[:-1])
    dt = t[step + 1] - t[step]
    miss = np.abs(d[step + 1] - d[step] - dt * 0.5 * (v[step] + v[step + 1]))
    apart = miss > 1e-3 + 500.0 * dt * dt / 8
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


def same(a: Track, b: Track) -> bool:
    """Whether two tracks follow one echo: their verified pairs agree within SAME_M at
    SAME_SHARE of the pairs both hold (and they hold some)."""
    both = a.valid & b.valid
    if both.sum() < 20:
        return False
    return bool(np.mean(np.abs(a.distance_m[both] - b.distance_m[both]) <= SAME_M) >= SAME_SHARE)


def path(track: Track) -> np.ndarray:
    """The object's distance at each pair (m): its verified pairs, linearly
    interpolated across gaps of at most BRIDGE_S, NaN elsewhere."""
    ok = np.flatnonzero(track.valid)
    out = np.full(track.pairs, np.nan)
    if ok.size == 0:
        return out
    t = track.time_s
    out[ok] = track.distance_m[ok]
    nxt = np.searchsorted(ok, np.arange(track.pairs))       # the next verified pair
    inner = (nxt > 0) & (nxt < ok.size)
    i = np.flatnonzero(inner & ~track.valid)
    a, b = ok[nxt[i] - 1], ok[nxt[i]]
    short = t[b] - t[a] <= BRIDGE_S
    i, a, b = i[short], a[short], b[short]
    w = (t[i] - t[a]) / (t[b] - t[a])
    out[i] = (1 - w) * track.distance_m[a] + w * track.distance_m[b]
    return out


def course(track: Track, reach_s: float = COURSE_S) -> tuple[np.ndarray, np.ndarray]:
    """An object's distance (m) and velocity (m/s) at each pair as far as its motion
    tells: its `path` (the velocities interpolated alike), and beyond it, within
    `reach_s` of the nearest verified pair, that pair's distance moved on at its
    velocity; NaN further."""
    where = path(track)
    ok = np.flatnonzero(track.valid)
    if ok.size == 0:
        return where, where.copy()
    t, d, v = track.time_s, track.distance_m, track.velocity_mps
    u = np.interp(t, t[ok], v[ok])
    u[np.isnan(where)] = np.nan
    gap = np.flatnonzero(np.isnan(where))
    nxt = np.searchsorted(ok, gap)
    before, after = ok[np.maximum(nxt - 1, 0)], ok[np.minimum(nxt, ok.size - 1)]
    near = np.where(np.abs(t[gap] - t[before]) <= np.abs(t[after] - t[gap]), before, after)
    dt = t[gap] - t[near]
    reach = np.abs(dt) <= reach_s
    gap, near, dt = gap[reach], near[reach], dt[reach]
    where[gap] = d[near] + v[near] * dt
    u[gap] = v[near]
    return where, u


def conflicts(tracks: list[Track], fixed: list[bool] | None = None,
              unseen: set[tuple[int, int]] = frozenset()) -> list[np.ndarray]:
    """For each track, the pairs where another object's path (`path`) lies within
    GATE_M of its own: the two echoes cannot be told apart there. A `fixed` object is
    there all along, at the span of its verified distances (1st-99th percentile),
    whether or not its own track holds it then: a pair of another within GATE_M of that
    span is ambiguous on both (a cable swaying +-10 mm, a fixed echo of the tables,
    whose band edge cut its near swing: the rail's tracker held that swing once the
    rail had left its band). Not where (i, j) is `unseen`: track i's rows hold nothing
    of object j (a still one, taken out of a mover's rows: fmcw_cl.scene)."""
    fixed = fixed or [False] * len(tracks)
    paths = [path(t) for t in tracks]
    out = [np.zeros(t.pairs, bool) for t in tracks]
    for i in range(len(tracks)):
        for j in range(i + 1, len(tracks)):
            close = np.abs(paths[i] - paths[j]) <= GATE_M      # NaN: False
            for a, b in ((i, j), (j, i)):
                if fixed[b] and tracks[b].valid.any():
                    close |= _within_span(tracks[b], paths[a])
            for a, b in ((i, j), (j, i)):
                if (a, b) not in unseen:
                    out[a] |= close
    return out


def _within_span(fixed: Track, d: np.ndarray) -> np.ndarray:
    """Where distances `d` (m, per pair) lie within GATE_M of a fixed object's span of
    verified distances."""
    lo, hi = np.percentile(fixed.distance_m[fixed.valid], [1, 99])
    return (d >= lo - GATE_M) & (d <= hi + GATE_M)


def harmonics(tracks: list[Track], unambiguous_m: float) -> list[np.ndarray]:
    """For each track, the verified pairs that lie where a harmonic of another object
    would (2..target.HARMONICS times its distance, folded at the unambiguous range,
    within target.HARMONIC_M per multiple, moving k times as fast within
    target.MOVING_MPS per multiple), target.HARMONIC_DB or more under its median level:
    a distortion's ghost of a strong echo, which a band of its own lets a tracker hold."""
    out = [np.zeros(t.pairs, bool) for t in tracks]
    for i, a in enumerate(tracks):
        weakest = np.nanmin(per_pair(a, "sweep_snr_dechirped_db"), axis=0)
        for j, b in enumerate(tracks):
            if i == j or not b.valid.any():
                continue
            weak = weakest <= level(b) - target.HARMONIC_DB
            for k in range(2, target.HARMONICS + 1):
                at = np.mod(k * b.distance_m, 2 * unambiguous_m)
                fold = at > unambiguous_m
                at = np.where(fold, 2 * unambiguous_m - at, at)
                v = np.where(fold, -k, k) * b.velocity_mps
                out[i] |= (a.valid & weak & (np.abs(a.distance_m - at) <= k * target.HARMONIC_M)
                           & (np.abs(a.velocity_mps - v) <= k * target.MOVING_MPS))
    return out


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


def images(tracks: list[Track], model, window: np.ndarray,
           unseen: set[tuple[int, int]] = frozenset()) -> list[np.ndarray]:
    """For each track, the verified pairs whose de-chirped peaks could be the image of
    another object (fmcw_cl.wall_images.confused_moving, along its `course`, at its
    velocity and median level): a band left empty of echoes lets a tracker hold
    another's image (a rail's, de-chirped 10 m/s off, 0.3 m beyond it). A fixed one's
    too, beside the target choice's `walls_m`: a cable swaying +-10 mm at 0.19 m/s,
    listed at 0.260 m, put its image 15 mm from that of a still tone there. Not where
    (i, j) is `unseen` (`conflicts`): no image of j in track i's rows."""
    from .wall_images import confused_moving

    out = [np.zeros(t.pairs, bool) for t in tracks]
    sources = {}                        # each object's course, velocity, verified path and level
    for j, b in enumerate(tracks):
        if b.valid.any():
            sources[j] = (*course(b), path(b), level(b))
    for i, a in enumerate(tracks):
        if not a.valid.any():
            continue
        peaks, snr = per_pair(a, "sweep_distance_dechirped_m"), per_pair(a, "sweep_snr_dechirped_db")
        for j, (where, u, known, top) in sources.items():
            if j == i or (i, j) in unseen:
                continue
            out[i] |= a.valid & confused_moving(a.velocity_mps, tuple(peaks), tuple(snr), known, u, top,
                                                model, window, a.valid)
            # beyond its verified pairs its level is not known (an integrated track's peaks
            # stand as high as an image 10 dB under the mover: taken as strong enough); near
            # its course the other may be this one itself, seen again (`conflicts`, `returns`)
            beyond = np.where(np.isnan(known) & (np.abs(a.distance_m - where) > GATE_M), where, np.nan)
            out[i] |= a.valid & confused_moving(a.velocity_mps, tuple(peaks), tuple(snr), beyond, u, np.inf,
                                                model, window, a.valid)
    return out


def still(track: Track, wavelength_m: float) -> bool:
    """Whether an object is still enough that rows without still echoes
    (stages.clutter) hold nothing of it: its verified distances span at most STILL_M
    (1st-99th percentile: no sway), and their trend moves it less than a quarter
    wavelength over the running mean's span (stages.clutter.STILL_S)."""
    ok = track.valid
    if ok.sum() < 20:
        return False
    t, d = track.time_s[ok], track.distance_m[ok]
    lo, hi = np.percentile(d, [1, 99])
    slope = np.polyfit(t - t.mean(), d, 1)[0] if np.ptp(t) > 0 else np.inf
    return bool(hi - lo <= STILL_M and abs(slope) * STILL_S < wavelength_m / 4)


def returns(a: Track, b: Track) -> bool:
    """Whether `b` is `a` seen again: never verified at one time, and the first of the
    later one's verified pairs within RETURN_M of the last of the earlier one's, as they
    lie or moved on by the trapezoid of their two velocities (a rail that crossed a
    swaying cable 60 mm on)."""
    if not a.valid.any() or not b.valid.any() or np.any(a.valid & b.valid):
        return False
    ia, ib = np.flatnonzero(a.valid), np.flatnonzero(b.valid)
    if ib[-1] < ia[0]:
        a, b, ia, ib = b, a, ib, ia
    if ia[-1] >= ib[0]:
        return False
    last, first = ia[-1], ib[0]
    moved = b.distance_m[first] - a.distance_m[last]
    run = 0.5 * (a.velocity_mps[last] + b.velocity_mps[first]) * (b.time_s[first] - a.time_s[last])
    return bool(min(abs(moved), abs(moved - run)) <= RETURN_M)


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
    for name in ("distance_m", "velocity_mps", "acceleration_mps2", "distance_uncertainty_m",
                 "velocity_uncertainty_mps", "acceleration_uncertainty_mps2"):
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


def where_m(o: SceneObject) -> float:
    """The median of an object's verified distances (m; NaN with none)."""
    d = o.track.distance_m[o.track.valid]
    return float(np.median(d)) if d.size else float("nan")


def describe(o: SceneObject) -> str:
    """One object in a line's words: "#2 (moving, 0.404-0.436 m)"."""
    lo, hi = o.attrs()["distance_span_m"]
    if not np.isfinite(lo):
        return f"#{o.id} ({o.kind}, no verified pair)"
    where = f"{lo:.3f} m" if o.kind == "fixed" or abs(hi - lo) < 1e-3 else f"{lo:.3f}-{hi:.3f} m"
    return f"#{o.id} ({o.kind}, {where})"
