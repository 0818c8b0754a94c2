"""Which echo is the target: the band it is tracked in, and where it cannot be told apart.

A first conversion tracks the strongest echo of the user's band [--min-range,
--max-range) and lists every echo (stages.cfar, `echoes.table`). From its tables:

- a **fixed echo** is a distance where the echoes of each current direction cluster
  (within echoes.HIST_M), the two within GATE_M of each other (a sync delay's error
  parts them by a few mm; a moving target's plain peak in one direction only, where
  its Doppler shift cancels its motion, is no fixed echo), at their midpoint, each in
  at least FIXED_SHARE of the capture's 10 ms slices, at any level: a wall, a window, a
  lens, or a target at rest for most of the capture (a target at rest 12 dB below a
  wall is still the target). An echo within HARMONIC_M of 2 to HARMONICS times the
  distance of one HARMONIC_DB stronger (folded at the unambiguous range) is its
  harmonic, not an object. The peaks of the surveyed half-sweeps' mean spectra
  (echoes.mean_peaks) count alike, a block of them for a slice: an echo too weak for
  the CFAR in single half-sweeps is a rival all the same. Fixed echoes within APART_M
  of each other are one, at the strongest, which stands for them all (its ambiguity
  and the band's edges beside it cover them);
- a **moving echo** spans the distances of the verified pairs that move faster than
  MOVING_MPS and of the echoes found by their Doppler-smeared energy (echoes.hidden);
  those distances part into several moving echoes where APART_M of range holds none
  (a second limb, a swinging cable).

The rule (`--target`):

- ``auto``: where a moving echo is found, it is the target (the instrument exists to
  measure motion); the fixed echoes it does not reach are left out of the band, which
  becomes the gap between them that holds the moving echo's span (each edge WALL_MARGIN_M
  inside the fixed echo, or half way to the span where that is nearer). A fixed echo
  inside the span (or within APART_M of its ends) is the target at rest when it fades with
  the target's departure; one that stays while the target is elsewhere is another object,
  and the pairs within GATE_M of it are ``ambiguous`` (a body's rest only while it is
  there, fmcw_cl.rest_spans; where the span comes from the smeared energy alone, while the
  first conversion held the object, the part beside the objects that holds most of the
  smeared energy's slices is tracked instead: the object would hold the tracker again).
  With no moving echo and several fixed echoes, or several moving echoes, the rule cannot
  tell which is the target: every pair on one of them is ``ambiguous``. With no echo at
  all at a slice's or a block's level, the echoes of the capture's mean spectra
  (`Echoes.peaks`) stand for the fixed ones; with none there either, the verified pairs in
  motion stand (`ambiguous` below). With one echo, it is the target, unless OTHERS_SHARE
  of all the half-sweeps hold other echoes in the band (something neither fixed nor found
  moving), or the capture's mean spectra hold another echo (one within APART_M of it that
  its power hides from the CFAR, `echoes.masked_peaks`, or a peak of both directions more
  than GATE_M from it, its harmonics excepted), or they put it at two distances more than
  SPLIT_M apart in the two directions (a conversion that moves an echo at rest: the sync
  delay or the chirp off): then the pairs on it are ``ambiguous``. Before that, the moving
  echoes a second look beside it finds (fmcw_cl.second_look; `Choice.lone` asks for one)
  join the choice; after it, where OTHERS_SHARE of the verified pairs lie more than GATE_M
  from the echo, the tracker held something else the tables missed, and the pairs on
  either are ``ambiguous`` (so are they beside several fixed echoes).
- ``moving``: as auto, and a capture without a moving echo is refused.
- ``nearest``: the nearest fixed echo or moving span, left alone in its gap (the other
  echoes' nearer ends bound it).
- ``strongest``: the strongest echo of the band, pair by pair (no second pass).
- ``--target-near D``: the fixed echo or moving span nearest to D m, left alone.

When the band changes, the capture is converted again in the chosen band (a second
pass over the file: a scene with a wall costs two conversions).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import echoes, fixed_echoes, numeric
from .fixed_echoes import APART_M, GATE_M, MOVING_MPS, OTHERS_SHARE, Fixed, are_objects, fixed_of, smeared
from .numeric import drift, nearest
from .options import RANGE_GAP_M, said
from .rivals import besides, directions_apart, elsewhere, others_share
from .stages import faults
from .stages.verification import DRIFT_BLOCKS, DRIFT_MPS, DRIFT_SIGMAS
from .swing import REST_APART_M, SMEAR_M, doppler_reach, rests, swinging

RULES = ("auto", "moving", "nearest", "strongest")
WALL_MARGIN_M = 0.03  # a band edge lies this far inside a left-out fixed echo where the gap allows
MIN_GAP_M = 0.004     # a band edge lies at least half this inside a left-out fixed echo
REST_SIGMAS = 6.0     # a fixed object's pair further than this many robust sigmas from its median ...
REST_M = 2.5e-4       # ... and than this is a blend with another echo beside it (a foot at rest 5 mm from
                      # a window read the window 3 mm off)
REST_MPS = 0.04       # a fixed object's velocity this far from its neighbours' (and REST_SIGMAS sigmas of
                      # its peaks' noise), or its distances leaving their velocities' integral this fast
                      # (and DRIFT_SIGMAS standard errors), is a blend: one half-sweep's peak pulled
                      # 2.4 mm (`_blended`)
REST_PAIRS = 100      # ... its pairs tested this many at a time (5 ms of a 4 Hz sway moves 0.03 m/s) ...
REST_GAP_S = 2e-3     # ... within stretches without gaps this long (a sway's integral is lost across)


@dataclass
class Choice:
    """The target chosen from a first conversion.

    Attributes
    ----------
    rule : the rule applied (RULES, or "near D").
    fixed_m : the fixed echoes' distances (m).
    objects : whether each fixed echo stays while the target is elsewhere.
    span_m : (lo, hi) of the target's distances (m), None when no echo is the target.
    moving : the target was chosen for its motion.
    band_m : the band (lo, hi) it is tracked in (m; hi None: to the end of the range).
    ambiguous_m : echoes inside the band that the target cannot be told from (fixed, or
        found in the capture's mean spectra only).
    ambiguous_spans_m : (k, 2) moving echoes' spans (m) the rule cannot tell apart.
    note : what was chosen and why, one line.
    lone : a second look beside the one fixed echo is due (taken for the target, or others' beside it).
    unseen_rest : no echo was found, fixed or moving: the pairs at rest are ambiguous.
    walls_m, walls_db : the fixed echoes that are not the target (out of its band, or
        ambiguous with it; the user's band's too) and their levels (dB over the floor):
        their images in de-chirped half-sweeps (fmcw_cl.wall_images).
    """

    rule: str
    fixed_m: np.ndarray
    objects: np.ndarray
    span_m: tuple[float, float] | None
    moving: bool
    band_m: tuple[float, float | None]
    ambiguous_m: np.ndarray = field(default_factory=lambda: np.zeros(0))
    note: str = ""
    ambiguous_spans_m: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    lone: bool = False
    unseen_rest: bool = False
    walls_m: np.ndarray = field(default_factory=lambda: np.zeros(0))
    walls_db: np.ndarray = field(default_factory=lambda: np.zeros(0))
    at_rest_m: float | None = None    # a fixed object (fmcw_cl.objects): its pairs only at rest, there
    taken_s: np.ndarray = field(default_factory=lambda: np.zeros(0))   # pair times another object shares
    there_s: tuple[float, float] = (-np.inf, np.inf)    # a fixed object a body's rest: there then alone
    rests_s: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))   # those ambiguous: (m, s, s)

    @property
    def undecided(self) -> bool:
        """Whether some pairs may be ambiguous under this choice."""
        return bool(self.ambiguous_m.size or self.ambiguous_spans_m.size or self.unseen_rest
                    or self.at_rest_m is not None or self.taken_s.size)

    def attrs(self) -> dict:
        return {"target_rule": self.rule,
                "target_fixed_echoes_m": np.asarray(self.fixed_m, np.float64),
                "target_moving": bool(self.moving),
                "target_span_m": np.asarray(self.span_m if self.span_m else (np.nan, np.nan), np.float64),
                "target_band_m": np.asarray((self.band_m[0], np.nan if self.band_m[1] is None
                                             else self.band_m[1]), np.float64),
                "target_ambiguous_echoes_m": np.asarray(self.ambiguous_m, np.float64),
                "target_ambiguous_spans_m": np.asarray(self.ambiguous_spans_m, np.float64).ravel(),
                "target_choice": self.note}


def _gap(span: tuple[float, float], fixed: np.ndarray, band, fair: bool = False
         ) -> tuple[float, float | None]:
    """The band around `span` that leaves out the echoes whose (lo, hi) (m) are the rows
    of `fixed` (all outside it), its edges `_margin` (`fair`: a fixed target's) inside them."""
    lo, hi = band
    below, above = fixed[fixed[:, 1] < span[0], 1], fixed[fixed[:, 0] > span[1], 0]
    if below.size:
        f = below.max()
        lo = max(lo, f + _margin(span[0] - f, fair))
    if above.size:
        f = above.min()
        edge = f - _margin(f - span[1], fair)
        hi = edge if hi is None else min(hi, edge)
    return lo, hi


def _margin(gap: float, fair: bool = False) -> float:
    """How far inside a left-out fixed echo a band edge lies, `gap` m from the target's
    span: WALL_MARGIN_M (its lobes stay out), less where the gap is narrow (half of it,
    at least MIN_GAP_M / 2). `fair` (a fixed target): half of it where that minimum would
    bring the edge nearer the target than half way (MIN_GAP_M / 2 to MIN_GAP_M: resolved
    from it, 2 range resolutions or more; nearer, the echo's end is the target's own
    arrival or departure: the minimum)."""
    if fair and MIN_GAP_M / 2 <= gap < MIN_GAP_M:
        return gap / 2
    return min(WALL_MARGIN_M, max(MIN_GAP_M / 2, gap / 2))


def choose(rule: str, near_m: float | None, time_s, distance_m, velocity_mps, valid,
           e: echoes.Echoes, unambiguous_m: float, band: tuple[float, float | None],
           beside: list[tuple[float, float]] | None = None, clipped: bool = False,
           fixed: Fixed | None = None, moving: bool | None = None, sides: bool = False) -> Choice:
    """The target of a first conversion's pairs (valid, distances, velocities) and echo
    table `e` (see the module); `unambiguous_m` is the capture's unambiguous range,
    `band` the user's (lo, hi) in m. A lone fixed echo (`auto`, `moving`) comes back
    with `lone` set until `beside`, the moving echoes found beside it by a second look
    (fmcw_cl.second_look), is given. `clipped`: some pairs are clipped (their distortion
    puts peaks into the mean spectra). `fixed`: `fixed_of` these arguments, where known
    (the call after a second look takes the first call's). `moving`: with `near_m`, a
    moving span (True) or a fixed echo (False) before the other where both lie at D
    (fmcw_cl.objects: a wall inside a leg's span). `sides`: the caller tracks a moving
    echo on each side of the fixed objects inside its span (fmcw_cl.scene), so its band
    is never one side of them."""
    if fixed is None:
        fixed = fixed_of(e, unambiguous_m, time_s, distance_m, velocity_mps, valid)
    listed, d, level = fixed.listed, fixed.distance_m, fixed.level_db
    # each fixed echo stands for those within APART_M of it (walls 12.6 mm apart are one)
    members = np.asarray([x for x, _ in listed])
    groups = [members[np.abs(members - f) < APART_M] for f in d]
    extent = np.array([(min(f, g.min()), max(f, g.max())) for f, g in zip(d, groups, strict=True)])
    choice = _choose(rule, near_m, time_s, distance_m, velocity_mps, valid, e, unambiguous_m, band, beside,
                     clipped, d, extent.reshape(-1, 2), fixed.objects, moving, sides)
    if choice.ambiguous_m.size:   # with the echoes each one stands for
        near = np.min(np.abs(members[:, None] - choice.ambiguous_m[None, :]), axis=1) < APART_M
        choice.ambiguous_m = np.union1d(choice.ambiguous_m, members[near])
    # the fixed echoes that are not the target: out of its band, or ambiguous with it
    hi = np.inf if choice.band_m[1] is None else choice.band_m[1]
    other = (d < choice.band_m[0]) | (d >= hi)
    if choice.ambiguous_m.size:
        other |= np.min(np.abs(d[:, None] - choice.ambiguous_m[None, :]), axis=1) <= GATE_M
    choice.walls_m, choice.walls_db = d[other], level[other]
    return choice


def _choose(rule: str, near_m: float | None, time_s, distance_m, velocity_mps, valid,
            e: echoes.Echoes, unambiguous_m: float, band: tuple[float, float | None],
            beside: list[tuple[float, float]] | None, clipped: bool, fixed: np.ndarray,
            extent: np.ndarray, objects: np.ndarray, prefer: bool | None = None, sides: bool = False
            ) -> Choice:
    """`choose` with the capture's fixed echoes `fixed` (m), the (lo, hi) of the echoes
    each stands for, `extent` (m), whether each is an object (`are_objects`), and the kind
    `prefer`red at a tie of `near_m`."""
    inband = (fixed >= band[0]) & (fixed < (band[1] or np.inf))
    fixed, extent, objects = fixed[inband], extent[inband], objects[inband]
    diffuse = smeared(e, band)
    spans = sorted(fixed_echoes.moving_spans(time_s, distance_m, velocity_mps, valid, diffuse)
                   + (beside or []))
    if fixed.size == 0 and not spans:   # none at a slice's or a block's level: those the capture's show
        fixed = fixed_echoes.capture_peaks(e, band)
        extent = np.c_[fixed, fixed]
        objects = are_objects(fixed, time_s, distance_m, velocity_mps, valid, e)
    name = rule if near_m is None else f"near {near_m:g} m"
    if rule == "strongest" and near_m is None:
        return Choice(name, fixed, objects, None, False, band, note="the strongest echo of the band")
    if rule == "moving" and not spans and near_m is None and beside is None and fixed.size == 1:
        return Choice(name, fixed, objects, None, False, band, note="one echo: the target", lone=True)
    if rule == "moving" and not spans and near_m is None:
        raise ValueError(f"no moving echo found ({said('target', 'moving')}): choose another "
                         f"{said('target')}")
    # the candidates: every fixed echo (a point) and each moving span
    cands = [((f, f), False) for f in fixed] + [(span, True) for span in spans]
    if near_m is not None:
        target = min(cands, key=lambda c: (max(c[0][0] - near_m, near_m - c[0][1], 0.0), c[1] != prefer),
                     default=None)
    elif rule == "nearest":
        target = min(cands, key=lambda c: c[0][0], default=None)
    elif len(spans) > 1:      # several echoes move: the rule cannot tell which is the target
        return Choice(name, fixed, objects, None, False, band, fixed.copy(),
                      ambiguous_spans_m=np.asarray(spans),
                      note=f"the moving echoes at {', '.join(f'{lo:.3f}-{hi:.3f}' for lo, hi in spans)} m "
                           "cannot be told apart")
    elif spans:
        target = (spans[0], True)
    elif fixed.size == 0:
        target = None
    elif fixed.size == 1:
        reach = doppler_reach(e, time_s, distance_m, velocity_mps, valid)
        swings = reach >= SMEAR_M                     # a target vibrating in place, or creeping to rest
        centre = float(np.median(distance_m[valid])) if swings else float("nan")
        # where its pairs lie (a creep of up to MIN_TRAVEL_M to rest), its Doppler images beside
        lo, hi = np.percentile(distance_m[valid], [1, 99]) if swings else (np.nan, np.nan)
        if swings and abs(fixed[0] - centre) <= reach + SMEAR_M:
            fixed = np.array([centre])                # the end of its own swing: it is where its pairs are
        seen = others_share(e, fixed[0], band, 2 * np.size(time_s))
        if seen >= OTHERS_SHARE:                      # neither fixed nor found moving: a second look first
            return Choice(name, fixed, objects, None, False, band, fixed.copy(), lone=beside is None,
                          note=f"no echo moves, but {100 * seen:.0f} % of the half-sweeps hold other echoes "
                               f"than the fixed echo at {_list(fixed)}: the target cannot be told apart")
        hidden = besides(e, fixed[0], band, unambiguous_m, clipped)
        if swings:                                    # its own swing fills the mean spectra ...
            rest = rests(time_s, distance_m, velocity_mps, valid)
            rest = rest[np.abs(rest - fixed[0]) > REST_APART_M]
            # ... but not where its pairs rest away from the fixed echo: another echo the tracker held
            hidden = [x for x in hidden if not lo - reach - SMEAR_M <= x <= hi + reach + SMEAR_M
                      or np.any(np.abs(rest - x) <= REST_APART_M)]
        if hidden:                                    # an echo too weak or too near for the CFAR
            # the tracker may follow either: a wall the target's CFAR echoes outnumber, its
            # pairs 16 mm from the fixed echo (noise at full scale)
            return Choice(name, fixed, objects, None, False, band, np.sort(np.r_[fixed, hidden]),
                          note=f"no echo moves, but the capture's mean spectra hold another echo at "
                               f"{_list(hidden)} besides the fixed echo at {_list(fixed)}: the target "
                               "cannot be told apart")
        split = None if swings else directions_apart(e, fixed[0], band)
        if split is not None:                         # a conversion that moves an echo at rest
            return Choice(name, fixed, objects, None, False, band, fixed.copy(),
                          note=f"no echo moves, but the fixed echo at {_list(fixed)} lies at "
                               f"{split[0]:.4f} m rising and {split[1]:.4f} m falling in the capture's mean "
                               "spectra (the sync delay or the chirp off): the target cannot be told apart")
        away = elsewhere(distance_m, valid, fixed) if beside is not None else None
        if away is not None:                          # after the second look: verified pairs elsewhere
            return Choice(name, fixed, objects, None, False, band, fixed.copy(),
                          ambiguous_spans_m=np.asarray([away[1:]]),
                          note=f"no echo moves, but {100 * away[0]:.0f} % of the verified pairs lie at "
                               f"{away[1]:.3f}-{away[2]:.3f} m, away from the fixed echo at {_list(fixed)}: "
                               "the target cannot be told apart")
        return Choice(name, fixed, objects, None, False, band, note="one echo: the target",
                      lone=beside is None)
    else:                     # still echoes only: the rule cannot tell which is the target
        # pairs elsewhere that move are the target's (a landing's end beside two walls)
        away = elsewhere(distance_m, valid, fixed, velocity_mps)
        held = "" if away is None else f" and the verified pairs at {away[1]:.3f}-{away[2]:.3f} m"
        return Choice(name, fixed, objects, None, False, band, fixed.copy(),
                      ambiguous_spans_m=np.zeros((0, 2)) if away is None else np.asarray([away[1:]]),
                      note=f"no echo moves: the fixed echoes at {_list(fixed)}{held} cannot be told apart")
    if target is None and swinging(e, time_s, distance_m, velocity_mps, valid):
        # no echo stays put, none travels, but the tracked peaks swing with the pairs'
        # velocities and the distances follow them: one echo (a foot bouncing +-4 mm)
        return Choice(name, fixed, objects, None, False, band,
                      note="one echo, swinging with its velocity (no fixed or moving echo): the target")
    if target is None:        # no echo: a moving target seen too briefly stands, one at rest on nothing
        return Choice(name, fixed, objects, None, False, band, unseen_rest=True,
                      note="no echo found, fixed or moving: the verified pairs in motion stand")
    (lo, hi), moving = target
    outside = (extent[:, 1] < lo - APART_M) | (extent[:, 0] > hi + APART_M)
    # the other moving echoes bound the band by their nearer ends (one nested in a moving target's: its body)
    others = [a if a > hi else b for a, b in spans
              if (a, b) != (lo, hi) and not (moving and (a <= lo and hi <= b or lo <= a and b <= hi))]
    inner = ~outside & objects if moving else np.zeros(fixed.size, bool)
    within = fixed[inner]
    what = (f"the moving echo at {lo:.3f}-{hi:.3f} m" if moving else f"the echo at {lo:.3f} m")
    bounds = np.concatenate([extent[outside], np.c_[others, others]])
    # a rest 2.6 mm from another's span end: the middle, not 0.2 mm off its peak (at_band_edge: ambiguous)
    new = _gap((lo, hi), bounds, band, fair=not moving)
    on = np.zeros(valid.shape, bool)
    for a, b in extent[inner]:
        on |= (distance_m >= a - GATE_M) & (distance_m <= b + GATE_M)
    held = valid.any() and (on & valid).sum() >= 0.5 * valid.sum()
    if held and not sides and not np.any(valid & (np.abs(velocity_mps) >= MOVING_MPS)):
        # found by its smeared energy alone, while the first conversion held an object (half
        # its verified pairs on one): the objects inside its span would hold the tracker again
        # (a take-off through a wall of 800 codes: every pair on the wall). The part beside
        # them it was found in is tracked.
        part = _part_band((lo, hi), extent[inner], diffuse, bounds, band)
        if part is not None:
            new = part
            outside |= objects & ((extent[:, 1] < new[0]) | (extent[:, 0] >= (new[1] or np.inf)))
            what += " (one side of the fixed echoes inside it tracked: they would hold the tracker)"
            within = np.zeros(0)
    left = fixed[outside]
    note = what + (f", fixed echoes at {_list(left)} left out" if left.size else "")
    return Choice(name, fixed, objects, (lo, hi), moving, new, within, note + passes(within))


def passes(within: np.ndarray) -> str:
    """The note's clause on the fixed echoes `within` (m) a moving choice passes."""
    return f"; ambiguous where it passes the fixed echoes at {_list(within)}" if within.size else ""


def _part_band(span: tuple[float, float], cuts: np.ndarray, found: np.ndarray, bounds: np.ndarray, band
               ) -> tuple[float, float | None] | None:
    """The band of the part of `span` (m) beside the (lo, hi) `cuts` (m) within APART_M
    of it that holds most of the distances where smeared energy was `found` (m): `_gap`
    of the part (clipped to the span) with the other echoes `bounds` ((lo, hi) rows, m),
    its edge at a cut GATE_M inside the part (nearer, the pairs are `ambiguous` anyway).
    None where no part holds more than half of them (the target may spend as long on
    either side, and leave the band where the tracker takes what it holds: a rail's
    start 14 mm before a wall of 3000 codes, one slice found on each side, left the band
    and 49 pairs were valid 25 mm off) or the band is narrower than options.RANGE_GAP_M."""
    cuts = cuts[np.argsort(cuts[:, 0])]
    starts, ends = np.r_[-np.inf, cuts[:, 1]], np.r_[cuts[:, 0], np.inf]
    held = np.array([np.sum((found > x) & (found < y)) for x, y in zip(starts, ends, strict=True)])
    k = int(np.argmax(held))
    if 2 * held[k] <= found.size:
        return None
    a, b = max(float(starts[k]), span[0]), min(float(ends[k]), span[1])
    cut_a, cut_b = k > 0, k < cuts.shape[0]
    lo, hi = _gap((a, b), bounds, band)
    lo = max(lo, a + GATE_M) if cut_a else lo
    hi = (b - GATE_M if hi is None else min(hi, b - GATE_M)) if cut_b else hi
    return None if hi is not None and hi - lo < RANGE_GAP_M else (lo, hi)


def _list(xs) -> str:
    return ", ".join(f"{x:.3f}" for x in xs) + " m"


def _blended(t: np.ndarray, d: np.ndarray, v: np.ndarray, ok: np.ndarray, sigma_v: np.ndarray,
             bias_v: float = 0.0) -> np.ndarray:
    """The pairs `ok` of a fixed object whose velocity disagrees with its own motion:
    further than REST_MPS and REST_SIGMAS x `sigma_v` (m/s) from the median velocity of
    its REST_PAIRS (its stretch without REST_GAP_S gaps cut into parts that long), or of
    a part whose distances leave their velocities' integral (numeric.drifts) faster than
    REST_MPS, DRIFT_SIGMAS standard errors and `bias_v` (m/s: what every velocity may
    share, a sync delay's error; inf where the delay was not refined: two walls of a
    capture whose delay came from the intensity alone, +-11 samples, read 0.037 and
    0.072 m/s, in proportion to their distances). A weak wall's peak pulled by a stronger
    echo beside it moves in one direction only: 5 mm from a rail creeping off, read 2-4
    mm off at a steady 0.06-0.15 m/s; between two walls 13 mm apart, on one in rising
    and the other in falling half-sweeps, at +-0.24 m/s. A sway's velocities follow its
    distances."""
    out = np.zeros(ok.size, bool)
    idx = np.flatnonzero(ok)
    if idx.size < 3:
        return out
    stretches = np.split(idx, np.flatnonzero(np.diff(t[idx]) > REST_GAP_S) + 1)
    parts = [p for s in stretches for p in np.array_split(s, -(-s.size // REST_PAIRS)) if p.size >= 3]
    if not parts:
        return out
    sizes = np.array([p.size for p in parts])
    mine = np.concatenate(parts)
    label = np.repeat(np.arange(sizes.size), sizes)
    centre = numeric.group_median(label, v[mine], sizes.size)
    out[mine] = np.abs(v[mine] - centre[label]) > np.maximum(REST_MPS, REST_SIGMAS * sigma_v[mine])
    slope, se = numeric.drifts(t[mine], d[mine], v[mine], sizes, DRIFT_BLOCKS)
    drifts = np.abs(slope) > np.fmax(max(REST_MPS, bias_v), DRIFT_SIGMAS * se)
    out[mine[np.repeat(drifts, sizes)]] = True
    return out


def ambiguous(code: np.ndarray, time_s: np.ndarray, distance_m: np.ndarray, velocity_mps: np.ndarray,
              choice: Choice, imaged: np.ndarray | None = None,
              velocity_sigma_mps: np.ndarray | float = 0.0, velocity_bias_mps: float = 0.0) -> np.ndarray:
    """`code` with the OK pairs within GATE_M of the choice's ambiguous echoes (fixed
    echoes, a body's rest only while there: `Choice.rests_s`; moving spans) or `imaged`
    (a half-sweep's peak may be the image of a fixed echo, fmcw_cl.wall_images) set to
    faults.AMBIGUOUS; with no echo found (`Choice.unseen_rest`), those slower than
    MOVING_MPS, or all where their distances do not follow their velocities
    (numeric.drift beyond pairing.DRIFT_MPS: a wall at rest read at 0.35 m/s under a
    sync delay 77 samples off). A fixed object's pairs (`Choice.at_rest_m`) beyond
    GATE_M of it, moving (MOVING_MPS), or faster than `_blended` (`velocity_sigma_mps`:
    the noise of each pair's velocity from its peaks'; `velocity_bias_mps`: the bias all
    velocities may share, the sync delay's) are another echo's or blends with one."""
    out = code.copy()
    if choice.unseen_rest:
        ok = out == faults.OK
        still = ~(np.abs(velocity_mps) >= MOVING_MPS)
        if ok.sum() >= 3 and abs(drift(time_s[ok], distance_m[ok], velocity_mps[ok])[0]) > DRIFT_MPS:
            still[:] = True
        out[ok & still] = faults.AMBIGUOUS
    spans = [(f, f) for f in choice.ambiguous_m] + [tuple(s) for s in choice.ambiguous_spans_m]
    for lo, hi in spans:
        near = (distance_m >= lo - GATE_M) & (distance_m <= hi + GATE_M)
        for f, a, b in choice.rests_s if lo == hi else ():     # a body's rest, there from a to b alone
            near &= (np.abs(lo - f) > APART_M) | ((time_s >= a) & (time_s <= b))
        out[(out == faults.OK) & near] = faults.AMBIGUOUS
    if imaged is not None:
        out[(out == faults.OK) & imaged] = faults.AMBIGUOUS
    if choice.at_rest_m is not None:        # a fixed object: what moves, or lies elsewhere, is another
        other = (np.abs(distance_m - choice.at_rest_m) > GATE_M) | (np.abs(velocity_mps) >= MOVING_MPS)
        ok = (out == faults.OK) & ~other
        other |= _blended(time_s, distance_m, velocity_mps, ok,
                          np.broadcast_to(velocity_sigma_mps, np.shape(velocity_mps)), velocity_bias_mps)
        out[(out == faults.OK) & other] = faults.AMBIGUOUS
        ok = out == faults.OK
        if ok.sum() >= 20:              # ... and so does a blend with an echo beside it: its peak moves
            mid = np.median(distance_m[ok])
            spread = 1.4826 * np.median(np.abs(distance_m[ok] - mid))
            out[ok & (np.abs(distance_m - mid) > max(REST_SIGMAS * spread, REST_M))] = faults.AMBIGUOUS
    if choice.taken_s.size:                 # another object's path within GATE_M (fmcw_cl.objects)
        near = np.abs(choice.taken_s[nearest(choice.taken_s, time_s)] - time_s) < 1e-9
        out[(out == faults.OK) & near] = faults.AMBIGUOUS
    return out
