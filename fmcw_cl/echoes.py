"""Every echo the instrument saw, the persistent ones, and the rival of the tracked target.

Each half-sweep's plain spectrum lists its CFAR echoes (stages.cfar): their distance
carries the half-sweep's Doppler shift, like /sweeps/distance_m. A detection at the
half-sweep's tracked peak is the tracked target. The others are cut into slices of
SLICE_S; in each slice, an echo seen at one distance (within HIST_M) in at least
PRESENT of the slice's half-sweeps is persistent (a wall, a window, a second target
that stays put for a while). Its level, the median CFAR SNR (peak over local noise),
is compared with the tracked target's in the same slice: its own CFAR SNR where the
plain spectra show it in at least SEEN of the slice's half-sweeps, else (a target
too fast to stay sharp without de-chirp) the median SNR of its final de-chirped
peaks, whose noise floor another strong echo raises: the comparison then errs
towards a warning. A persistent echo within RIVAL_DB of the tracked target is the
user's to judge: `process` names it.

An echo too weak for the CFAR in single half-sweeps still stands out of their mean:
the surveyed half-sweeps' plain spectra are averaged in blocks of MEAN_ROWS of a
direction (`block_sums`), and each mean spectrum's peaks are listed (`mean_peaks`):
the mean of K exponential noise bins is Gamma(K)/K, so its noise fluctuates sqrt(K)
less and an echo a few dB over the noise is found in every block (fixed echoes,
fmcw_cl.target).

Both tests take a bin's noise from the louder of its two sides' training bins, so an
echo a few resolution cells beside a louder one is not found: those training bins hold
the louder echo. The surveyed half-sweeps' plain spectra summed over the whole capture
(`Echoes.spectrum`) are searched for such echoes too (`masked_peaks`): a peak outside
any louder echo's main lobe that stands over the quieter side's training bins.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .numeric import group_median, neighbour_sums, ragged
from .stages import bank, cfar
from .stages.cfar import Detections
from .stages.spectrum import interpolate

SLICE_S = 0.01        # persistent echoes are found in slices of 10 ms (200 periods)
HIST_M = 0.002        # distance histogram bin; an echo is counted over 3 neighbouring bins
PRESENT = 0.3         # share of a slice's half-sweeps an echo must be seen in
TRACKED_M = 0.001     # a detection this close to its half-sweep's tracked peak is the target
SEEN = 0.2           # share of a slice's half-sweeps the target's plain peak must be an echo in
SURVEY_STRIDE = 16    # every 16th pair's spectra are surveyed for energy no echo explains
EXPLAIN_BINS = 16     # padded bins either side of a peak counted as its energy
HIDDEN_SIGMAS = 5.0   # unexplained energy must stand this far above the noise of its sum
SHARP = 0.9           # the target's energy within +-3 bins over +-EXPLAIN_BINS (a lone peak: >= 0.96)
RIVAL_DB = 10.0       # a persistent echo this close to the tracked target's level is reported
AT_REST_M = 0.01      # unexplained energy whose directions' centres lie this close has no Doppler shift
                      # (0.17 m/s): an echo at rest the CFAR missed beside a louder one, not a smeared one
MEAN_ROWS = 12        # surveyed half-sweeps of a direction a mean spectrum (12 x 16 periods: 9.6 ms)
# the factor white noise's mean of K spectra (K = 1 .. MEAN_ROWS) exceeds over the
# training mean with probability cfar.PFA: scipy.stats.f.isf(PFA, 2K, K TRAIN) (the
# conversion imports no scipy; tests/test_echoes.py checks the table)
MEAN_LIMITS = np.array([36.9873, 14.0629, 9.2355, 7.1597, 5.9977, 5.2500, 4.7258, 4.3361, 4.0340,
                        3.7922, 3.5937, 3.4276])
LOBE_BINS = cfar.GUARD // 2   # the Hann main lobe's half-width in padded bins (2x padding)
MEAN_KEYS = ("mean_time_s", "mean_rising", "peak_time_s", "peak_rising", "peak_distance_m", "peak_snr_db")


@dataclass
class Echoes:
    """Per detection (flat, in time order), and the persistent echoes per slice.

    Attributes
    ----------
    time_s, distance_m, snr_db, rising, tracked : per detection: its half-sweep's centre
        time (s), distance (m, Doppler shift included), CFAR SNR (dB), current direction,
        and whether it is the tracked peak.
    persistent : dict of arrays per persistent echo and slice: time_s (slice centre),
        distance_m (median), snr_db (median), share (of the slice's half-sweeps),
        relative_db (over the tracked target's level in the slice), in_band (below
        --max-range), diffuse (found by its unexplained energy, not as a sharp echo).
        An echo found by its unexplained energy (`hidden`) in half-sweeps of both
        directions lies at the mean of the two directions' median centres, whose Doppler
        shifts cancel (one direction's alone, where the other's lies below the band or
        folds: a take-off's rising centres), its snr_db the target's level plus
        relative_db; it is diffuse unless both directions' centres lie within AT_REST_M
        (then an echo at rest that the CFAR missed beside a louder one: a wall 10 mm
        before a target at rest, whose energy was taken for a moving echo behind it).
    means : dict of arrays (MEAN_KEYS) of the surveyed half-sweeps' mean spectra: per
        mean spectrum its pairs' mean time (s) and direction, per peak (`mean_peaks`)
        its mean spectrum's time and direction, distance (m) and power over the noise (dB).
    spectrum : (2, nfft/2) the surveyed half-sweeps' mean plain power spectrum over the
        capture, rising then falling ((2, 0) without a survey); `spectrum_rows` the
        half-sweeps of a direction in it, `metres_per_bin` its bins' distance (m).
    fast : dict of arrays (stages.bank.POINT_KEYS): the velocity bank's points, movers too
        fast for a plain peak (time s, distance m, velocity m/s, SNR dB; empty where no
        bank ran: every conversion but the first).
    """

    time_s: np.ndarray
    distance_m: np.ndarray
    snr_db: np.ndarray
    rising: np.ndarray
    tracked: np.ndarray
    persistent: dict
    means: dict = field(default_factory=lambda: no_means())
    spectrum: np.ndarray = field(default_factory=lambda: np.zeros((2, 0)))
    spectrum_rows: int = 0
    metres_per_bin: float = float("nan")
    fast: dict = field(default_factory=lambda: bank.no_points())

    def masked(self, lo_m: float, hi_m: float) -> np.ndarray:
        """The distances (m) of the echoes beside louder ones in either direction's
        `spectrum` (`masked_peaks`) between lo_m and hi_m."""
        if self.spectrum_rows == 0:
            return np.zeros(0)
        lo = max(0, int(np.ceil(lo_m / self.metres_per_bin)))
        d = np.concatenate([masked_peaks(mean, self.spectrum_rows, lo)[0] for mean in self.spectrum])
        d *= self.metres_per_bin
        return d[d < hi_m]

    def peaks(self, lo_m: float, hi_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(rising, distances m, power over the noise dB) of the echoes of either
        direction's `spectrum` (`mean_peaks`, at its limit for MEAN_ROWS spectra) between
        lo_m and hi_m."""
        if self.spectrum_rows == 0:
            return np.zeros(0, bool), np.zeros(0), np.zeros(0)
        lo = max(0, int(np.ceil(lo_m / self.metres_per_bin)))
        counts = np.full(len(self.spectrum), self.spectrum_rows)
        rows, b, db = mean_peaks(self.spectrum * self.spectrum_rows, counts, lo)
        d = b * self.metres_per_bin
        keep = d < hi_m
        return rows[keep] == 0, d[keep], db[keep]

    @property
    def rival(self) -> tuple[float, float, bool] | None:
        """(distance m, level dB over the target, diffuse) of the persistent echo closest
        to or above the tracked target's level, if within RIVAL_DB of it."""
        p = self.persistent
        rel = np.where(p["in_band"], p["relative_db"], -np.inf)
        if rel.size == 0 or not np.nanmax(rel) >= -RIVAL_DB:
            return None
        i = int(np.nanargmax(rel))
        return float(p["distance_m"][i]), float(rel[i]), bool(p.get("diffuse", np.zeros(rel.size, bool))[i])

    def attrs(self) -> dict:
        """Track attributes: the rival echo (NaN when there is none) and counts."""
        rival = self.rival or (float("nan"), float("nan"), False)
        return {"echoes_detected": int(self.time_s.size),
                "echoes_persistent_slices": int(self.persistent["time_s"].size),
                "rival_echo_m": rival[0], "rival_echo_db": rival[1], "rival_echo_diffuse": rival[2],
                "echo_rival_limit_db": RIVAL_DB}


def is_tracked(distance_m, tracked_m):
    """Whether echoes at `distance_m` are the tracked peaks at `tracked_m` (the same bin)."""
    return np.abs(distance_m - tracked_m) < TRACKED_M


def table(t_sweep: np.ndarray, rising: np.ndarray, tracked_m: np.ndarray, level_db: np.ndarray,
          det: Detections, metres_per_bin: float, max_range_m: float = np.inf,
          survey: dict | None = None, spectrum: tuple[np.ndarray, int] | None = None) -> Echoes:
    """The detections of half-sweeps (times t_sweep, directions, tracked plain distances
    and de-chirped SNRs) as a flat table, with the persistent echoes (sharp, and diffuse
    from the `survey` of `hidden`: time_s, ratio, distance_m, found) and the surveyed
    half-sweeps' plain power summed per direction over the capture, with the half-sweeps
    of a direction summed (`spectrum`)."""
    rows, slots = ragged(np.zeros(det.count.size, np.int64), np.minimum(det.count, det.bin.shape[1]))
    dist = det.bin[rows, slots] * metres_per_bin
    tracked = is_tracked(dist, tracked_m[rows])
    order = np.argsort(t_sweep[rows], kind="stable")
    rows, dist, tracked = rows[order], dist[order], tracked[order]
    snr = det.snr_db[rows, slots[order]]
    pers = persistent(t_sweep, level_db, t_sweep[rows], dist, snr, tracked, survey)
    pers["in_band"] = pers["distance_m"] < max_range_m
    means = no_means() if survey is None else {k: np.asarray(survey[k]) for k in MEAN_KEYS}
    total, count = spectrum if spectrum is not None and spectrum[1] else (np.zeros((2, 0)), 0)
    fast = bank.no_points() if survey is None else {k: np.asarray(survey[k]) for k in bank.POINT_KEYS}
    return Echoes(t_sweep[rows], dist, snr.astype(np.float32), rising[rows], tracked, pers, means,
                  total / max(count, 1), count, metres_per_bin, fast)


def no_means() -> dict:
    """`Echoes.means` without a mean spectrum."""
    return {k: np.zeros(0, bool if k.endswith("rising") else np.float64) for k in MEAN_KEYS}


def block_sums(plain: np.ndarray, rows: int = MEAN_ROWS) -> np.ndarray:
    """(ceil(R / rows), nfft/2) sums of `rows` consecutive rows of the (R, nfft/2) power
    spectra `plain` (the last block shorter). Twin: kernels/survey.cl `block_sums`."""
    starts = np.arange(0, plain.shape[0], rows)
    if starts.size == 0:
        return np.zeros((0, plain.shape[1]))
    return np.add.reduceat(np.asarray(plain, np.float64), starts, axis=0)


def block_rows(count: int, rows: int = MEAN_ROWS) -> np.ndarray:
    """The rows of each block of `block_sums` of `count` rows."""
    return np.minimum(rows, count - np.arange(0, count, rows))


def mean_peaks(sums: np.ndarray, counts: np.ndarray, lo: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The echoes of mean power spectra: (block, fractional bin, power over the noise in
    dB) of each.

    Parameters
    ----------
    sums : (B, nfft/2) sums of `counts` (B,) power spectra each (`block_sums`).
    lo : first bin of the search band.

    A bin is an echo where it is the largest of its +-cfar.GUARD bins and stands over the
    noise of both sides' cfar.TRAIN training bins (the greater of the two means: a slope,
    such as the intensity ramp's skirt above `lo`, is no echo) by the factor that white
    noise exceeds with probability cfar.PFA: the ratio of a mean of K exponential bins to
    a training mean of K TRAIN / 2 independent ones is F(2K, K TRAIN) distributed. Only
    bins whose training cells lie inside [lo, nfft/2) are tested.
    """
    b, half = sums.shape
    reach = cfar.GUARD + cfar.TRAIN
    k0, k1 = lo + reach, half - reach
    if b == 0 or k1 <= k0:
        return np.zeros(0, np.int64), np.zeros(0), np.zeros(0)
    mean = sums / np.maximum(counts, 1)[:, None]
    c = np.zeros((b, half + 1))
    np.cumsum(mean, axis=1, out=c[:, 1:])
    left = cfar.window_sums(c, k0, k1, -reach, -cfar.GUARD) / cfar.TRAIN
    right = cfar.window_sums(c, k0, k1, cfar.GUARD + 1, reach + 1) / cfar.TRAIN
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = mean[:, k0:k1] / np.maximum(left, right)
    limit = MEAN_LIMITS[np.clip(counts, 1, MEAN_ROWS) - 1]
    rows, cols = np.nonzero(ratio > limit[:, None])
    peak = cfar.is_peak(mean, rows, cols + k0)
    rows, cols = rows[peak], cols[peak]
    return rows, interpolate(mean, rows, cols + k0), 10 * np.log10(ratio[rows, cols])


def masked_peaks(mean: np.ndarray, rows: int, lo: int) -> tuple[np.ndarray, np.ndarray]:
    """The echoes of a mean power spectrum that stand beside a louder one: (fractional
    bin, power over the noise in dB) of each.

    Parameters
    ----------
    mean : (nfft/2,) mean of `rows` power spectra.
    lo : first bin of the search band.

    `mean_peaks` wants an echo to be the largest of its +-cfar.GUARD bins and to stand
    over the louder side's training bins: beside a louder echo neither holds (a target 10
    padded bins, five resolution cells, beyond a wall and 5 dB under it, 25 dB over the
    noise, has the wall's main lobe within its +-8 bins and the wall's power in its
    training bins). Here a bin is such an echo where it is the largest of its +-LOBE_BINS
    (outside the Hann main lobe of any louder echo: the lobes beyond it fall away
    steadily), a louder echo of `mean_peaks` lies within cfar.GUARD + cfar.TRAIN of it
    beyond those, it stands over the quieter side's training bins by `mean_peaks`'
    factor for `rows` spectra (at most MEAN_ROWS), and it is no echo of `mean_peaks`.
    """
    half = mean.size
    reach = cfar.GUARD + cfar.TRAIN
    k = np.arange(lo + reach, half - reach)
    if rows == 0 or k.size == 0:
        return np.zeros(0), np.zeros(0)
    c = np.concatenate([[0.0], np.cumsum(mean)])
    left = (c[k - cfar.GUARD] - c[k - reach]) / cfar.TRAIN
    right = (c[k + reach + 1] - c[k + cfar.GUARD + 1]) / cfar.TRAIN
    p = mean[k]
    near = np.ones(k.size, bool)                     # the largest of its +-LOBE_BINS
    for d in range(1, LOBE_BINS + 1):
        near &= (p > mean[k - d]) & (p >= mean[k + d])
    limit = MEAN_LIMITS[min(rows, MEAN_ROWS) - 1]
    rows0 = np.zeros(k.size, np.int64)
    listed = cfar.is_peak(mean[None, :], rows0, k) & (p > limit * np.maximum(left, right))
    # the louder echo: one `mean_peaks` lists, LOBE_BINS + 1 .. reach bins away (a slope's
    # skirt, louder towards the band's start, is none)
    echo = np.zeros(half)
    echo[k[listed]] = p[listed]
    most = np.lib.stride_tricks.sliding_window_view(echo, reach - LOBE_BINS).max(axis=1)
    louder = np.maximum(most[k - reach], most[k + LOBE_BINS + 1]) > p
    found = near & louder & (p > limit * np.minimum(left, right)) & ~listed
    k = k[found]
    over = 10 * np.log10(mean[k] / np.minimum(left, right)[found])
    return interpolate(mean[None, :], rows0[: k.size], k), over


def persistent(t_sweep: np.ndarray, level_db: np.ndarray, t: np.ndarray, dist: np.ndarray,
               snr: np.ndarray, tracked: np.ndarray, survey: dict | None = None) -> dict:
    """Persistent echoes other than the tracked target, slice by slice (see the module),
    every slice at once; `t_sweep` and the detections' times `t` in increasing order."""
    keys = ("time_s", "distance_m", "snr_db", "share", "relative_db", "diffuse")
    if t_sweep.size == 0:
        return {k: np.zeros(0, bool if k == "diffuse" else np.float64) for k in keys}
    edges = np.arange(t_sweep.min(), t_sweep.max() + SLICE_S, SLICE_S)
    slices = edges.size

    def within(times):                          # each slice's elements of sorted `times`
        return ragged(np.searchsorted(times, edges), np.searchsorted(times, edges + SLICE_S))

    g_sweep, at_sweep = within(t_sweep)
    sweeps = np.bincount(g_sweep, minlength=slices)
    kept = sweeps >= 20
    g_det, at_det = within(t)
    mine = tracked[at_det]
    seen = np.bincount(g_det[mine], minlength=slices) >= SEEN * sweeps
    level = np.where(seen, group_median(g_det[mine], snr[at_det[mine]], slices),
                     group_median(g_sweep, level_db[at_sweep], slices))
    others = ~mine & kept[g_det]
    at = at_det[others]
    g, d, x, n = keyed_clusters(g_det[others], dist[at], snr[at], sweeps, medians=True)
    rows = [(g, d, x, n / sweeps[g], x - level[g], np.zeros(g.size, bool))]
    if survey is not None:                      # by time (chunks list their directions apart)
        order = np.argsort(survey["time_s"], kind="stable")
        g_sv, at_sv = within(np.asarray(survey["time_s"])[order])
        at_sv = order[at_sv]
        total = np.bincount(g_sv, minlength=slices)
        found = np.asarray(survey["found"], bool)[at_sv]
        g_hit, at_hit = g_sv[found], at_sv[found]
        hits = np.bincount(g_hit, minlength=slices)
        s = np.flatnonzero(kept & (total >= 4) & (hits >= PRESENT * total))
        with np.errstate(divide="ignore"):
            rel = 10 * np.log10(group_median(g_hit, np.asarray(survey["ratio"])[at_hit], slices)[s])
        # each direction's centres carry its Doppler shift, the two opposite: their mean has none
        up = np.asarray(survey["rising"], bool)[at_hit]
        d = np.asarray(survey["distance_m"])[at_hit]
        rise, fall = (group_median(g_hit[m], d[m], slices)[s] for m in (up, ~up))
        both = np.isfinite(rise) & np.isfinite(fall)
        dist = np.where(both, 0.5 * (rise + fall), group_median(g_hit, d, slices)[s])
        moving = ~both | (np.abs(fall - rise) >= AT_REST_M)
        rows.append((s, dist, level[s] + rel, hits[s] / total[s], rel, moving))
    cols = [np.concatenate(c) for c in zip(*rows, strict=True)]
    order = np.argsort(cols[0], kind="stable")  # by slice: its sharp echoes by distance, then its diffuse one
    out = dict(zip(keys, (edges[cols[0][order]] + SLICE_S / 2, *(c[order] for c in cols[1:])), strict=True))
    return {k: v.astype(bool if k == "diffuse" else np.float64) for k, v in out.items()}


def hidden(plain: np.ndarray, dechirped: np.ndarray, lo: int, tracked_bin: np.ndarray,
           plain_bin: np.ndarray, others: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Energy of surveyed half-sweeps that no sharp echo explains (see the module).

    Parameters
    ----------
    plain, dechirped : (R, nfft/2) power spectra, plain and de-chirped at the pair's
        final velocity.
    lo : first bin of the band (--min-range).
    tracked_bin, plain_bin : (R,) the tracked peak's bin in each spectrum.
    others : (R, M) bins of the other echoes (NaN: none).

    Returns
    -------
    ratio : (R,) unexplained over the tracked target's energy.
    centroid : (R,) bin of the unexplained energy's centre away from the plain peak, its
        power over the floor the weight (NaN: not found). Unclipped: the noise's clipped
        power, about a third of the floor in every bin, drew a landing's centres 0.04-0.13
        m towards the band's middle. It carries the half-sweep's Doppler shift (+0.13 m
        rising at -5 m/s), which one direction cannot tell from distance (`persistent`).
    found : (R,) the target's peak is sharp, the ratio reaches RIVAL_DB, and the energy and
        its part away from the plain peak (the centroid's weights) stand HIDDEN_SIGMAS over
        the noise.
    """
    r, half = plain.shape
    k = np.arange(lo, half)
    p = plain[:, lo:]
    floor = np.median(p, axis=1) / np.log(2)               # exponential noise: mean = median / ln 2
    excess = p - floor[:, None]
    floor_d = np.median(dechirped[:, lo:], axis=1) / np.log(2)
    off_t = np.abs(k[None, :] - np.rint(tracked_bin)[:, None])
    excess_d = dechirped[:, lo:] - floor_d[:, None]
    target = np.sum(excess_d * (off_t <= EXPLAIN_BINS), axis=1)
    sharp = np.sum(excess_d * (off_t <= 3), axis=1) >= SHARP * target
    explained = np.zeros(p.shape, bool)
    for b in others.T:
        explained |= np.abs(k[None, :] - np.rint(np.nan_to_num(b, nan=-1e9))[:, None]) <= EXPLAIN_BINS
    unexplained = np.sum(excess * ~explained, axis=1) - target
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(target != 0, unexplained / target, 0.0)
    # the noise of a sum of n correlated (2x padded) exponential bins: floor sqrt(2 n)
    noise = floor * np.sqrt(2.0 * np.sum(~explained, axis=1))
    at_target = np.abs(k[None, :] - np.rint(plain_bin)[:, None]) <= EXPLAIN_BINS
    w = excess * ~explained * ~at_target        # unclipped: the noise adds nothing on average
    away = np.sum(w, axis=1)
    found = ((target > 0) & sharp & (ratio >= 10 ** (-RIVAL_DB / 10)) & (unexplained > HIDDEN_SIGMAS * noise)
             & (away > HIDDEN_SIGMAS * noise))
    with np.errstate(divide="ignore", invalid="ignore"):
        centroid = np.where(found, np.sum(w * k[None, :], axis=1) / away, np.nan)
    return ratio, centroid, found


def _histograms(key: np.ndarray, dist: np.ndarray, groups: int):
    """Each group's distance histogram (HIST_M bins, a bin of margin at each end): the
    bins of the detections, and sums over three neighbouring bins per group (of counts,
    or of `weights`)."""
    idx = np.floor(dist / HIST_M).astype(np.int64)
    idx -= idx.min() - 1
    nb = int(idx.max() + 2)
    flat = key * nb + idx

    def windowed(weights=None) -> np.ndarray:
        h = np.bincount(flat, weights, minlength=groups * nb).reshape(groups, nb)
        return neighbour_sums(h)

    return idx, windowed


def _peaks(window: np.ndarray, sweeps: np.ndarray, present: float) -> tuple[np.ndarray, np.ndarray]:
    """(group, bin) of the local maxima of each group's three-bin counts seen in at least
    `present` of its `sweeps` half-sweeps."""
    peak = (window >= present * np.asarray(sweeps)[:, None]) & (window > 0)     # counts: >= 0
    peak[:, 1:] &= window[:, 1:] > window[:, :-1]
    peak[:, :-1] &= window[:, :-1] >= window[:, 1:]
    return np.nonzero(peak)


def keyed_clusters(key: np.ndarray, dist: np.ndarray, snr: np.ndarray, sweeps: np.ndarray,
                   present: float = PRESENT, medians: bool = False
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The distances seen in >= `present` of their group's half-sweeps, many groups at
    once: the detections of group `key` (0..K-1) among `sweeps[key]` half-sweeps; local
    maxima of the counts over three histogram bins. Returns each cluster's group, its
    distance (m) and SNR (dB) over its three bins (means, or with `medians` medians) and
    its detections, by group, then distance."""
    if dist.size == 0:
        return np.zeros(0, np.int64), np.zeros(0), np.zeros(0), np.zeros(0, np.int64)
    idx, windowed = _histograms(key, dist, sweeps.size)
    window = windowed()
    g, b = _peaks(window, sweeps, present)
    n = window[g, b]
    if not medians:
        return g, windowed(dist)[g, b] / n, windowed(snr)[g, b] / n, n
    # each detection belongs to the clusters whose peak is its bin or a neighbour (the
    # histogram's margins keep idx +- 1 inside)
    peak = np.full(window.shape, -1)
    peak[g, b] = np.arange(g.size)
    member = np.concatenate([peak[key, idx + o] for o in (-1, 0, 1)])
    at = np.tile(np.arange(dist.size), 3)[member >= 0]
    member = member[member >= 0]
    return g, group_median(member, dist[at], g.size), group_median(member, snr[at], g.size), n


def clusters(dist: np.ndarray, snr: np.ndarray, sweeps: int, present: float = PRESENT):
    """(median distance, median SNR, share) of each distance seen in >= `present` of
    `sweeps` half-sweeps (or slices): `keyed_clusters` of one group."""
    _, d, x, n = keyed_clusters(np.zeros(dist.size, np.int64), dist, snr, np.array([sweeps]), present,
                                medians=True)
    return zip(d, x, n / sweeps, strict=True)
