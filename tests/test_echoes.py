"""The echo table's persistent echoes, found for every slice at once, against a slice
by slice reference; the grouped medians they take."""

from __future__ import annotations

import numpy as np
import pytest

from fmcw_cl import echoes, rivals
from fmcw_cl.numeric import group_median, ragged
from fmcw_cl.stages import cfar


def test_group_medians_equal_numpys():
    rng = np.random.default_rng(4)
    for size, groups in ((0, 3), (1, 1), (7, 3), (500, 40), (2001, 9), (3000, 2000)):
        group = rng.integers(0, groups, size)
        if groups == 2000:
            group[: size // 2] = 7               # one large group among small ones: no padded table
        x = rng.normal(size=size).round(1)                    # ties
        if size > 10:
            x[:3] = (np.nan, np.inf, -np.inf)
        want = [np.median(x[group == g]) if np.any(group == g) else np.nan for g in range(groups)]
        np.testing.assert_array_equal(group_median(group, x, groups), want)
    which, index = ragged(np.array([3, 0, 5, 9]), np.array([6, 0, 7, 8]))
    np.testing.assert_array_equal(which, [0, 0, 0, 2, 2])
    np.testing.assert_array_equal(index, [3, 4, 5, 5, 6])


def reference(t_sweep, level_db, t, dist, snr, tracked, survey=None) -> dict:
    """The persistent echoes as the module says, one slice at a time."""
    keys = ("time_s", "distance_m", "snr_db", "share", "relative_db", "diffuse")
    out = {k: [] for k in keys}
    snr = snr.astype(np.float64)                    # medians of float32 SNRs in double
    if t_sweep.size == 0:
        return {k: np.asarray(v, bool if k == "diffuse" else np.float64) for k, v in out.items()}
    for a in np.arange(t_sweep.min(), t_sweep.max() + echoes.SLICE_S, echoes.SLICE_S):
        s = (t_sweep >= a) & (t_sweep < a + echoes.SLICE_S)
        d = (t >= a) & (t < a + echoes.SLICE_S)
        sweeps = s.sum()
        if sweeps < 20:
            continue
        mine = d & tracked
        level = np.median(snr[mine] if mine.sum() >= echoes.SEEN * sweeps else level_db[s])
        rows = []
        others = d & ~tracked
        if others.any():
            b = np.floor(dist[others] / echoes.HIST_M).astype(np.int64)
            bins = np.arange(b.min() - 1, b.max() + 2)
            count = np.array([np.sum(np.abs(b - k) <= 1) for k in bins])
            for i, k in enumerate(bins):
                left = count[i - 1] if i else -1
                right = count[i + 1] if i + 1 < bins.size else -1
                peak = count[i] > max(left, 0) and count[i] >= right
                if peak and count[i] >= echoes.PRESENT * sweeps:
                    near = np.abs(b - k) <= 1
                    x = np.median(snr[others][near])
                    rows.append((np.median(dist[others][near]), x, near.sum() / sweeps, x - level, False))
        if survey is not None:
            v = (survey["time_s"] >= a) & (survey["time_s"] < a + echoes.SLICE_S)
            hit = v & survey["found"]
            up, down = hit & survey["rising"], hit & ~survey["rising"]
            if v.sum() >= 4 and hit.sum() >= echoes.PRESENT * v.sum():
                rel = 10 * np.log10(np.median(survey["ratio"][hit]))
                share = hit.sum() / v.sum()
                d = survey["distance_m"]
                if up.any() and down.any():
                    split = abs(np.median(d[down]) - np.median(d[up]))
                    rows.append((0.5 * (np.median(d[up]) + np.median(d[down])), level + rel, share, rel,
                                 split >= echoes.AT_REST_M))
                else:
                    rows.append((np.median(d[hit]), level + rel, share, rel, True))
        for row in rows:
            for k, x in zip(keys, (a + echoes.SLICE_S / 2, *row), strict=True):
                out[k].append(x)
    return {k: np.asarray(v, bool if k == "diffuse" else np.float64) for k, v in out.items()}


@pytest.mark.parametrize("seed", range(12))
def test_persistent_echoes_of_all_slices_equal_slice_by_slice(seed):
    """Walls two histogram bins apart (a detection in two clusters), slices without
    half-sweeps, NaN levels, a target seen or not, and a survey out of time order."""
    rng = np.random.default_rng(seed)
    m = int(rng.integers(0, 2500))
    ts = np.sort(rng.uniform(0, rng.uniform(0.001, 0.06), m))
    if seed % 3 == 0:
        ts = np.r_[ts[: m // 3], ts[m // 3:] + 0.03]
    level = rng.normal(20, 5, m)
    if seed % 4 == 0 and m:
        level[rng.integers(0, m, 3)] = np.nan
    t = np.repeat(ts, rng.integers(0, 4, m))
    walls = rng.choice([0.1, 0.2, 0.3001, 0.3041, 0.3081], int(rng.integers(1, 4)), replace=False)
    dist = rng.choice(walls, t.size) + rng.normal(0, rng.uniform(2e-4, 2e-3), t.size)
    snr = rng.normal(15, 3, t.size).astype(np.float32)
    tracked = rng.random(t.size) < rng.uniform(0, 0.6)
    survey = None
    if seed % 2:
        k = m // 6
        survey = {"time_s": rng.permutation(rng.choice(ts, k)) if m else np.zeros(0),
                  "rising": rng.random(k) < 0.5 if seed % 4 == 1 else np.arange(k) < 3,
                  "ratio": rng.uniform(0.05, 3, k), "distance_m": rng.uniform(0, 0.4, k),
                  "found": rng.random(k) < rng.uniform(0, 1)}
    got = echoes.persistent(ts, level, t, dist, snr, tracked, survey)
    want = reference(ts, level, t, dist, snr, tracked, survey)
    assert got.keys() == want.keys()
    for k in got:
        np.testing.assert_allclose(got[k], want[k], rtol=1e-12, err_msg=k)
        assert got[k].dtype == want[k].dtype


def test_unexplained_energy_is_placed_by_both_directions():
    """A landing at -5 m/s beside a wall: its unexplained energy centres 0.13 m beyond it
    rising and short of it falling (Doppler); their mean is its distance. Centres that
    agree have no Doppler shift: an echo at rest the CFAR missed (a wall 10 mm before a
    target at rest), not smeared. One direction alone (the other below the band: a
    take-off's rising centres) places it at its own centres."""
    t_sweep = np.arange(400) * 25e-6                # one slice of 10 ms
    level = np.full(t_sweep.size, 20.0)
    none = np.zeros(0)

    def listed(rise_m, fall_m):
        times = t_sweep[::16]
        rows = times.size
        survey = {"time_s": np.r_[times, times + 12.5e-6], "rising": np.repeat([True, False], rows),
                  "ratio": np.full(2 * rows, 2.0), "found": np.ones(2 * rows, bool),
                  "distance_m": np.r_[np.full(rows, rise_m), np.full(rows, fall_m)]}
        if fall_m is None:
            survey["found"][rows:] = False
            survey["distance_m"][rows:] = np.nan
        p = echoes.persistent(t_sweep, level, none, none, none.astype(np.float32), none.astype(bool), survey)
        return p["distance_m"], p["diffuse"]

    d, diffuse = listed(0.29, 0.03)
    assert np.allclose(d, [0.16]) and diffuse.tolist() == [True]
    d, diffuse = listed(0.107, 0.109)
    assert np.allclose(d, [0.108]) and diffuse.tolist() == [False]
    d, diffuse = listed(0.29, None)
    assert np.allclose(d, [0.29]) and diffuse.tolist() == [True]


def test_mean_spectra_find_a_weak_echo_and_no_false_one():
    """echoes.mean_peaks on the mean of K exponential noise spectra: a steady echo 6 dB
    over the noise, rarely the peak of a single spectrum, is found in every block at its
    bin; pure noise and the skirt of a slope above the band's start give none (the F
    threshold at cfar.PFA: over 4000 blocks of 1000 bins, none expected)."""
    rng = np.random.default_rng(7)
    half, lo, k = 1024, 40, 12
    blocks = 4000
    noise = rng.exponential(1.0, (blocks, k, half))
    b, _, _ = echoes.mean_peaks(noise.sum(axis=1), np.full(blocks, k), lo)
    assert b.size == 0
    slope = noise[:40] * (1 + 30 * np.exp(-(np.arange(half) - lo) / 15.0))     # a ramp's skirt
    assert echoes.mean_peaks(slope.sum(axis=1), np.full(40, k), lo)[0].size == 0
    tone = noise[:200].copy()
    tone[:, :, 500] += 4.0                                            # 10 log10(4) = 6 dB
    single = tone.reshape(-1, half)[:, lo:].argmax(axis=1) + lo
    assert np.mean(single == 500) < 0.1
    sums = echoes.block_sums(tone.reshape(-1, half), k)
    b, at, snr = echoes.mean_peaks(sums, echoes.block_rows(200 * k, k), lo)
    assert np.array_equal(b, np.arange(200)) and np.all(np.abs(at - 500) <= 0.5)
    assert 6.0 < np.median(snr) < 7.5                                 # (1 + 4) / 1 over the noise: 7 dB


def test_the_mean_spectras_thresholds_are_the_f_distributions():
    from scipy import stats

    k = np.arange(1, echoes.MEAN_ROWS + 1)
    np.testing.assert_allclose(echoes.MEAN_LIMITS, stats.f.isf(cfar.PFA, 2 * k, k * cfar.TRAIN), rtol=1e-4)


def test_block_sums_and_their_rows():
    x = np.arange(5 * 3, dtype=float).reshape(5, 3)
    np.testing.assert_array_equal(echoes.block_sums(x, 2), [x[0] + x[1], x[2] + x[3], x[4]])
    np.testing.assert_array_equal(echoes.block_rows(5, 2), [2, 2, 1])
    assert echoes.block_sums(np.zeros((0, 3)), 2).shape == (0, 3) and echoes.block_rows(0, 2).size == 0


def hann_tone(half: int, at: float, points: int = 1000) -> np.ndarray:
    """The power spectrum (nfft = 2 half bins) of a Hann-windowed tone at padded bin `at`,
    peak 1: the shape of an echo in the plain spectra."""
    j = np.arange(points)
    win = 0.5 - 0.5 * np.cos(2 * np.pi * (j + 0.5) / points)
    p = np.abs(np.fft.rfft(win * np.cos(2 * np.pi * at * j / (2 * half)), 2 * half)[:half]) ** 2
    return p / p.max()


def test_masked_peaks_find_an_echo_beside_a_louder_one_and_no_false_one():
    """A capture's mean spectrum (600 half-sweeps) of a wall 30 dB over the noise and a
    target 10 padded bins beyond it, 5 dB under: `mean_peaks` finds the wall alone (the
    target is under the wall's main lobe within its +-8 bins and under its power in the
    training bins), `masked_peaks` the target. Neither the wall's own lobes, alone or 50
    dB over the noise, nor pure noise (4000 spectra of 12 rows), nor a slope's skirt
    give one."""
    rng = np.random.default_rng(11)
    half, lo, rows = 1024, 40, 600
    noise = rng.gamma(rows, 1.0 / rows, (3, half))                  # means of 600 exponential bins
    wall, target = 1e3 * hann_tone(half, 389.0), 1e3 * 10 ** -0.5 * hann_tone(half, 399.3)
    both = noise[0] + wall + target
    _, b, _ = echoes.mean_peaks(both[None, :], np.array([rows]), lo)
    assert np.allclose(b, [389.0], atol=0.5)
    at, over = echoes.masked_peaks(both, rows, lo)
    assert np.allclose(at, [399.3], atol=0.5) and 20 < over[0] < 26
    for alone in (noise[1] + wall, noise[2] + 100 * wall):
        assert echoes.masked_peaks(alone, rows, lo)[0].size == 0
    k = 12
    spectra = rng.exponential(1.0, (4000, k, half)).mean(axis=1)
    assert sum(echoes.masked_peaks(m, k, lo)[0].size for m in spectra) == 0
    slope = spectra[:40] * (1 + 30 * np.exp(-(np.arange(half) - lo) / 15.0))
    assert sum(echoes.masked_peaks(m, k, lo)[0].size for m in slope) == 0


def test_the_capture_mean_spectra_tests_of_one_echo():
    """target's tests of a lone fixed echo on the capture's mean spectra (200 half-sweeps
    a direction, the echo 30 dB over the noise at 0.188 m): its two directions 6 padded
    bins (2.8 mm) apart are a split (`_split`), 1 bin apart none; a weak peak far off is
    another echo (`_besides`), in one direction only too, but not where some pairs are
    clipped (a clipped stretch's distortion, 7 dB over the noise), and at twice the
    distance 25 dB under (a harmonic) none."""

    rng = np.random.default_rng(5)
    half, rows, mpb = 1024, 200, 0.47e-3
    band = (0.03, None)

    def table(rise, fall):
        spectrum = rng.gamma(rows, 1.0 / rows, (2, half)) + np.array([rise, fall])
        none = np.zeros(0)
        return echoes.Echoes(none, none, none, none.astype(bool), none.astype(bool), {},
                             spectrum=spectrum, spectrum_rows=rows, metres_per_bin=mpb)

    echo = 1e3 * hann_tone(half, 400.0)
    fixed_m = 400 * mpb
    moved = 1e3 * hann_tone(half, 406.0)
    r, f = rivals.directions_apart(table(echo, moved), fixed_m, band)
    assert abs(r - fixed_m) < 1e-4 and abs(f - 406 * mpb) < 1e-4
    assert rivals.directions_apart(table(echo, 1e3 * hann_tone(half, 401.0)), fixed_m, band) is None
    weak = 4.0 * hann_tone(half, 700.0)                             # 7 dB over the noise's mean
    got = rivals.besides(table(echo + weak, echo + weak), fixed_m, band, 0.47)
    assert len(got) == 1 and abs(got[0] - 700 * mpb) < 2e-4
    one = table(echo + weak, echo)                                  # in one direction only
    assert len(rivals.besides(one, fixed_m, band, 0.47)) == 1
    assert rivals.besides(one, fixed_m, band, 0.47, clipped=True) == []
    harmonic = 10 ** -2.5 * 1e3 * hann_tone(half, 800.0)
    assert rivals.besides(table(echo + harmonic, echo + harmonic), fixed_m, band, 0.47) == []


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_own_peaks_of_all_mean_spectra_equal_peak_by_peak(seed):
    """fixed_echoes._own_peaks (each peak's stretch of the target's images, all peaks at
    once) equals the test made peak by peak over every image, on detections and peaks
    of both directions, near and far from each other in time and distance."""
    from fmcw_cl import fixed_echoes

    rng = np.random.default_rng(seed)
    n = 3000
    period = 50e-6
    t = np.sort(rng.integers(0, 4000, n)) * period * 0.5
    e = echoes.Echoes(time_s=t, distance_m=0.2 + 0.01 * rng.standard_normal(n), snr_db=np.zeros(n),
                      rising=rng.random(n) < 0.5, tracked=np.ones(n, bool), persistent={},
                      means={"peak_time_s": rng.uniform(-0.01, 0.11, 400),
                             "peak_rising": rng.random(400) < 0.5,
                             "peak_distance_m": 0.2 + 0.004 * rng.standard_normal(400)})
    mine = rng.random(n) < 0.8
    half = 0.5 * echoes.MEAN_ROWS * echoes.SURVEY_STRIDE * period
    m = e.means
    want = np.zeros(400, bool)
    for i in range(400):
        sel = mine & (e.rising == m["peak_rising"][i]) & (np.abs(t - m["peak_time_s"][i]) <= half)
        want[i] = bool(sel.any()) and (np.mean(np.abs(e.distance_m[sel] - m["peak_distance_m"][i])
                                               <= 1.5 * echoes.HIST_M) >= echoes.PRESENT)
    got = fixed_echoes._own_peaks(e, mine, period)
    assert 0 < want.sum() < want.size
    assert got.tolist() == want.tolist()
