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
  becomes the gap between them that holds the moving echo's span (each edge
  WALL_MARGIN_M inside the fixed echo, or half way to the span where that is nearer). A fixed echo
  inside the span (or within APART_M of its ends) is the target at rest when it fades
  with the target's departure; one that stays while the target is elsewhere is another
  object, and the pairs within GATE_M of it are ``ambiguous`` (where the span comes
  from the smeared energy alone, while the first conversion held the object, the part
  beside the objects that holds most of the smeared energy's slices is tracked
  instead: the object would hold the tracker again). With no moving echo and several fixed echoes, or
  several moving echoes, the rule cannot tell which is the target: every pair on one of
  them is ``ambiguous``. With no echo at all at a slice's or a block's level, the
  echoes of the capture's mean spectra (`Echoes.peaks`) stand for the fixed ones; with
  none there either, the verified pairs in motion stand (`ambiguous` below). With one
  echo, it is the target, unless
  OTHERS_SHARE of all the half-sweeps hold other echoes in the band (something neither
  fixed nor found moving), or the capture's mean spectra hold another echo (one within
  APART_M of it that its power hides from the CFAR, `echoes.masked_peaks`, or a peak of
  both directions more than GATE_M from it, its harmonics excepted), or they put it at
  two distances more than SPLIT_M apart in the two directions (a conversion that moves
  an echo at rest: the sync delay or the chirp off): then the pairs on it are
  ``ambiguous``. Before that, the moving echoes a second look beside it finds
  (fmcw_cl.second_look; `Choice.lone` asks for one) join the choice; after it, where
  OTHERS_SHARE of the verified pairs lie more than GATE_M from the echo, the tracker
  held something else the tables missed, and the pairs on either are ``ambiguous``
  (so are they beside several fixed echoes).
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

from . import echoes
from .numeric import drift, group_median, nearest
from .options import RANGE_GAP_M, said
from .stages import faults
from .stages.verification import DRIFT_MPS

RULES = ("auto", "moving", "nearest", "strongest")
FIXED_SHARE = 0.5     # of the slices a fixed echo is seen in
MOVING_MPS = 0.3      # a verified pair this fast belongs to the moving echo
GATE_M = 0.01         # pairs this close to an echo the target cannot be told from are ambiguous
WALL_MARGIN_M = 0.03  # a band edge lies this far inside a left-out fixed echo where the gap allows
MIN_GAP_M = 0.004     # a band edge lies at least half this inside a left-out fixed echo
APART_M = 0.02        # fixed echoes closer than this are one (a smeared peak's lobes); nearer the
                      # target's span than this, a fixed echo is not left out of the band
MIN_TRAVEL_M = 0.01   # a moving echo's verified pairs span at least this (a biased velocity is no motion)
TOGETHER_S = 2e-3    # pairs this close in time but APART_M apart are two moving echoes
AWAY_SHARE = 0.5      # a fixed echo seen in this share of the slices where the target is away is an object
AWAY_SWEEPS = 20      # ... judged by half-sweeps where no slice is away, by at least this many
OTHERS_SHARE = 0.1    # "one echo" only while fewer half-sweeps than this share hold another echo (false
                      # alarms: 0.1-0.8 % of all; a rail start under noise at full scale beside a wall: 22 %)
REST_SIGMAS = 6.0     # a fixed object's pair further than this many robust sigmas from its median ...
REST_M = 2.5e-4       # ... and than this is a blend with another echo beside it (a foot at rest 5 mm from
                      # a window read the window 3 mm off)
SPLIT_M = 0.002       # a fixed echo's directions this far apart in the mean spectra: the conversion is off
SWING_FIT = 0.9       # a target swings where its pairs' Doppler shifts explain this share of its plain
                      # peaks' offsets (their power) ...
SMEAR_M = 0.001       # ... and reach a resolution cell; the mean spectra's peaks within its reach plus
                      # this are its own (a vibration's peaks swing +-9 mm at 0.31 m/s, +-1.8 at 0.06)
HARMONICS = 3         # a fixed echo at 2..HARMONICS times the distance of a far stronger one ...
HARMONIC_M = 0.002    # ... within this (a distortion's tone lies at the multiple of the bin) ...
HARMONIC_DB = 20.0    # ... and this much weaker is its harmonic (a target at rest 8.6 mm from twice
                      # a wall's distance, as strong, is none)


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
    lone : one fixed echo was taken for the target before a second look beside it.
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
    lone: bool = False      # one fixed echo taken for the target, before a second look beside it
    unseen_rest: bool = False   # no echo at all: the pairs at rest (under MOVING_MPS) stand on none
    walls_m: np.ndarray = field(default_factory=lambda: np.zeros(0))
    walls_db: np.ndarray = field(default_factory=lambda: np.zeros(0))
    at_rest_m: float | None = None    # a fixed object (fmcw_cl.objects): its pairs only at rest, there
    taken_s: np.ndarray = field(default_factory=lambda: np.zeros(0))   # pair times another object shares

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


def fixed_echoes(e: echoes.Echoes, unambiguous_m: float, found: list | None = None
                 ) -> tuple[np.ndarray, np.ndarray]:
    """(distances m, levels dB) of the fixed echoes of an echo table (see the module):
    the CFAR's echoes clustered in each slice, and the peaks of the mean spectra
    (`found`, from `_found`, where at hand), less the harmonics of stronger ones (a
    detector's or a converter's distortion)."""
    found = _found(e) if found is None else found
    out_d: list[float] = []
    out_s: list[float] = []
    for x, level in found:
        if out_d and x - out_d[-1] < APART_M:            # one echo: the stronger stands for both
            if level > out_s[-1]:
                out_d[-1], out_s[-1] = x, level
            continue
        out_d.append(x)
        out_s.append(level)
    d, s = np.asarray(out_d), np.asarray(out_s)
    keep = ~harmonic(d, s, unambiguous_m)
    return d[keep], s[keep]


def _found(e: echoes.Echoes) -> list[tuple[float, float]]:
    """(distance m, level dB) of every fixed echo of the two tables, in order, before
    those within APART_M of each other are one."""
    return sorted([*_sharp(e), *_averaged(e)])


def harmonic(d: np.ndarray, level: np.ndarray, unambiguous_m: float) -> np.ndarray:
    """Which echoes (distances `d` m, levels dB) lie within HARMONIC_M of 2..HARMONICS
    times the distance of one at least HARMONIC_DB stronger, folded into [0,
    unambiguous_m] as a real beat's tone folds at the resampled Nyquist frequency."""
    m = np.arange(2, HARMONICS + 1)
    at = np.mod(d[:, None] * m, 2 * unambiguous_m)                  # (echo, multiple)
    at = np.minimum(at, 2 * unambiguous_m - at)
    near = np.abs(d[None, :, None] - at[:, None, :]).min(axis=2) <= HARMONIC_M   # (source, echo)
    return np.any(near & (level[:, None] >= level[None, :] + HARMONIC_DB), axis=0)


def _sharp(e: echoes.Echoes) -> list[tuple[float, float]]:
    """(distance m, median CFAR SNR dB) of the echoes whose CFAR detections cluster in
    both directions of FIXED_SHARE of the slices."""
    if e.time_s.size == 0:
        return []
    # each direction of each slice apart: an echo seen in one only is a moving target's
    # Doppler image
    slice_ = np.floor((e.time_s - e.time_s.min()) / echoes.SLICE_S).astype(np.int64)
    key = 2 * slice_ + e.rising.astype(np.int64)
    first = np.r_[True, (np.diff(e.time_s) != 0) | (np.diff(key) != 0)]   # a half-sweep's first echo
    sweeps = np.bincount(key[first], minlength=2 * slice_.max() + 2)
    kept = np.bincount(slice_[first], minlength=slice_.max() + 1) >= 20
    rows = kept[slice_]
    g, d, snr, _ = echoes.keyed_clusters(key[rows], e.distance_m[rows], e.snr_db[rows], sweeps)
    return _fixed(g % 2 == 1, d, snr, int(kept.sum()))


def _averaged(e: echoes.Echoes) -> list[tuple[float, float]]:
    """(distance m, median power over the noise dB) of the echoes at the peaks of both
    directions' mean spectra (echoes.mean_peaks) in FIXED_SHARE of their blocks."""
    m = e.means
    blocks = np.unique(m["mean_time_s"])          # a block's two directions share its time
    if blocks.size == 0:
        return []
    return _fixed(m["peak_rising"], m["peak_distance_m"], m["peak_snr_db"], blocks.size)


def _fixed(rising: np.ndarray, d: np.ndarray, level: np.ndarray, groups: int) -> list[tuple[float, float]]:
    """(distance, level) of the echoes (one a group and distance) seen at one distance in
    FIXED_SHARE of `groups` (slices, or blocks) in each direction: each rising cluster
    paired with the nearest falling one within GATE_M, at their midpoint and the weaker
    level. The two directions need not be seen in the same groups: an echo a few dB over
    the noise is missed in some blocks of each (3 and 4 of 6)."""
    rise = list(echoes.clusters(d[rising], level[rising], groups, FIXED_SHARE))
    fall = list(echoes.clusters(d[~rising], level[~rising], groups, FIXED_SHARE))
    if not rise or not fall:
        return []
    f_d = np.array([x for x, _, _ in fall])
    f_s = np.array([lv for _, lv, _ in fall])
    out = []
    for x, lv, _ in rise:
        j = int(np.argmin(np.abs(f_d - x)))
        if abs(f_d[j] - x) <= GATE_M:
            out.append((0.5 * (x + float(f_d[j])), min(float(lv), float(f_s[j]))))
    return out


def _whole(e: echoes.Echoes, band) -> np.ndarray:
    """The distances (m) of the echoes of the capture's mean spectra (Echoes.peaks), the
    two directions' within GATE_M as one, at their mean: a target at rest at -20 dB per
    sample over 10 ms is too weak for the CFAR's slices and the survey's blocks, and
    stands over the noise of one direction's mean spectrum of 13 half-sweeps."""
    return np.asarray(_merged(e.peaks(band[0], band[1] or np.inf)[1]))


def _merged(d: np.ndarray) -> list[float]:
    """Distances (m) sorted, those within GATE_M of the next as one, at their mean."""
    d = np.sort(d)
    return [float(np.mean(g)) for g in np.split(d, np.flatnonzero(np.diff(d) > GATE_M) + 1) if g.size]


def smeared(e: echoes.Echoes, band) -> np.ndarray:
    """The distances (m) of the echoes found by their Doppler-smeared energy (the echo
    table's diffuse persistent echoes) inside `band`."""
    p = e.persistent
    d = p["distance_m"]
    return d[p["diffuse"] & (d >= band[0]) & (d < (band[1] or np.inf))]


def moving_spans(time_s, distance_m, velocity_mps, valid, diffuse: np.ndarray) -> list[tuple[float, float]]:
    """(lo, hi) of each moving echo's distances (m), nearest first, from the verified
    pairs and the distances of the echoes found by their Doppler-smeared energy
    (`diffuse`, m: `smeared`).

    The fast verified pairs part where APART_M of range holds none; neighbouring parts
    are one echo unless both were measured within TOGETHER_S (one target cannot be in
    both: it would have crossed APART_M in that time). The Doppler-smeared echoes join
    the nearest part (alone, they are one echo).
    """
    fast = valid & (np.abs(velocity_mps) >= MOVING_MPS)
    t, d = time_s[fast], distance_m[fast]
    order = np.argsort(d, kind="stable")
    t, d = t[order], d[order]
    parts: list[tuple[np.ndarray, np.ndarray]] = []
    for g in np.split(np.arange(d.size), np.flatnonzero(np.diff(d) > APART_M) + 1):
        if g.size and parts and not _together(parts[-1][0], t[g]):
            parts[-1] = (np.concatenate([parts[-1][0], t[g]]), np.concatenate([parts[-1][1], d[g]]))
        elif g.size:
            parts.append((t[g], d[g]))
    # pairs must travel (a biased velocity is no motion)
    parts = [(pt, pd) for pt, pd in parts if pd.size >= 3 and np.ptp(pd) >= MIN_TRAVEL_M]
    if not parts:                               # a slice's smeared energy is evidence alone
        parts = [(np.zeros(0), diffuse)] if diffuse.size else []
    else:
        for x in diffuse:
            k = int(np.argmin([min(abs(x - pd.min()), abs(x - pd.max())) for _, pd in parts]))
            parts[k] = (parts[k][0], np.append(parts[k][1], x))
    return sorted((float(np.percentile(pd, 1)), float(np.percentile(pd, 99))) for _, pd in parts)


def _together(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether some time of `a` lies within TOGETHER_S of one of `b` (s)."""
    a = np.sort(a)
    return bool(np.any(np.abs(a[nearest(a, b)] - b) < TOGETHER_S))


def _objects(fixed: np.ndarray, time_s, distance_m, velocity_mps, valid, e: echoes.Echoes) -> np.ndarray:
    """Whether each fixed echo stays while the tracked target is elsewhere: seen in
    AWAY_SHARE of the slices (of >= 20 valid pairs) whose valid pairs' median lies more
    than GATE_M from it, by the CFAR (in echoes.PRESENT of the slice's half-sweeps) or at
    a peak of a mean spectrum of the slice (a wall of 150 codes, found by the mean
    spectra alone, stood at 0.309 m while a take-off went on below it: taken for the
    target at rest, 374 pairs on it were valid); where no slice is away, `_beside`. What
    the tracked target's own plain peaks make (a tracked detection, `_own_peaks`) is not
    the echo seen: its Doppler image lies beside it."""
    if fixed.size == 0 or time_s.size == 0:
        return np.zeros(fixed.size, bool)
    t0 = time_s.min()
    nslices = int((time_s.max() - t0) // echoes.SLICE_S) + 1
    k = ((time_s[valid] - t0) // echoes.SLICE_S).astype(np.int64)
    full = np.bincount(k, minlength=nslices) >= 20
    mid = np.where(full, group_median(k, distance_m[valid], nslices), np.nan)   # the slice's median distance
    # the echoes' slices (echo times outside the pairs' span fall out)
    ke = ((e.time_s - t0) // echoes.SLICE_S).astype(np.int64)
    inside = (ke >= 0) & (ke < nslices)
    ke, de = ke[inside], e.distance_m[inside]
    first = np.diff(e.time_s[inside], prepend=np.nan) != 0    # a half-sweep's first echo (none: none)
    sweeps = np.bincount(ke[first], minlength=nslices)
    mine = _images(e, time_s, distance_m, velocity_mps, valid)    # the target's own Doppler images
    own = mine[inside]
    kp = ((e.means["peak_time_s"] - t0) // echoes.SLICE_S).astype(np.int64)     # the mean spectra's peaks
    kept = (kp >= 0) & (kp < nslices) & ~_own_peaks(e, mine, float(np.median(np.diff(time_s))))
    kp, dp = kp[kept], e.means["peak_distance_m"][kept]
    out = np.zeros(fixed.size, bool)
    for n, f in enumerate(fixed):
        away = full & (np.abs(mid - f) > GATE_M)
        hits = np.bincount(ke[~own & (np.abs(de - f) <= 1.5 * echoes.HIST_M)], minlength=nslices)
        peaks = np.bincount(kp[np.abs(dp - f) <= 1.5 * echoes.HIST_M], minlength=nslices)
        seen = away & (((sweeps > 0) & (hits >= echoes.PRESENT * sweeps)) | (peaks > 0))
        if away.any():
            out[n] = seen.sum() >= AWAY_SHARE * away.sum()
        else:                   # the target never leaves it by a slice: its half-sweeps tell
            out[n] = bool(peaks.any()) or _beside(f, e)
    return out


def _images(e: echoes.Echoes, time_s, distance_m, velocity_mps, valid) -> np.ndarray:
    """Which detections of the echo table are the tracked target's own plain peaks where
    its verified pairs put them: tracked, and within 1.5 echoes.HIST_M of their pair's
    distance moved by its direction's Doppler shift, k v with k fitted over the
    capture (`doppler_reach`'s fit). A tracked detection elsewhere is what the plain
    pass held instead (a wall, while the de-chirped pairs followed the target)."""
    out = np.zeros(e.time_s.size, bool)
    held, offset, v = _offsets(e, time_s, distance_m, velocity_mps, valid)
    for way in (True, False):
        m = e.rising[held] == way
        k = _shift_per_mps(offset[m], v[m])
        out[held[m]] = np.abs(offset[m] - k * v[m]) <= 1.5 * echoes.HIST_M
    return out


def _own_peaks(e: echoes.Echoes, mine: np.ndarray, period_s: float) -> np.ndarray:
    """Which peaks of the mean spectra (`e.means`) the tracked target's own plain peaks
    make: echoes.PRESENT of its direction's own images (`mine`, `_images`) within half a
    block of the mean spectrum's time (echoes.MEAN_ROWS surveyed half-sweeps, every
    echoes.SURVEY_STRIDE-th pair of `period_s`) lie within 1.5 echoes.HIST_M of the
    peak (a landing turning at 0.4 m/s puts one direction's image 11 mm beside its
    pairs; a jump slowing onto its plateau, its image's end at its rest)."""
    m = e.means
    t, d, rising = m["peak_time_s"], m["peak_distance_m"], m["peak_rising"]
    half = 0.5 * echoes.MEAN_ROWS * echoes.SURVEY_STRIDE * period_s
    tt, dt, rt = e.time_s[mine], e.distance_m[mine], e.rising[mine]
    out = np.zeros(t.size, bool)
    for i in range(t.size):
        sel = (rt == rising[i]) & (np.abs(tt - t[i]) <= half)
        out[i] = bool(sel.any()) and np.mean(np.abs(dt[sel] - d[i]) <= 1.5 * echoes.HIST_M) >= echoes.PRESENT
    return out


def _beside(f: float, e: echoes.Echoes) -> bool:
    """Whether a fixed echo at `f` (m) is seen beside the tracked target in single
    half-sweeps: of those whose tracked detection lies more than GATE_M from it (a
    louder echo nearer may hide it from the CFAR), OTHERS_SHARE hold an untracked
    detection within 1.5 echoes.HIST_M of it. True also where fewer than AWAY_SWEEPS
    half-sweeps lie away (nothing tells). False: every detection there is the tracked
    target's own (15 ms of a jump slowing onto its plateau, within a slice of it)."""
    sweep, at = np.unique(e.time_s, return_inverse=True)     # a half-sweep's detections share its time
    near = np.abs(e.distance_m - f) <= 1.5 * echoes.HIST_M
    away = np.zeros(sweep.size, bool)
    away[at[e.tracked & (np.abs(e.distance_m - f) > GATE_M)]] = True
    other = np.zeros(sweep.size, bool)
    other[at[~e.tracked & near]] = True
    return bool(away.sum() < AWAY_SWEEPS or (other & away).sum() >= OTHERS_SHARE * away.sum())


def _gap(span: tuple[float, float], fixed: np.ndarray, band) -> tuple[float, float | None]:
    """The band around `span` that leaves out the echoes whose (lo, hi) (m) are the rows
    of `fixed` (all outside it)."""
    lo, hi = band
    below, above = fixed[fixed[:, 1] < span[0], 1], fixed[fixed[:, 0] > span[1], 0]
    if below.size:
        f = below.max()
        lo = max(lo, f + _margin(span[0] - f))
    if above.size:
        f = above.min()
        edge = f - _margin(f - span[1])
        hi = edge if hi is None else min(hi, edge)
    return lo, hi


def _margin(gap: float) -> float:
    """How far inside a left-out fixed echo a band edge lies, `gap` m from the target's
    span: WALL_MARGIN_M (its lobes stay out), less where the gap is narrow (half of it,
    at least MIN_GAP_M / 2)."""
    return min(WALL_MARGIN_M, max(MIN_GAP_M / 2, gap / 2))


@dataclass(frozen=True)
class Fixed:
    """The fixed echoes of a first conversion, whatever a second look finds beside them:
    every one listed (`_found`), those standing for the others (`fixed_echoes`: distances
    m, levels dB), and whether each of these is an object (`_objects`)."""

    listed: list[tuple[float, float]]
    distance_m: np.ndarray
    level_db: np.ndarray
    objects: np.ndarray


def fixed_of(e: echoes.Echoes, unambiguous_m: float, time_s, distance_m, velocity_mps, valid) -> Fixed:
    """The `Fixed` echoes of a first conversion's echo table `e` and pairs (times s,
    distances m, velocities m/s, valid), for `choose`; `unambiguous_m` is the capture's
    unambiguous range."""
    listed = _found(e)
    d, level = fixed_echoes(e, unambiguous_m, listed)
    return Fixed(listed, d, level, _objects(d, time_s, distance_m, velocity_mps, valid, e))


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
    each stands for, `extent` (m), whether each is an object (`_objects`), and the kind
    `prefer`red at a tie of `near_m`."""
    inband = (fixed >= band[0]) & (fixed < (band[1] or np.inf))
    fixed, extent, objects = fixed[inband], extent[inband], objects[inband]
    diffuse = smeared(e, band)
    spans = sorted(moving_spans(time_s, distance_m, velocity_mps, valid, diffuse) + (beside or []))
    if fixed.size == 0 and not spans:   # none at a slice's or a block's level: those the capture's show
        fixed = _whole(e, band)
        extent = np.c_[fixed, fixed]
        objects = _objects(fixed, time_s, distance_m, velocity_mps, valid, e)
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
        seen = _others(e, fixed[0], band, 2 * np.size(time_s))
        if seen >= OTHERS_SHARE:                      # an echo that is neither fixed nor found moving
            return Choice(name, fixed, objects, None, False, band, fixed.copy(),
                          note=f"no echo moves, but {100 * seen:.0f} % of the half-sweeps hold other echoes "
                               f"than the fixed echo at {_list(fixed)}: the target cannot be told apart")
        hidden = _besides(e, fixed[0], band, unambiguous_m, clipped)
        if swings:                                    # its own swing fills the mean spectra
            hidden = [x for x in hidden if not lo - reach - SMEAR_M <= x <= hi + reach + SMEAR_M]
        if hidden:                                    # an echo too weak or too near for the CFAR
            # the tracker may follow either: a wall the target's CFAR echoes outnumber, its
            # pairs 16 mm from the fixed echo (noise at full scale)
            return Choice(name, fixed, objects, None, False, band, np.sort(np.r_[fixed, hidden]),
                          note=f"no echo moves, but the capture's mean spectra hold another echo at "
                               f"{_list(hidden)} besides the fixed echo at {_list(fixed)}: the target "
                               "cannot be told apart")
        split = None if swings else _split(e, fixed[0], band)
        if split is not None:                         # a conversion that moves an echo at rest
            return Choice(name, fixed, objects, None, False, band, fixed.copy(),
                          note=f"no echo moves, but the fixed echo at {_list(fixed)} lies at "
                               f"{split[0]:.4f} m rising and {split[1]:.4f} m falling in the capture's mean "
                               "spectra (the sync delay or the chirp off): the target cannot be told apart")
        away = _elsewhere(distance_m, valid, fixed) if beside is not None else None
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
        away = _elsewhere(distance_m, valid, fixed, velocity_mps)
        held = "" if away is None else f" and the verified pairs at {away[1]:.3f}-{away[2]:.3f} m"
        return Choice(name, fixed, objects, None, False, band, fixed.copy(),
                      ambiguous_spans_m=np.zeros((0, 2)) if away is None else np.asarray([away[1:]]),
                      note=f"no echo moves: the fixed echoes at {_list(fixed)}{held} cannot be told apart")
    if target is None and _swinging(e, time_s, distance_m, velocity_mps, valid):
        # no echo stays put, none travels, but the tracked peaks swing with the pairs'
        # velocities and the distances follow them: one echo (a foot bouncing +-4 mm)
        return Choice(name, fixed, objects, None, False, band,
                      note="one echo, swinging with its velocity (no fixed or moving echo): the target")
    if target is None:        # no echo: a moving target seen too briefly stands, one at rest on nothing
        return Choice(name, fixed, objects, None, False, band, unseen_rest=True,
                      note="no echo found, fixed or moving: the verified pairs in motion stand")
    (lo, hi), moving = target
    outside = (extent[:, 1] < lo - APART_M) | (extent[:, 0] > hi + APART_M)
    # the other moving echoes bound the band by their nearer ends
    others = [a if a > hi else b for a, b in spans if (a, b) != (lo, hi)]
    inner = ~outside & objects if moving else np.zeros(fixed.size, bool)
    within = fixed[inner]
    what = (f"the moving echo at {lo:.3f}-{hi:.3f} m" if moving else f"the echo at {lo:.3f} m")
    bounds = np.concatenate([extent[outside], np.c_[others, others]])
    new = _gap((lo, hi), bounds, band)
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
    if within.size:
        note += f"; ambiguous where it passes the fixed echoes at {_list(within)}"
    return Choice(name, fixed, objects, (lo, hi), moving, new, within, note)


def _part_band(span: tuple[float, float], cuts: np.ndarray, found: np.ndarray, bounds: np.ndarray, band
               ) -> tuple[float, float | None] | None:
    """The band of the part of `span` (m) beside the (lo, hi) `cuts` (m) within APART_M
    of it that holds most of the distances where smeared energy was `found` (m): `_gap`
    of the part (clipped to the span) with the other echoes `bounds` ((lo, hi) rows, m),
    its edge at a cut GATE_M inside the part (nearer, the pairs are `ambiguous` anyway).
    None where no part holds more than
    half of them (the target may spend as long on either side, and leave the band where
    the tracker takes what it holds: a rail's start 14 mm before a wall of 3000 codes,
    one slice found on each side, left the band and 49 pairs were valid 25 mm off) or
    the band is narrower than options.RANGE_GAP_M."""
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


def _elsewhere(distance_m: np.ndarray, valid: np.ndarray, fixed_m: np.ndarray,
               still: np.ndarray | None = None) -> tuple[float, ...] | None:
    """(share, lo, hi m) of the verified pairs more than GATE_M from every fixed echo
    `fixed_m` (those no `ambiguous` verdict on the echoes covers), where they are
    OTHERS_SHARE of the verified pairs at least (None else): the tracker held another
    echo that the tables (and the second look) missed. With velocities `still` (m/s),
    only where those pairs are at rest (99 % of them slower than MOVING_MPS). A landing
    under noise at full scale passed a wall of 800 codes and rested 32 mm before it for
    18 ms: "one echo" put 507 valid pairs on the wall, up to 64 mm off; a target at rest
    between walls, 18 mm from one of 400 codes that no table found, the fixed echoes
    ambiguous: 392 valid pairs on that wall."""
    ok = np.asarray(valid, bool)
    far = ok & (np.min(np.abs(distance_m[:, None] - np.asarray(fixed_m)[None, :]), axis=1) > GATE_M)
    if not ok.any() or far.sum() < OTHERS_SHARE * ok.sum():
        return None
    if still is not None and np.percentile(np.abs(still[far]), 99) >= MOVING_MPS:
        return None
    d = distance_m[far]
    return float(far.sum() / ok.sum()), float(np.percentile(d, 1)), float(np.percentile(d, 99))


def _others(e: echoes.Echoes, fixed_m: float, band, sweeps: int) -> float:
    """The share of the capture's `sweeps` half-sweeps whose CFAR echoes include one
    inside `band` that is not the tracked peak and lies APART_M or more from the fixed
    echo at `fixed_m`. Of all half-sweeps, not of those with an echo: a weak target's
    single half-sweeps rarely hold one (at -20 dB per sample 10 of 796, one of them a
    false alarm)."""
    inside = ((e.distance_m >= band[0]) & (e.distance_m < (band[1] or np.inf)) & ~e.tracked
              & (np.abs(e.distance_m - fixed_m) >= APART_M))
    return np.unique(e.time_s[inside]).size / sweeps if sweeps else 0.0


def _besides(e: echoes.Echoes, fixed_m: float, band, unambiguous_m: float, clipped: bool = False
             ) -> list[float]:
    """The distances (m) of the other echoes that either direction's mean spectrum over
    the capture holds inside `band`, the two directions' within GATE_M as one, at their
    mean:
    - within APART_M of the fixed echo at `fixed_m`, those its power hides from the CFAR
      (echoes.masked_peaks): a second object at rest a few resolution cells away, or a
      moving target's Doppler-shifted peak in one direction;
    - the peaks (echoes.mean_peaks) more than GATE_M from it, but its harmonics
      (`harmonic`): an object at rest too weak for a half-sweep's CFAR, seen over the
      capture (at noise at full scale, a target 5.6-5.8 dB over the noise in the mean
      spectra had 7 CFAR echoes in 1996 half-sweeps, as many as the false alarms, and the
      wall seen in 28 was taken for it; in one direction only, the other's just under
      the limit), or the peaks of a blend of echoes around the fixed one (walls at 0.404
      and 0.435 m, the target at 0.416 m between). Where some pairs are `clipped`, only
      peaks of both directions within GATE_M of each other: a clipped stretch's
      distortion puts peaks 7 dB over the noise into one direction's mean spectrum or the
      other's."""
    lo, hi = band[0], band[1] or np.inf
    near = e.masked(lo, hi)
    rising, d, db = e.peaks(lo, hi)
    own = np.abs(d - fixed_m) <= GATE_M
    level = np.max(db[own]) if own.any() else -np.inf        # the fixed echo's, where a peak
    far = ~own & ~harmonic(np.r_[fixed_m, d], np.r_[level, db], unambiguous_m)[1:]
    far = [x for x, _ in _fixed(rising[far], d[far], db[far], 1)] if clipped else d[far]
    return _merged(np.r_[near[np.abs(near - fixed_m) < APART_M], far])


def doppler_reach(e: echoes.Echoes, time_s, distance_m, velocity_mps, valid) -> float:
    """How far (m) the tracked peaks of the plain pass (`e.tracked`) swing from their
    verified pair's distance with its velocity: in each direction the peaks' offset is
    fitted as a multiple of the pair's velocity (their Doppler shift, opposite in the
    two), and where that explains SWING_FIT of the offsets' power in both, 99 % of the
    fitted shifts lie within the reach; else 0 (a target at rest: noise; noise at full
    scale: the tracked peaks anywhere, not with the velocity). A vibration of 50 um at
    1 kHz: 9 mm, its mean spectra's peaks at the ends of its swing in each direction."""
    held, offset, v = _offsets(e, time_s, distance_m, velocity_mps, valid)
    rising = e.rising[held]
    reach = 0.0
    for way in (rising, ~rising):
        o, u = offset[way], v[way]
        power, weight = float(np.sum(o * o)), float(np.sum(u * u))
        if o.size < 2 or power == 0.0 or weight == 0.0:
            return 0.0
        shift = _shift_per_mps(o, u) * u                      # the fitted Doppler shifts (m)
        if 1.0 - float(np.sum((o - shift) ** 2)) / power < SWING_FIT:
            return 0.0
        reach = max(reach, float(np.percentile(np.abs(shift), 99)))
    return reach


def _offsets(e: echoes.Echoes, time_s, distance_m, velocity_mps, valid
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The tracked detections of the echo table that lie within a period of a verified
    pair (their indices), their offsets from that pair's distance (m) and its velocity
    (m/s); all empty with under two verified pairs."""
    ok = np.flatnonzero(np.asarray(valid, bool) & np.isfinite(distance_m) & np.isfinite(velocity_mps))
    held = np.flatnonzero(e.tracked)
    if ok.size < 2 or held.size == 0:
        return np.zeros(0, np.int64), np.zeros(0), np.zeros(0)
    at = ok[nearest(time_s[ok], e.time_s[held])]
    near = np.abs(time_s[at] - e.time_s[held]) <= np.median(np.diff(time_s))
    held, at = held[near], at[near]
    return held, e.distance_m[held] - distance_m[at], velocity_mps[at]


def _shift_per_mps(offset: np.ndarray, velocity: np.ndarray) -> float:
    """The least-squares Doppler shift per m/s (m) of one direction's `offset`s (m) at
    their pairs' `velocity` (m/s); 0 where every velocity is 0."""
    weight = float(np.sum(velocity**2))
    return float(np.sum(offset * velocity)) / weight if weight > 0 else 0.0


def _swinging(e: echoes.Echoes, time_s, distance_m, velocity_mps, valid) -> bool:
    """Whether the verified pairs are one echo in motion though no echo of the tables
    stays or travels: their tracked plain peaks swing with their velocities
    (`doppler_reach` >= SMEAR_M: noise cannot) and their distances follow those
    velocities (numeric.drift within pairing.DRIFT_MPS: a wall at rest read at 0.35 m/s
    under a delay 77 samples off has plain peaks offset with its constant velocity, but
    its distances stand still)."""
    ok = np.asarray(valid, bool) & np.isfinite(distance_m) & np.isfinite(velocity_mps)
    if ok.sum() < 3 or doppler_reach(e, time_s, distance_m, velocity_mps, valid) < SMEAR_M:
        return False
    return abs(drift(time_s[ok], distance_m[ok], velocity_mps[ok])[0]) <= DRIFT_MPS


def _split(e: echoes.Echoes, fixed_m: float, band) -> tuple[float, float] | None:
    """(rising, falling) distances (m) of the fixed echo at `fixed_m` in the two
    directions' mean spectra over the capture (their peaks within GATE_M of it nearest
    to it) where they lie more than SPLIT_M apart: an echo at rest lies at one distance
    in both, unless the conversion is off (a sync delay 55 samples off under noise at
    full scale: a wall at 0.2325 and 0.2401 m, and the target beside it lost)."""
    rising, d, _ = e.peaks(band[0], band[1] or np.inf)
    near = np.abs(d - fixed_m) <= GATE_M
    if not (near & rising).any() or not (near & ~rising).any():
        return None
    r, f = (d[m][np.argmin(np.abs(d[m] - fixed_m))] for m in (near & rising, near & ~rising))
    return (float(r), float(f)) if abs(r - f) > SPLIT_M else None


def _list(xs) -> str:
    return ", ".join(f"{x:.3f}" for x in xs) + " m"


def ambiguous(code: np.ndarray, time_s: np.ndarray, distance_m: np.ndarray, velocity_mps: np.ndarray,
              choice: Choice, imaged: np.ndarray | None = None) -> np.ndarray:
    """`code` with the OK pairs within GATE_M of the choice's ambiguous echoes (fixed
    echoes and moving spans) or `imaged` (a half-sweep's peak may be the image of a
    fixed echo, fmcw_cl.wall_images) set to faults.AMBIGUOUS; with no echo found
    (`Choice.unseen_rest`), those slower than MOVING_MPS, or all where their distances
    do not follow their velocities (numeric.drift beyond pairing.DRIFT_MPS: a wall at
    rest read at 0.35 m/s under a sync delay 77 samples off)."""
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
        out[(out == faults.OK) & near] = faults.AMBIGUOUS
    if imaged is not None:
        out[(out == faults.OK) & imaged] = faults.AMBIGUOUS
    if choice.at_rest_m is not None:        # a fixed object: what moves, or lies elsewhere, is another
        other = (np.abs(distance_m - choice.at_rest_m) > GATE_M) | (np.abs(velocity_mps) >= MOVING_MPS)
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
