"""Stage 5d: incoherent integration of K half-sweeps of a direction along the track.

A weak echo's single power spectrum is a noise lottery: at about -13 dB per sample
its peak no longer stands SNR_MIN_DB over the floor in every half-sweep. Summing the
(de-chirped) power spectra of K consecutive half-sweeps of one direction keeps the
echo's mean power and shrinks the noise's scatter by sqrt(K), so its peak is found
again, at a time resolution of K periods. The target moves meanwhile: each
neighbour's spectrum is read displaced by what the tracked velocity says the target
moved between the two pairs (linear interpolation between bins, which moves a peak's
centroid by exactly the displacement), so the sum stays sharp at the pair's own
distance.

The sum of K exponential noise bins is a Gamma(K) variable: the SNR threshold of an
integrated peak keeps the single spectrum's false-alarm probability per bin,
exp(-10^(SNR_MIN_DB / 10)), and falls from 10 dB at K = 1 to 6.3 dB at K = 4 and
3.6 dB at K = 16.

With K chosen automatically (`choose`), a chunk is integrated only when fewer than
AUTO_SHARE of its single pairs are heard; the per-sweep SNR is then measured on a
K = PROBE integration (peak over floor of the mean spectrum is 1 + SNR) and K is the
smallest that detects such a peak with probability PD in each direction.
"""

from __future__ import annotations

import numpy as np

from .spectrum import Search, find_peaks

MAX_K = 32          # half-sweeps of a direction summed at most (1.6 ms at 20 kHz)
PROBE = 16          # the integration that measures a weak chunk's SNR
AUTO_SHARE = 0.95   # auto: a chunk is integrated when fewer of its single pairs are heard
PD = 0.995          # auto: detection probability of each direction's integrated peak
BLOCK_ROWS = 32     # rows `integrate` aligns at once: its temporaries stay in cache (2048 bins:
                    # 512 KB each), 2.4-4x faster than all rows at once (1200 rows)


def window(k: int) -> tuple[int, int]:
    """Pairs (before, after) pair i that its K-window holds: i - before .. i + after."""
    return k // 2, k - 1 - k // 2


def false_alarm(snr_min_db: float) -> float:
    """Probability that one bin of pure noise (exponential power) exceeds snr_min_db."""
    return float(np.exp(-(10 ** (snr_min_db / 10))))


# threshold_db of 1 .. MAX_K spectra at the tracker's 10 dB (pairing.SNR_MIN_DB), scipy's
# within a few units of the last place: a conversion imports no scipy (tests/test_integrate.py)
TABLE_SNR_DB = 10.0
THRESHOLDS_DB = np.array([
    10.0, 7.997150061955899, 6.941756164111155, 6.2497191720464045, 5.74636655437454,
    5.356977529652508, 5.043098103578009, 4.782505946921427, 4.5612850886379706, 4.370189607672586,
    4.202789907269483, 4.054449845218025, 3.9217262543304567, 3.8019983901303993, 3.6932296642084097,
    3.5938090566854326, 3.5024424117559363, 3.4180760111586106, 3.3398416393275676, 3.267016320479192,
    3.1989922951669483, 3.1352542843163493, 3.0753620315617147, 3.0189367294985763, 2.965650344981126,
    2.9152171366662802, 2.867386850148548, 2.821939210927596, 2.7786794315492873, 2.737434518645273,
    2.698050216315639, 2.6603884598028675])


def threshold_db(count: np.ndarray | int, snr_min_db: float) -> np.ndarray:
    """SNR threshold (dB) of a peak integrated over `count` spectra with the false-alarm
    probability per bin that snr_min_db has for one spectrum."""
    n = np.asarray(count, np.float64)
    if snr_min_db == TABLE_SNR_DB and np.all((n >= 1) & (n <= MAX_K) & (n == np.round(n))):
        return THRESHOLDS_DB[n.astype(np.int64) - 1]
    from scipy.special import gammainccinv  # imported where used: the command line starts fast

    return 10 * np.log10(gammainccinv(n, false_alarm(snr_min_db)) / n)


def detection(k, snr: float, snr_min_db: float) -> np.ndarray:
    """Probability that a peak of per-sweep SNR `snr` (linear: peak power over the mean
    noise power of a bin) integrated over k spectra (whole numbers, an array of them or
    one) stands above `threshold_db`: the integrated power is non-central chi-square
    with 2K degrees of freedom and non-centrality 2 K snr (`chi2_sf`)."""
    k = np.asarray(k, np.float64)
    t = 10 ** (threshold_db(k, snr_min_db) / 10)
    return chi2_sf(2 * k * t, k, k * snr)


def chi2_sf(x, n, mu) -> np.ndarray:
    """P(X > x) for X non-central chi-square with 2n degrees of freedom (n whole) and
    non-centrality 2 mu (scipy.stats.ncx2.sf(x, 2n, 2 mu), in numpy: a conversion
    imports no scipy module): the Poisson(mu) mixture of central ones, each the chance
    that a Poisson(x / 2) count stays under n + j. Within 1e-13 of scipy's where it is
    under 0.9999 (near 1, sums of rounded weights: 1e-10)."""
    x, n, mu = (np.atleast_1d(np.asarray(a, np.float64)) for a in (x, n, mu))
    y = x / 2
    terms = int(np.max(mu + 12 * np.sqrt(mu))) + 40           # of the mixture: the weights beyond, < 1e-30
    top = int(np.max(n)) + terms
    log_fact = np.concatenate([[0.0], np.cumsum(np.log(np.arange(1, top + 1)))])

    def poisson(mean: np.ndarray, count: int) -> np.ndarray:    # (means, count): P(N = i), i < count
        i = np.arange(count)
        with np.errstate(divide="ignore", invalid="ignore"):
            p = np.exp(i * np.log(mean)[:, None] - mean[:, None] - log_fact[:count])
        p[mean == 0] = i == 0
        return p

    under = np.cumsum(poisson(y, top), axis=1)                   # P(Poisson(y) <= i)
    at = (n[:, None] + np.arange(terms) - 1).astype(np.int64)
    return np.sum(poisson(mu, terms) * np.take_along_axis(under, at, axis=1), axis=1)


def choose(snr: float, snr_min_db: float) -> int:
    """The smallest K <= MAX_K that detects a per-sweep SNR `snr` (linear) with
    probability PD (MAX_K when none does)."""
    if detection(1, snr, snr_min_db)[0] >= PD:        # strong: no K of the costly mixtures
        return 1
    k = np.arange(2, MAX_K + 1)
    found = np.flatnonzero(detection(k, snr, snr_min_db) >= PD)
    return int(k[found[0]]) if found.size else MAX_K


def integrate(power: np.ndarray, disp: np.ndarray, k: int, bounds: np.ndarray | None = None,
              columns: tuple[int, int] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Mean of the K-window of power spectra around each row, aligned.

    Parameters
    ----------
    power : (P, B) power spectra of consecutive half-sweeps of one direction.
    disp : (P,) target displacement of each row (bins of those spectra): row j is read
        at bin b + disp[j] - disp[i] for bin b of row i (linear interpolation, the
        ends held).
    k : half-sweeps per window (`window`); windows are cut at the array's ends.
    bounds : (2 P,) int, optional: the first row of each row's group, then the last of
        each (pairing.Times.bounds); windows are cut at their group's ends too.
    columns : (first, end), optional: only bins first .. end - 1 of the integrated
        spectra are made (`peaks`: the band searched and its neighbours).

    Returns
    -------
    (P, B) integrated spectra (P, end - first with `columns`) and (P,) the count of
    spectra in each.
    """
    rows, bins = power.shape
    first_bin, end_bin = (0, bins) if columns is None else columns
    width = end_bin - first_bin
    before, after = window(k)
    first, last = (np.zeros(rows, np.int64), np.full(rows, rows - 1)) if bounds is None else \
        (bounds[:rows], bounds[rows:])
    # a row read at b + d is its row shifted by floor(d) bins and interpolated by the
    # rest: the rows padded with their end values need no clipping, and each shifted
    # row is one contiguous window of its padded row (no per-bin index arithmetic)
    finite = bool(np.isfinite(disp).all())
    spread = float(np.max(disp) - np.min(disp)) if finite and rows else float(bins)
    pad = min(int(np.ceil(spread)) + 1, bins)
    padded = np.pad(power, ((0, 0), (pad, pad + 1)), mode="edge")
    shifted = np.lib.stride_tricks.sliding_window_view(padded, width + 1, axis=1)
    acc = np.empty((rows, width))
    count = np.zeros(rows, np.int32)
    with np.errstate(invalid="ignore"):                    # a displacement not finite
        for a in range(0, rows, BLOCK_ROWS):
            ii = np.arange(a, min(a + BLOCK_ROWS, rows))
            block = np.zeros((ii.size, width))
            for m in range(-before, after + 1):
                jj = ii + m
                ok = (jj >= first[ii]) & (jj <= last[ii])
                if not ok.any():
                    continue
                i_ok, j_ok = ii[ok], jj[ok]
                d = np.asarray(disp[j_ok] - disp[i_ok], np.float64)
                whole = np.floor(d)
                frac = d - whole
                if not finite:                          # read as the first bin (pad = bins)
                    lost = ~np.isfinite(d)
                    frac[lost], whole[lost] = 0.0, -pad
                start = np.clip(whole, -pad, pad).astype(np.int64) + (pad + first_bin)
                frac = frac[:, None]
                rows_read = shifted[j_ok, start]                              # (n, width + 1)
                left = rows_read[:, :-1]
                step = np.subtract(rows_read[:, 1:], left, dtype=np.float64)
                step *= frac
                step += left
                if ok.all():
                    block += step
                else:
                    block[ok] += step
                count[i_ok] += 1
            acc[ii] = block
    return acc / count[:, None], count


def peaks(power: np.ndarray, disp: np.ndarray, k: int, search: Search, bounds: np.ndarray | None = None,
          direction: int = 0) -> tuple:
    """(bin, SNR dB, count) of the tracked peak of each row's integrated spectrum
    (`integrate`; `bounds`: windows cut at each row's group's ends), in `direction`'s
    bands (0: rising, 1: falling) where the search has them."""
    # the band and a bin either side (the peak's parabola) are all find_peaks reads
    first, end = max(search.lo - 1, 0), min(search.hi + 1, power.shape[1])
    spec, count = integrate(power, disp, k, bounds, (first, end))
    lo, hi = search.band(direction)
    pk = find_peaks(spec, lo - first, hi - first)
    return pk.bin + first, pk.snr_db, count
