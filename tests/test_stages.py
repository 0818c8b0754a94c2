"""Each numpy stage on synthetic data with a known answer."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from fmcw_cl.physics import C
from fmcw_cl.simulator import paper_dfb
from fmcw_cl.stages import delay, doppler, kinematics, lpf, pairing, resample, spectrum, sync, verification
from fmcw_cl.stages.lut import build_lut
from fmcw_cl.stages.spectrum import Search

HP = 2500.0  # half-period, samples


def triangle(n, half, t0, amp=3000.0, noise=0.0, seed=0):
    """Triangle with a minimum at sample t0 (+ k * 2 half), values in [-amp/2, amp/2]."""
    p = ((np.arange(n) - t0) / (2 * half)) % 1.0
    tri = np.where(p < 0.5, 2 * p, 2 - 2 * p)
    return amp * (tri - 0.5) + np.random.default_rng(seed).normal(0, noise, n)


def test_cic_rejects_beats_near_multiples_of_the_decimated_rate():
    fs = 100e6
    t = np.arange(400_000) / fs
    for f in (3.9e6, 4.1e6, 8.05e6):
        y, _, _ = lpf.intensity(1000 * np.cos(2 * np.pi * f * t), fs)
        assert np.abs(y[100:-100]).max() < 1.0   # > 60 dB down
    y, t0, step = lpf.intensity(np.full(10_000, 7.0), fs)
    assert y[50:-50] == pytest.approx(7.0)
    assert (t0, step) == (36.0, 25.0)


def test_turning_points_sub_sample_and_split_on_dropped_samples():
    x = triangle(200_000, HP, t0=1234.56, noise=4.0)
    tp = sync.sync_turning_points(np.rint(x), HP)
    assert tp.segment.max() == 0
    expect = 1234.56 + HP * np.round((tp.time - 1234.56) / HP)
    assert np.abs(tp.time - expect).max() < 0.05
    assert np.all(tp.is_max == (np.round((tp.time - 1234.56) / HP) % 2 == 1))
    dropped = np.delete(x, np.arange(100_000, 100_003))   # 3 samples lost
    tp = sync.sync_turning_points(np.rint(dropped), HP)
    assert tp.segment.max() == 1


def test_turning_points_where_the_level_or_the_period_is_off():
    """Turning points are midpoints of two crossings, whatever the crossing level: a level
    2 % of the swing off the middle (spacings alternating +-4 %) and a period 2.5 % off
    the nominal still give every one (the spacing test allowed 2 %), on four seeds."""
    for seed in range(4):
        x = np.rint(triangle(200_000, HP * 1.025, t0=1234.56, noise=4.0, seed=seed))
        tp = sync.sync_turning_points(x, HP)
        expect = 1234.56 + HP * 1.025 * np.round((tp.time - 1234.56) / (HP * 1.025))
        assert tp.segment.max() == 0 and tp.time.size == 76
        assert np.abs(tp.time - expect).max() < 0.08

        def off(codes, half):                   # the crossings timed at a level 60 codes up
            f = sync.fitted(codes, half)
            return sync.Fitted(f.centre, f.s0, f.s1, f.direction, f.level + 60.0)

        x = np.rint(triangle(200_000, HP, t0=1234.56, noise=4.0, seed=seed))
        assert np.ptp(np.diff(sync.crossings(x, HP, off).time)) > 0.075 * HP
        tp = sync.sync_turning_points(x, HP, off)
        assert tp.segment.max() == 0 and tp.time.size == 78
        assert np.abs(tp.time - 1234.56 - HP * np.round((tp.time - 1234.56) / HP)).max() < 0.08


def test_the_level_of_a_chunk_whose_sampled_blocks_hold_few_phases():
    """A clean 256 ms chunk whose level's sampled blocks (every 100th of 62 samples: 1.24
    periods apart) hold 25 of a period's phases: the level is 1.8 % of the swing off the
    middle, and every turning point is still found (none were: "no complete modulation
    period found" on a two-mover capture of benchmarks/movers.py)."""
    period = np.rint(triangle(50_000, HP, t0=1234.56, noise=4.0)).astype(np.int16)
    x = np.tile(period, 513)[:25_612_054]
    factor = sync.block_length(HP)
    sums = sync.block_sums(x, factor)
    assert sync.level_stride(sums.size) == 100
    assert abs(sync.levels(sums[::100], factor).level) > 0.015 * 3000
    tp = sync.sync_turning_points(x, HP)
    assert tp.segment.max() == 0 and tp.time.size == 10_243


def test_uniform_grid_is_the_least_squares_line():
    """The closed-form grid of a segment's turning points equals np.polyfit's line to a
    few ulps, at a chunk's offsets (samples up to 4e7) and lengths (3 to 16 384)."""
    rng = np.random.default_rng(4)
    for n, t0 in ((3, 12.5), (4, 4e7), (101, 2.1e6), (16_384, 3.3e7)):
        k = np.arange(n, dtype=np.float64)
        t = t0 + 2500.137 * k + rng.normal(0, 0.3, n)
        want = np.polyval(np.polyfit(k, t, 1), k)
        np.testing.assert_allclose(sync.uniform_grid(t), want, rtol=0, atol=8 * np.spacing(t.max()))
    # two segments split by dropped samples: each its own line
    x = triangle(200_000, HP, t0=811.2, noise=4.0)
    tp = sync.sync_turning_points(np.rint(np.delete(x, np.arange(90_000, 90_002))), HP)
    for s in range(2):
        seg = tp.time[tp.segment == s]
        assert np.ptp(np.diff(seg)) < 1e-6 and abs(np.diff(seg).mean() - HP) < 0.01


@pytest.mark.parametrize("lag,sign", [(17.3, 1.0), (-31.7, -1.0), (0.4, 1.0)])
def test_delay_from_the_intensity_triangle(lag, sign):
    n = 400_000
    sync_ch = triangle(n, HP, t0=777.0, amp=6000, noise=4, seed=1)
    optical = triangle(n, HP, t0=777.0 - lag, amp=800, noise=25, seed=2)
    lags, misfit = delay.period_delays(sign * optical, sync_ch, 100e6, HP)
    est, used, best, _ = delay.combine_delays(lags, misfit)
    assert est == pytest.approx(lag, abs=0.1)
    assert used > 0.8 * lags.size and best < delay.CLEAN_MISFIT


def test_delay_of_stretches_as_rows():
    """Stretches given as rows (one low-pass call for all) give each stretch's periods
    as if fitted alone, in turn."""
    n = 200_000
    sync_ch = np.stack([triangle(n, HP, t0=100.0 * k, amp=6000, noise=4, seed=k) for k in range(3)])
    optical = np.stack([triangle(n, HP, t0=100.0 * k - 12.5, amp=800, noise=25, seed=9 + k)
                        for k in range(3)])
    lags, misfit = delay.period_delays(optical, sync_ch, 100e6, HP)
    alone = [delay.period_delays(o, s, 100e6, HP) for o, s in zip(optical, sync_ch, strict=True)]
    assert np.array_equal(lags, np.concatenate([a[0] for a in alone]), equal_nan=True)
    assert np.array_equal(misfit, np.concatenate([a[1] for a in alone]), equal_nan=True)
    assert lags.size == 3 * alone[0][0].size > 0 and np.nanmedian(lags) == pytest.approx(12.5, abs=0.2)


@pytest.mark.parametrize("shifts", [(-3.25, 0.0, 2.5), (-40.0, 0.5, 60.0), (7.0, -7.0, 1e-9)])
def test_shifted_template_is_interp(shifts):
    """The delay fit's template moved by one shift a period equals np.interp on the
    sample grid, rows that run off either end held at the end values."""
    rng = np.random.default_rng(3)
    z = rng.normal(size=300)
    windows = np.arange(20, 260, 80)[:3, None] + np.arange(80)
    shift = np.array(shifts)
    want = np.interp(windows + shift[:, None], np.arange(z.size, dtype=float), z)
    assert np.allclose(delay._shifted(z, windows, shift), want, rtol=0, atol=1e-12)


def test_lut_uniform_frequency_and_mirror():
    laser = paper_dfb()
    cur = np.linspace(0.02, 0.5, 25)
    lut = build_lut(cur, laser.frequency(cur), 0.16, 0.48, points=1000)
    assert lut.bandwidth_hz == pytest.approx(160e9, rel=1e-6)
    np.testing.assert_allclose(lut.u_rise, 1 - lut.u_fall)
    # rising: current = 0.16 + 0.32 u; the frequency there is nu_j, uniformly spaced
    nu = laser.frequency(0.16 + 0.32 * lut.u_rise)
    np.testing.assert_allclose(nu, lut.nu_hz, atol=2e3)
    np.testing.assert_allclose(np.diff(lut.nu_hz), 160e6, rtol=1e-9)
    assert lut.unambiguous_range_m == pytest.approx(1000 * C / (4 * 160e9), rel=1e-6)


def test_resample_cubic_from_codes():
    n = 20_000
    f = 0.013  # cycles per sample
    codes = np.rint(3000 * np.sin(2 * np.pi * f * np.arange(n))).astype(np.int16)
    rng = np.random.default_rng(4)
    starts = rng.uniform(2, 10_000, 7)
    u = np.sort(rng.uniform(0, 1, 333))
    ones = np.ones(u.size)
    y = resample.resample(codes, starts, np.full(7, 2500.0), u, ones)
    p = starts[:, None] + 2500.0 * u
    exact = 3000 * np.sin(2 * np.pi * f * p)
    exact -= exact.mean(axis=1, keepdims=True)
    assert np.abs(y - exact).max() < 2.0   # rounding to codes + cubic error


@pytest.mark.parametrize("points", [1000, 2048, 777])
def test_peak_interpolation_bias_is_small(points):
    nfft = spectrum.fft_length(points)
    win = resample.window(points)
    true_bins = np.linspace(60.0, 300.0, 41) + 0.137
    j = np.arange(points)
    x = np.cos(2 * np.pi * np.outer(true_bins / nfft, j)) * win
    pk = spectrum.find_peaks(spectrum.power_spectra(x, nfft), 20)
    assert np.abs(pk.bin - true_bins).max() < 0.01   # padded bins: < 0.005 resolution cells
    assert np.all(pk.snr_db > 40)


def _synthetic_pair(lut, model, r_m, v, half_s, noise, rng):
    """Resampled rising/falling sweeps of a target moving at v (m/s), centred at R = r_m."""
    n = lut.points
    win = resample.window(n)
    out = []
    for beta, u, dt in ((model.beta_rise, lut.u_rise, -half_s / 2),
                        (model.beta_fall, lut.u_fall, half_s / 2)):
        r_c = r_m + v * dt
        phase = lut.nu_hz * 2 * r_c / C + v * beta + rng.uniform()
        x = np.cos(2 * np.pi * phase) + rng.normal(0, noise, n)
        out.append((x - x.mean()) * win)
        del u
    return out


def test_tracker_resolves_folds_and_the_paper_method_does_not():
    laser = paper_dfb()
    cur = np.linspace(0.02, 0.5, 25)
    lut = build_lut(cur, laser.frequency(cur), 0.16, 0.48, points=1000)
    half_s = 25e-6
    nfft = spectrum.fft_length(1000)
    model = doppler.doppler_model(lut, half_s, nfft, resample.window(1000))
    rng = np.random.default_rng(0)
    # 300 pairs: accelerating from 1 to 7 m/s at 0.12 m, where v K > R (fold) from ~4 m/s
    pairs = 300
    t_mid = np.arange(pairs) * 50e-6
    v = np.linspace(1.0, 7.0, pairs)
    r = 0.12 + np.cumsum(v) * 50e-6
    xr, xf = map(np.array, zip(*(_synthetic_pair(lut, model, r[i], v[i], half_s, 0.3, rng)
                                 for i in range(pairs)), strict=False))
    lo = int(0.03 / model.metres_per_bin)
    assert abs(model.k_rise) * 7.0 > 0.12   # the fold really happens
    times = pairing.Times(t_mid - half_s / 2, t_mid + half_s / 2)
    res = pairing.track_pairs(xr, xf, times, model, Search(lo, model.nfft // 2))
    assert res.valid.mean() > 0.98
    ok = res.valid
    assert np.abs(res.distance[ok] - r[ok]).max() < 0.05e-3
    assert np.abs(res.velocity[ok] - v[ok]).max() < 2e-3
    paper = pairing.track_pairs(xr, xf, times, model, Search(lo, model.nfft // 2), dechirp=False)
    assert np.percentile(np.abs(paper.distance - r), 95) > 5e-3   # centimetres off
    # pairs in groups tracked apart are each group's own tracking, nobody's neighbours
    # across a group's ends: a group of one pair, one of 11 with the target faded out
    # (no trusted pair), and groups whose velocities differ at their ends
    xr[120:131] = rng.normal(0, 0.3, (11, xr.shape[1])) * resample.window(1000)
    edges = [0, 7, 8, 120, 131, 200, pairs]
    groups = pairing.Times(times.rise, times.fall, np.array(edges[:-1]))
    search = Search(lo, model.nfft // 2)
    # integrated (k = 4), each group's windows end at its ends: a group of one pair
    # counts one half-sweep, the faded group's windows hold none of its neighbours' echoes
    for k, keys in ((1, ("dechirped_rise", "dechirped_fall")), (4, ("integrated", "dechirped_snr_rise"))):
        got = pairing.track_pairs(xr, xf, groups, model, search, integrate_k=k)
        each = [pairing.track_pairs(xr[a:b], xf[a:b], pairing.Times(times.rise[a:b], times.fall[a:b]), model,
                                    search, integrate_k=k)
                for a, b in zip(edges[:-1], edges[1:], strict=True)]
        want = pairing.PairResult.concat(each)
        for key in ("distance", "velocity", "valid", "continuous", *keys):
            np.testing.assert_array_equal(getattr(got, key), getattr(want, key), err_msg=f"{key}, k = {k}")
        alone = pairing.track_pairs(xr, xf, times, model, search, integrate_k=k)
        assert not (np.array_equal(alone.continuous, got.continuous)
                    and np.array_equal(alone.velocity, got.velocity)), k
    assert got.integrated[7] == 1 and not got.valid[120:131].any()
    assert not np.array_equal(alone.integrated, got.integrated)
    assert not np.array_equal(alone.dechirped_snr_rise, got.dechirped_snr_rise)
    with pytest.raises(ValueError, match="a given integration"):
        pairing.track_pairs(xr, xf, groups, model, search, integrate_k=None)


def test_acceleration_skips_gaps():
    period = 50e-6
    t = np.arange(200) * period
    v = 3.0 + 120.0 * t + 400.0 * t**2
    valid = np.ones(200, bool)
    valid[90:95] = False
    a = kinematics.acceleration(v, valid, period)
    assert np.all(np.isnan(a[90:95]))
    np.testing.assert_allclose(a[valid], (120.0 + 800.0 * t)[valid], rtol=1e-6)


def test_lowpass_taps_are_scipys_firwin():
    from scipy.signal import firwin

    from fmcw_cl.stages import lpf

    for fs, cut, taps in ((4e6, 200e3, 63), (4e6, 150e3, 31), (1e6, 100e3, 101)):
        np.testing.assert_allclose(lpf.lowpass_taps(fs, cut, taps), firwin(taps, cut, fs=fs), atol=1e-15)


def test_tuning_fit_states_its_own_scale_uncertainty():
    """On 600 noisy G(I) tables (20 MHz rms, an OSA's), the distance scale's error that
    the fit leaves, shape between the table's points included (the weighted slope of the
    fit's error along the LUT's instants), is within 2 stated sigma in >= 95 % of them,
    and so it is on the tables whose degree was chosen above the laser's (the covariance
    alone covered about half of those); the bandwidth alone would state less."""
    from fmcw_cl.simulator import paper_dfb
    from fmcw_cl.stages.lut import build_lut, fit_tuning
    from fmcw_cl.stages.resample import window

    laser = paper_dfb()
    x = np.linspace(0.02, 0.5, 25)
    n = 2048
    w = window(n) ** 2
    j = np.arange(n) - np.sum(w * np.arange(n)) / np.sum(w)
    stated, err, ends, degree, scatter = [], [], [], [], []
    for seed in range(600):
        y = laser.frequency(x) + np.random.default_rng(seed).normal(0, 20e6, x.size)
        lut = build_lut(x, y, 0.16, 0.48, n)
        current = 0.16 + 0.32 * lut.u_rise
        wrong = fit_tuning(x, y)(current) - laser.frequency(current)   # the fit's error at the instants
        err.append(-np.sum(w * j * wrong) / np.sum(w * j * j) * n / lut.bandwidth_hz * 1e6)
        stated.append(lut.scale_ppm)
        ends.append(1e6 * lut.bandwidth_std_hz / lut.bandwidth_hz)
        degree.append(lut.fit_degree)
        scatter.append(lut.table_scatter_hz)
    err, stated, ends, degree, scatter = map(np.asarray, (err, stated, ends, degree, scatter))
    assert degree.min() >= 2
    assert abs(np.median(scatter) / 20e6 - 1) < 0.05 and np.all(np.abs(scatter / 20e6 - 1) < 0.6)
    covered = np.abs(err) <= 2 * stated
    assert np.mean(covered) >= 0.95
    assert np.sum(degree > 2) >= 8 and np.mean(covered[degree > 2]) >= 0.75
    assert np.median(stated) > np.median(ends)
    assert np.percentile(np.abs(err), 99) < 300            # 0.21 mm at 0.7 m


def test_tuning_fit_of_a_few_points():
    """The contract allows a G(I) table of 4 points: it is fitted (a quadratic, whatever
    its scatter), and with under 3 degrees of freedom left its scale's uncertainty is
    unknown (NaN), not a number the scatter of 1 or 2 residuals could not support."""
    from fmcw_cl.simulator import paper_dfb
    from fmcw_cl.stages.lut import build_lut

    laser = paper_dfb()
    for points, known in ((4, False), (5, False), (6, True)):
        x = np.linspace(0.02, 0.5, points)
        y = laser.frequency(x) + np.random.default_rng(points).normal(0, 20e6, points)
        lut = build_lut(x, y, 0.16, 0.48, 1000)
        assert lut.fit_degree == 2
        assert np.isfinite(lut.scale_ppm) == known
        assert abs(lut.bandwidth_hz - 160e9) < 2e9


def test_small_array_medians_equal_numpys():
    from fmcw_cl.numeric import median, row_nanmedian

    rng = np.random.default_rng(8)
    for n in (1, 2, 3, 16, 17, 401):
        x = rng.normal(size=n)
        assert median(x) == np.median(x)
    x[5] = np.nan
    assert np.isnan(median(x)) and np.isnan(median(np.zeros(0)))
    a = rng.normal(size=(50, 16))
    a[rng.random(a.shape) < 0.4] = np.nan
    a[:, 0] = 1.0                                   # every row holds a number
    np.testing.assert_array_equal(row_nanmedian(a), np.nanmedian(a, axis=1))
    a[::7] = np.nan                                 # and rows of NaN only: NaN, no warning
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        got = row_nanmedian(a)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        np.testing.assert_array_equal(got, np.nanmedian(a, axis=1))


def test_run_medians_equal_numpys_nanmedian_over_each_runs_windows():
    """uncertainty.run_median: per valid pair, np.nanmedian of the window of its own run
    (the run's ends padded with NaN), NaN outside the runs and where a window holds no number."""
    from numpy.lib.stride_tricks import sliding_window_view

    from fmcw_cl.numeric import runs
    from fmcw_cl.uncertainty import run_median

    rng = np.random.default_rng(9)
    x = rng.normal(size=3000)
    x[rng.random(x.size) < 0.2] = np.nan
    x[1000:1040] = np.nan                           # windows of NaN only
    valid = rng.random(x.size) < 0.97
    valid[2000:2300] = True
    window = 33
    want = np.full(x.size, np.nan)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        for a, b in runs(valid):
            pad = np.r_[np.full(window // 2, np.nan), x[a:b], np.full(window // 2, np.nan)]
            want[a:b] = np.nanmedian(sliding_window_view(pad, window), axis=1)
    got = run_median(x, valid, window)
    np.testing.assert_array_equal(got, want)
    assert np.isnan(got[~valid]).all() and np.isnan(got[1016:1024]).all()


def test_nearest_first_matches_as_the_argmin_of_what_is_left():
    """numeric.nearest_first (the trackers' and echo lines' one detection a line): the
    matrix's smallest finite cost taken again and again, its row and column then left
    out, on a tie the first in row-major order (np.argmin), on costs rounded to give ties."""
    from fmcw_cl.numeric import nearest_first

    def argmin_loop(miss):
        miss, out = miss.copy(), []
        while np.isfinite(miss).any():
            i, n = np.unravel_index(np.argmin(miss), miss.shape)
            out.append((int(i), int(n)))
            miss[i, :] = miss[:, n] = np.inf
        return out

    rng = np.random.default_rng(4)
    for _ in range(500):
        miss = np.round(rng.uniform(0, 1, rng.integers(1, 9, 2)), 1)
        miss[rng.random(miss.shape) < 0.4] = np.inf
        assert nearest_first(miss) == argmin_loop(miss)
    assert nearest_first(np.array([[1.0, 1.0], [1.0, 0.5]])) == [(1, 1), (0, 0)]


def test_running_median_and_savgol_derivative_equal_scipys():
    """The tracker's running median and the acceleration's Savitzky-Golay derivative
    (fmcw_cl.numeric: scipy.signal and scipy.ndimage cost a second to import) against
    scipy's: on random walks of odd and even lengths, windows from 3 to 21, the run
    shorter than the window included."""
    from scipy.ndimage import median_filter
    from scipy.signal import savgol_filter

    from fmcw_cl.numeric import running_median, savgol_derivative

    rng = np.random.default_rng(9)
    assert running_median(np.zeros(0), 17).size == 0
    for n in (1, 3, 4, 8, 17, 20, 21, 22, 100, 1001):
        x = np.cumsum(rng.normal(size=n)) * 3 + 7
        for size in (1, 3, 17):
            want = median_filter(x, size=size, mode="nearest")
            np.testing.assert_array_equal(running_median(x, size), want)
        for window, order in ((21, 2), (n - 1 + n % 2, 2), (5, 1), (7, 3), (3, 2)):
            if 1 <= order < window <= n:
                want = savgol_filter(x, window, order, deriv=1, delta=5e-5, mode="interp")
                np.testing.assert_allclose(savgol_derivative(x, window, order, 5e-5), want,
                                           rtol=1e-10, atol=1e-10 * np.abs(want).max())


def test_running_median_of_segments_and_long_windows_equals_scipys():
    """The running median (bottleneck's double heap) of segments laid end to end, each
    on its own (the tracker's groups), against scipy's on each segment alone; windows up
    to the displacement's 65 pairs, values with ties, segments shorter than the window;
    values with NaN: each window's middle with NaN sorted last, as a partition gives."""
    from scipy.ndimage import median_filter

    from fmcw_cl.numeric import running_median

    rng = np.random.default_rng(4)
    for n in (1, 2, 7, 64, 300):
        x = np.round(np.cumsum(rng.normal(size=n)), 1)         # ties
        for size in (1, 3, 17, 33, 41, 65):
            want = median_filter(x, size=size, mode="nearest")
            np.testing.assert_array_equal(running_median(x, size), want)
            edges = np.unique(np.r_[0, rng.integers(1, max(n, 2), size=3), n])
            edges = edges[edges <= n]
            first = np.repeat(edges[:-1], np.diff(edges))
            last = np.repeat(edges[1:] - 1, np.diff(edges))
            want = np.concatenate([median_filter(x[a:b], size=size, mode="nearest")
                                   for a, b in zip(edges[:-1], edges[1:], strict=True)])
            np.testing.assert_array_equal(running_median(x, size, (first, last)), want)
            gappy = np.where(rng.random(n) < 0.2, np.nan, x)
            windows = gappy[np.clip(np.arange(n)[:, None] + np.arange(-(size // 2), size // 2 + 1), 0, n - 1)]
            np.testing.assert_array_equal(running_median(gappy, size), np.sort(windows, axis=1)[:, size // 2])


def test_neighbour_residuals_in_blocks_equal_those_of_each_pair():
    """The continuity residuals of all pairs, taken RESIDUAL_BLOCK rows at a time,
    against those of subsets of pairs (one block of copied windows), across the
    blocks' seams; NaN distances and untrusted pairs among them."""
    rng = np.random.default_rng(12)
    n = 3 * verification.RESIDUAL_BLOCK + 123
    t = np.cumsum(rng.uniform(4e-5, 6e-5, n))
    dist = 0.3 + np.cumsum(rng.normal(0, 1e-4, n))
    vel = rng.normal(0, 0.01, n)
    dist[rng.integers(0, n, 20)] = np.nan
    trusted = rng.random(n) < 0.9
    trusted[100:140] = False                        # pairs with too few neighbours: inf
    resid, support = verification._residuals(t, dist, vel, trusted)
    seams = np.arange(1, 4) * verification.RESIDUAL_BLOCK
    for rows in (np.sort(rng.choice(n, n // 5, replace=False)), np.r_[seams - 1, seams, seams + 1]):
        got = verification._residuals(t, dist, vel, trusted, rows)
        np.testing.assert_array_equal(got[0], resid[rows])
        np.testing.assert_array_equal(got[1], support[rows])
    assert np.isinf(resid).any() and np.isfinite(resid).mean() > 0.5
