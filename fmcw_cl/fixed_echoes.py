"""The fixed echoes of a conversion's tables, and which of them are objects.

The rules are fmcw_cl.target's (its docstring): a fixed echo clusters in both
directions of FIXED_SHARE of the 10 ms slices (or of the survey's blocks), those within
APART_M are one, harmonics of far stronger ones are none (`fixed_echoes`); a moving echo
spans the verified pairs that move and the Doppler-smeared energy (`moving_spans`); a
fixed echo seen while the target is away is an object (`are_objects`), not the target's
own rest or its Doppler images (`swing`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import echoes
from .numeric import group_median, nearest, ragged
from .swing import peak_offsets, shift_per_mps

FIXED_SHARE = 0.5     # of the slices a fixed echo is seen in
MOVING_MPS = 0.3      # a verified pair this fast belongs to the moving echo
GATE_M = 0.01         # pairs this close to an echo the target cannot be told from are ambiguous
ONE_M = 2e-3          # two echoes this close make one peak: two range resolutions at 160 GHz (c / 2B
                      # = 0.94 mm), a Hann window's main lobe at half power
APART_M = 0.02        # fixed echoes closer than this are one (a smeared peak's lobes); nearer the
                      # target's span than this, a fixed echo is not left out of the band
MIN_TRAVEL_M = 0.01   # a moving echo's verified pairs span at least this (a biased velocity is no motion)
TOGETHER_S = 2e-3    # pairs this close in time but APART_M apart are two moving echoes
AWAY_SHARE = 0.5      # a fixed echo seen in this share of the slices where the target is away is an object
AWAY_SWEEPS = 20      # ... judged by half-sweeps where no slice is away, by at least this many
OTHERS_SHARE = 0.1    # "one echo" only while fewer half-sweeps than this share hold another echo (false
                      # alarms: 0.1-0.8 % of all; a rail start under noise at full scale beside a wall: 22 %)
HARMONICS = 3         # a fixed echo at 2..HARMONICS times the distance of a far stronger one ...
HARMONIC_M = 0.002    # ... within this (a distortion's tone lies at the multiple of the bin) ...
HARMONIC_DB = 20.0    # ... and this much weaker is its harmonic (a target at rest 8.6 mm from twice
                      # a wall's distance, as strong, is none)



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


def beside_span(x: float, spans) -> bool:
    """Whether `x` (m) lies within APART_M of one of `spans` ((lo, hi) m): the same echo
    as the span's, its peak split or smeared."""
    return any(a - APART_M <= x <= b + APART_M for a, b in spans)


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
    return in_both_directions(g % 2 == 1, d, snr, int(kept.sum()))


def _averaged(e: echoes.Echoes) -> list[tuple[float, float]]:
    """(distance m, median power over the noise dB) of the echoes at the peaks of both
    directions' mean spectra (echoes.mean_peaks) in FIXED_SHARE of their blocks."""
    m = e.means
    blocks = np.unique(m["mean_time_s"])          # a block's two directions share its time
    if blocks.size == 0:
        return []
    return in_both_directions(m["peak_rising"], m["peak_distance_m"], m["peak_snr_db"], blocks.size)


def in_both_directions(rising: np.ndarray, d: np.ndarray, level: np.ndarray, groups: int
                       ) -> list[tuple[float, float]]:
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


def capture_peaks(e: echoes.Echoes, band) -> np.ndarray:
    """The distances (m) of the echoes of the capture's mean spectra (Echoes.peaks), the
    two directions' within GATE_M as one, at their mean: a target at rest at -20 dB per
    sample over 10 ms is too weak for the CFAR's slices and the survey's blocks, and
    stands over the noise of one direction's mean spectrum of 13 half-sweeps."""
    return np.asarray(merged(e.peaks(band[0], band[1] or np.inf)[1]))


def merged(d: np.ndarray) -> list[float]:
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


def are_objects(fixed: np.ndarray, time_s, distance_m, velocity_mps, valid, e: echoes.Echoes) -> np.ndarray:
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
    held, offset, v = peak_offsets(e, time_s, distance_m, velocity_mps, valid)
    for way in (True, False):
        m = e.rising[held] == way
        k = shift_per_mps(offset[m], v[m])
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
    out = np.zeros(t.size, bool)
    for way in (True, False):
        own = mine & (e.rising == way)
        order = np.argsort(e.time_s[own], kind="stable")     # the table's own order: cheap
        tt, dt = e.time_s[own][order], e.distance_m[own][order]
        # each peak's images lie in one stretch of them: a little wider, the test itself below
        peaks = np.flatnonzero(rising == way)
        which, j = ragged(np.searchsorted(tt, t[peaks] - 1.01 * half, "left"),
                          np.searchsorted(tt, t[peaks] + 1.01 * half, "right"))
        i = peaks[which]
        sel = np.abs(tt[j] - t[i]) <= half
        seen = np.bincount(which[sel], minlength=peaks.size)
        close = np.bincount(which[sel & (np.abs(dt[j] - d[i]) <= 1.5 * echoes.HIST_M)], minlength=peaks.size)
        with np.errstate(invalid="ignore"):
            out[peaks] = (seen > 0) & (close / seen >= echoes.PRESENT)
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


@dataclass(frozen=True)
class Fixed:
    """The fixed echoes of a first conversion, whatever a second look finds beside them:
    every one listed (`_found`), those standing for the others (`fixed_echoes`: distances
    m, levels dB), and whether each of these is an object (`are_objects`)."""

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
    return Fixed(listed, d, level, are_objects(d, time_s, distance_m, velocity_mps, valid, e))
