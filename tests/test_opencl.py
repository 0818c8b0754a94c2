"""Each OpenCL kernel against its numpy twin (PoCL in CI), and whole tracks."""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest
from conftest import bent_lut

from fmcw_cl import echoes
from fmcw_cl.backend import make_processor
from fmcw_cl.chunks import margin_samples
from fmcw_cl.engine import process
from fmcw_cl.opencl import faults as k_faults
from fmcw_cl.opencl import resample as k_resample
from fmcw_cl.opencl import spectrum as k_spectrum
from fmcw_cl.opencl.context import cl, lanes_width
from fmcw_cl.opencl.processor import OpenCLProcessor
from fmcw_cl.options import Options
from fmcw_cl.stages import clutter, delay, faults, lpf, resample, spectrum, sync
from fmcw_cl.stages.spectrum import Search


@pytest.fixture(scope="module")
def backend():
    return OpenCLProcessor()


@pytest.mark.parametrize("sweeps,points", [(1, 1000), (777, 1000), (33, 2048), (5, 999), (3, 7)])
def test_resample_kernel_matches_numpy(backend, kernel_variant, sweeps, points):
    rng = np.random.default_rng(sweeps)
    codes = rng.integers(-8192, 8192, 60_001).astype(np.int16)   # white: the hardest case
    codes[:5000] = 8191                                            # a clipped stretch
    starts = rng.uniform(2, 60_001 - 2600, sweeps)
    lengths = 2499.999 + rng.uniform(-1e-3, 1e-3, sweeps)
    u = np.sort(rng.uniform(0, 1, points))
    for uu in (u, u[::-1]):                 # both sweep directions (a rising current's u falls)
        ref = resample.resample(codes, starts, lengths, uu, resample.window(points))
        got = backend.resample(codes, starts, lengths, uu, resample.window(points)).get(backend.rt.queue)
        assert got.shape == ref.shape
        assert np.abs(got - ref).max() < 0.02     # codes; float32 positions keep 1e-6 sample


@pytest.mark.parametrize("points", [1000, 999, 7])
def test_resample_rows_are_resample_lanes_bit_for_bit(backend, monkeypatch, points):
    """resample_rows (a row a lane) against resample_lanes (a row a work-item), at 8 lanes
    and the device's width: idle lanes, points past the last whole tile, both sweep
    directions, rows far from the nominal length (points whose taps move beyond the
    seven codes, taken a lane at a time), rows at both ends of the codes, and runs of
    rows each as if alone (the delay's trials: a launch a run, each its own nominal
    length and LUT table; an empty run among them)."""
    rt = backend.rt
    rng = np.random.default_rng(points)
    codes = rng.integers(-8192, 8192, 60_001).astype(np.int16)
    sweeps = 37
    starts = np.sort(rng.uniform(2, codes.size - 2600, sweeps))
    starts[0], starts[-1] = 2.3, codes.size - 2504.5        # tiles past the codes' ends
    lengths = 2499.999 + rng.uniform(-1e-3, 1e-3, sweeps)
    lengths[5::9] += (-3.2, 2.7, 3.9, -2.5)[: lengths[5::9].size]
    u = np.sort(rng.uniform(0, 1, points))
    win = resample.window(points)
    runs = [10, 0, 20, 7]
    in_runs = lengths + np.repeat([0.0, 25.0, -40.0], [10, 20, 7])
    chosen = rt.lanes, rt.width
    try:
        for uu in (u, u[::-1]):
            for job in ((starts, lengths, uu), (starts, in_runs, uu, runs)):
                rt.lanes = True
                with monkeypatch.context() as m:
                    m.setattr(k_resample, "rows_across", lambda *_: None)
                    (want,) = k_resample.resample_each(rt, backend.bufs, codes, [job], win)
                    want = want.get()
                assert np.abs(want - resample.resample(codes, *job[:3], win)).max() < 0.02
                for width in {8, rt.width}:
                    rt.width = width
                    # a GPU's local memory (NVIDIA: 48 KB) holds no rows of 2500 codes: it
                    # runs resample_lanes, which `want` is
                    across = k_resample.rows_across(rt, np.floor(2500 * uu), points)
                    assert across is not None or not rt.device.type & cl.device_type.CPU
                    (got,) = k_resample.resample_each(rt, backend.bufs, codes, [job], win)
                    np.testing.assert_array_equal(got.get(), want)
                rt.width = chosen[1]
    finally:
        rt.lanes, rt.width = chosen


def _measure(backend, rows, beta, v, nfft, lo, hi=None):
    pk, _, _ = k_spectrum.measure(backend.rt, backend.bufs, rows, beta, v, nfft, lo, hi)
    return pk


@pytest.mark.parametrize("sweeps,nfft", [(1, 2048), (301, 2048), (17, 4096), (3, 64), (6, 128)])
def test_fft_kernel_matches_numpy(backend, kernel_variant, sweeps, nfft):
    """Both transform shapes (log2 nfft odd: a radix-2 stage; even: radix-4 only),
    plain and de-chirped with folds of several cycles."""
    rng = np.random.default_rng(nfft + sweeps)
    points = nfft // 2 - 3
    x = rng.normal(0, 100, (sweeps, points))
    ref = spectrum.power_spectra(x, nfft)
    got = backend.power(x.astype(np.float32), None, None, nfft)
    assert np.abs(got - ref).max() <= 1e-5 * ref.max()
    pick = np.arange(sweeps)[::-2]                           # picked rows, plain: the de-chirp path
    got = backend.power(x.astype(np.float32), None, None, nfft, pick)
    assert np.abs(got - ref[pick]).max() <= 1e-5 * ref.max()
    beta = rng.uniform(-30, 30, points)
    v = rng.uniform(-8, 8, sweeps)
    ref = spectrum.power_spectra(x * np.exp(-2j * np.pi * np.outer(v, beta)), nfft)
    got = _measure(backend, x.astype(np.float32), beta, v, nfft, 1)
    want = spectrum.find_peaks(ref, 1)
    np.testing.assert_allclose(got.bin, want.bin, atol=1e-3)
    np.testing.assert_allclose(got.snr_db, want.snr_db, atol=1e-2)


@pytest.mark.parametrize("sweeps,points,nfft", [(3, 20, 128), (10, 300, 2048), (17, 1000, 2048)])
def test_short_rows_and_idle_lanes(backend, kernel_variant, sweeps, points, nfft):
    """Rows far shorter than the transform (the padding reaches into the first stage's
    inputs), and row counts that leave lanes of the last group idle."""
    x = np.random.default_rng(points).normal(0, 10, (sweeps, points)) + 50 * np.cos(0.3 * np.arange(points))
    ref = spectrum.power_spectra(x, nfft)
    got = backend.power(x.astype(np.float32), None, None, nfft)
    assert np.abs(got - ref).max() <= 1e-5 * ref.max()
    pk = _measure(backend, x.astype(np.float32), None, None, nfft, 2)
    want = spectrum.find_peaks(ref, 2)
    np.testing.assert_allclose(pk.bin, want.bin, atol=1e-3)
    np.testing.assert_allclose(pk.snr_db, want.snr_db, atol=1e-2)


@pytest.mark.parametrize("sweeps,picked", [(41, None), (41, 9), (3, 0)])
def test_both_directions_in_one_trip_equal_each_alone(backend, kernel_variant, sweeps, picked):
    """resample_each and measure_each (a pair's rising and falling half-sweeps, their
    positions up in one copy, all results down in one): bit for bit each direction
    alone, plain (every echo listed) and de-chirped at picked rows."""
    from fmcw_cl.stages import doppler

    rng = np.random.default_rng(sweeps)
    codes = rng.integers(-3000, 3000, 200_003).astype(np.int16)
    lut, win = bent_lut()
    jobs = [(rng.uniform(10, 190_000, sweeps), np.full(sweeps, 2500.0) + rng.uniform(-1, 1, sweeps), u)
            for u in (lut.u_rise, lut.u_fall)]
    both = backend.resample_each(codes, jobs, win)
    for x, job in zip(both, jobs, strict=True):
        np.testing.assert_array_equal(x.get(), backend.resample(codes, *job, win).get())
    model = doppler.doppler_model(lut, 25e-6, 1024, win)
    betas = (model.beta_rise, model.beta_fall)
    search = Search(3, 400, echoes=picked is None)
    rows = None if picked is None else np.sort(rng.choice(sweeps, picked, replace=False))
    v = None if picked is None else rng.uniform(-5, 5, picked)
    together = backend.measure_each(both, betas, v, model, search, rows)
    for x, beta, got in zip(both, betas, together, strict=True):
        alone = backend.measure(x, beta, v, model, search, rows)
        assert len(got) == len(alone) == (3 if picked is None else 2)
        np.testing.assert_array_equal(got[0], alone[0])
        np.testing.assert_array_equal(got[1], alone[1])
        if picked is None:
            for k in ("bin", "snr_db", "count"):
                np.testing.assert_array_equal(getattr(got[2], k), getattr(alone[2], k))


def test_runs_and_groups_of_rows_equal_each_alone(backend, kernel_variant):
    """The chunks of one pass of the delay's trials: resample_each of half-sweeps in runs
    (each run's positions split at its own median length) and the plain spectra of rows
    in groups (two rows a transform, within a group only) give each run's and group's
    rows bit for bit as alone, whatever is beside them: runs and groups of odd sizes,
    one of a single row, one empty; the rows within float32 of numpy's."""

    rng = np.random.default_rng(5)
    codes = rng.integers(-3000, 3000, 200_003).astype(np.int16)
    lut, win = bent_lut()
    runs = [71, 0, 120, 1, 51]
    lengths = np.concatenate([2500.0 + 3.3 * k + rng.uniform(-1, 1, n) for k, n in enumerate(runs)])
    starts = rng.uniform(10, 190_000, lengths.size)
    u = lut.u_rise
    (x,) = backend.resample_each(codes, [(starts, lengths, u, runs)], win)
    got = x.get()
    np.testing.assert_allclose(got, resample.resample(codes, starts, lengths, u, win), rtol=0, atol=0.02)
    firsts = np.cumsum([0, *runs[:-1]])
    alone = [backend.resample(codes, starts[a:a + n], lengths[a:a + n], u, win).get()
             for a, n in zip(firsts, runs, strict=True) if n]
    np.testing.assert_array_equal(got, np.concatenate(alone))
    groups = np.unique(firsts)            # the empty run's first row is the next one's

    def plain(rows, groups=None):         # the plain spectra's peaks and every echo
        (pk, _, det), = k_spectrum.measure_each(backend.rt, backend.bufs, [(rows, None, None)], None, 1024, 3,
                                                400, echoes=True, groups=groups)
        return pk, det

    pk, det = plain(x, groups)
    at = 0
    for rows in alone:
        pk1, det1 = plain(rows)
        part = slice(at, at + rows.shape[0])
        np.testing.assert_array_equal(pk.bin[part], pk1.bin)
        np.testing.assert_array_equal(pk.snr_db[part], pk1.snr_db)
        for k in ("bin", "snr_db", "count"):
            np.testing.assert_array_equal(getattr(det, k)[part], getattr(det1, k))
        at += rows.shape[0]
    assert not np.array_equal(plain(x)[0].snr_db, pk.snr_db)    # one group: rows pair across the ends


@pytest.mark.parametrize("nfft", [128, 2048])
def test_power_spectra_of_several_row_counts_in_one_trip(backend, kernel_variant, nfft):
    """power_each (the tuning check's rising, falling and reference spectra): rows of
    other counts, plain and de-chirped, by one download, each bit for bit as alone and
    within float32 of numpy's."""
    rng = np.random.default_rng(nfft)
    points = nfft // 2 - 5
    beta = rng.uniform(-20, 20, points)
    jobs = [(rng.normal(0, 50, (n, points)).astype(np.float32), b, v)
            for n, b, v in ((7, beta, rng.uniform(-6, 6, 7)), (4, -beta, rng.uniform(-6, 6, 4)),
                            (3, None, None), (0, None, None))]
    before = backend.traffic()["downloads"]
    got = backend.power_each(jobs, nfft)
    assert backend.traffic()["downloads"] == before + 1
    for (x, b, v), spec in zip(jobs, got, strict=True):
        assert spec.shape == (x.shape[0], nfft // 2)
        np.testing.assert_array_equal(spec, backend.power(x, b, v, nfft))
        ref = spectrum.power_spectra(x if v is None else x * np.exp(-2j * np.pi * np.outer(v, b)), nfft)
        # float32 phases of tens of cycles: the de-chirped rows 1e-4
        assert np.abs(spec - ref).max(initial=0) <= (1e-5 if v is None else 1e-4) * ref.max(initial=1)


def test_a_kernel_uses_the_scalars_of_each_launch(backend):
    """A kernel's scalar types are declared at its first launch and every argument is
    set at each: one kernel object launched in turn with other blocks, limits and
    buffers counts each time as numpy does."""
    rt = backend.rt
    codes = np.random.default_rng(3).integers(-2048, 2048, 5001).astype(np.int16)
    kernel = rt.kernel("faults", "clip_blocks")
    assert kernel is rt.kernel("faults", "clip_blocks")
    for block, full_scale in ((64, 2048), (37, 1500), (64, 2048), (1000, 100)):
        got = k_faults.clip_counts(rt, backend.bufs, codes, block, full_scale)
        np.testing.assert_array_equal(got, faults.clip_counts(codes, block, full_scale))
    assert kernel.typed


def test_fft_tables_undo_the_digit_reversal():
    for nfft in (8, 32, 2048, 4096):
        _, _, perm = k_spectrum.tables(nfft)
        assert np.array_equal(np.sort(perm), np.arange(nfft))


def test_peak_kernel_on_tones_and_band_edges(backend, kernel_variant):
    nfft, points = 2048, 1000
    true_bins = np.array([40.3, 100.0, 511.75, 1000.2, 1022.6])
    j = np.arange(points)
    x = np.cos(2 * np.pi * np.outer(true_bins / nfft, j)) * resample.window(points)
    x += np.random.default_rng(1).normal(0, 0.01, x.shape)
    for lo, hi in ((30, None), (30, 700)):
        got = _measure(backend, x.astype(np.float32), None, None, nfft, lo, hi)
        want = spectrum.find_peaks(spectrum.power_spectra(x, nfft), lo, hi)
        np.testing.assert_allclose(got.bin, want.bin, atol=2e-3)
        np.testing.assert_allclose(got.snr_db, want.snr_db, atol=0.02)


def test_measure_on_device_rows_equals_host_rows(backend, kernel_variant):
    """The resampled rows stay on the device across passes: same peaks as uploading."""
    rng = np.random.default_rng(5)
    codes = rng.integers(-2000, 2000, 40_001).astype(np.int16)
    starts = rng.uniform(2, 30_000, 9)
    u = np.linspace(0, 1, 1000)
    win = resample.window(1000)
    rows = backend.resample(codes, starts, np.full(9, 2500.0), u, win)
    beta = rng.uniform(-10, 10, 1000)
    v = rng.uniform(-3, 3, 9)
    for vv in (None, v):
        a = _measure(backend, rows, beta, vv, 2048, 20)
        b = _measure(backend, rows.get(backend.rt.queue), beta, vv, 2048, 20)
        np.testing.assert_array_equal(a.bin, b.bin)
    # the tracker's later passes: some rows, in any order, each with its velocity
    pick = np.array([7, 2, 5])
    got, _, _ = k_spectrum.measure(backend.rt, backend.bufs, rows, beta, v[pick], 2048, 20, index=pick)
    want = _measure(backend, rows.get(backend.rt.queue)[pick], beta, v[pick], 2048, 20)
    np.testing.assert_array_equal(got.bin, want.bin)
    np.testing.assert_array_equal(got.snr_db, want.snr_db)


def sync_codes(n, half, t0, noise, seed, spikes=0):
    """A sync triangle as int16 codes, with isolated glitches of either sign."""
    rng = np.random.default_rng(seed)
    p = ((np.arange(n) - t0) / (2 * half)) % 1.0
    x = 6000 * (np.where(p < 0.5, 2 * p, 2 - 2 * p) - 0.5) + rng.normal(0, noise, n)
    at = rng.integers(10, n - 10, spikes)
    x[at] += rng.choice([-1, 1], spikes) * rng.uniform(800, 20_000, spikes)
    return np.clip(np.rint(x), -32768, 32767).astype(np.int16)


def assert_fitted_equal(got: sync.Fitted, want: sync.Fitted) -> None:
    for key in ("centre", "s0", "s1", "direction"):
        np.testing.assert_array_equal(getattr(got, key), getattr(want, key))


@pytest.mark.parametrize("span", [512, 5])
@pytest.mark.parametrize("n,half,spikes", [(200_001, 2500.0, 0), (123_457, 2500.0, 40),
                                           (50_003, 1234.5, 7), (9_999, 300.0, 3)])
def test_sync_kernels_match_numpy(backend, kernel_variant, monkeypatch, span, n, half, spikes):
    """Block sums, the level's thresholds, the hysteresis's band and side changes and the
    despiked line-fit sums are exact integers on both sides, and the crossings' centres
    and the second fit's centre are rounded in double precision as numpy does, so both
    fits of every crossing and the turning points are bitwise equal: odd lengths, partial
    periods at both ends, a sync that stops for longer than a span, and spans of 5 blocks
    (every state the hysteresis carries from span to span)."""
    from fmcw_cl.opencl import sync as k_sync

    monkeypatch.setattr(k_sync, "SPAN", span)
    x = sync_codes(n, half, t0=0.37 * half, noise=5.0, seed=n, spikes=spikes)
    if spikes == 40:
        x[60_000:100_000] = x[60_000]                      # the sync stops: no crossing
    got, want = backend._fitted(x, half), sync.fitted(x, half)
    assert want.centre.size > 2 and (want.centre >= 0).sum() > 2
    assert_fitted_equal(got, want)
    assert got.level == want.level
    hw = sync.fit_half_width(half)
    # both fits: random centres (their crossings mostly far off: dropped), centres a few
    # samples off the real crossings (a second fit elsewhere) and on the window's reach
    fine = sync.crossings(x, half).time
    centre = np.r_[np.random.default_rng(1).integers(hw + 2, n - hw - 2, 33), np.rint(fine) + 3,
                   np.rint(fine), hw + 2, n - hw - 3].astype(np.int64)
    got = k_sync.line_fits(backend.rt, backend.bufs, x, centre, hw, 300.0, want.level)
    ref = sync.line_fits(x, centre, hw, 300.0, want.level)
    for a, b in zip(got, ref, strict=True):
        np.testing.assert_array_equal(a, b)
    moved = (ref[0] >= 0) & (ref[0] != centre)
    assert moved.sum() >= fine.size and (ref[0] < 0).any() and (ref[0] == centre).any()
    ref = sync.sync_turning_points(x, half)
    got = backend.turning_points(x, half)
    assert ref.time.size > 2
    np.testing.assert_array_equal(got.time, ref.time)
    np.testing.assert_array_equal(got.segment, ref.segment)


def test_line_fits_see_a_spike_at_every_place_of_the_window(backend, kernel_variant):
    """A spike on a window's first or last code, just outside it, or where the lanes
    hand over to the scalar tail is found and replaced as numpy's despike does (the
    lanes variant looks for spikes by each code's step to the left only: the next
    code's step is its step to the right; a search that misses any of these places
    fails here); spikes two or three codes past the first window, and on or just before
    the first code of a second window that lies outside the first."""
    from fmcw_cl.opencl import sync as k_sync

    half = 2500.0
    x = sync_codes(120_001, half, t0=0.37 * half, noise=5.0, seed=5)
    level = sync.fitted(x, half).level
    hw = sync.fit_half_width(half)
    centre = np.rint(sync.crossings(x, half).time).astype(np.int64)
    centre = centre[(centre > hw + 20) & (centre < x.size - hw - 20)]
    tail = (2 * hw + 1) // 8 * 8 - hw          # the first code the lanes leave to the tail
    offsets = [-hw - 1, -hw, -hw + 1, tail - 1, tail, hw - 1, hw, hw + 1, 0, -hw - 2, hw + 2, -hw - 3, hw + 3]
    assert centre.size >= len(offsets)
    spiky = x.copy()
    for c, off in zip(centre, offsets, strict=False):      # the first len(offsets) crossings
        spiky[c + off] += 6000
    got = k_sync.line_fits(backend.rt, backend.bufs, spiky, centre, hw, 300.0, level)
    ref = sync.line_fits(spiky, centre, hw, 300.0, level)
    clean = sync.line_fits(x, centre, hw, 300.0, level)
    for a, b in zip(got, ref, strict=True):
        np.testing.assert_array_equal(a, b)
    assert not np.array_equal(ref[1], clean[1])        # some spikes were inside their windows
    # centres 3 codes past their crossings: the second window (at c2, 3 codes back) is the
    # first's moved; a spike on its first code or just before it lies outside the first
    moved = centre + 3
    c2 = sync.line_fits(x, moved, hw, 300.0, level)[0]
    assert np.all(c2 == moved - 3)
    spiky = x.copy()
    for k, c in enumerate(c2):
        spiky[c - hw - k % 2] += 6000
    got = k_sync.line_fits(backend.rt, backend.bufs, spiky, moved, hw, 300.0, level)
    ref = sync.line_fits(spiky, moved, hw, 300.0, level)
    for a, b in zip(got, ref, strict=True):
        np.testing.assert_array_equal(a, b)
    assert not np.array_equal(ref[1], sync.line_fits(x, moved, hw, 300.0, level)[1])


@pytest.mark.parametrize("n", [1, 2, 19, 21, 4097, 8191])
def test_sync_level_kernel_matches_numpy(backend, kernel_variant, n):
    """The percentiles of the sampled sums (a radix select on the device) and the band's
    thresholds are numpy's integers: sums at both extremes of 64 int16 codes, ties,
    negative values, sizes at and between the twentieths of the ranks."""
    from fmcw_cl.opencl import sync as k_sync

    rng = np.random.default_rng(n)
    for sampled in (rng.integers(-2**21, 2**21 - 63, n), rng.integers(-1, 2, n) * 64 * 32767,
                    rng.integers(-40_000, 90_000, n)):
        sampled = sampled.astype(np.int32)
        sampled[: min(n, 2)] = [-2**21, 64 * 32767][: min(n, 2)]
        rt, bufs = backend.rt, backend.bufs
        out = np.zeros(k_sync.HEADER, np.int32)
        d_out = bufs.upload("level_test_out", out)
        k_sync.levels(rt, bufs.upload("level_test_in", sampled), n, d_out)
        rt.copy(out, d_out)
        a, b = sync.percentile_sums(sampled)
        lv = sync.levels(sampled, 64)
        assert list(out[:5]) == [a, b, lv.high, lv.low, lv.mid]
        lo, hi = np.percentile(sampled.astype(np.float64), [5.0, 95.0])
        assert abs(a / 20 - lo) <= 1e-9 * abs(lo) + 1e-6 and abs(b / 20 - hi) <= 1e-9 * abs(hi) + 1e-6


def test_sync_crossings_beyond_the_slots_are_redone_on_the_host(backend, monkeypatch):
    """More crossings in a span than its slots hold (a sync that is no triangle): the
    host redoes the search from the sums, with the same fits."""
    from fmcw_cl.opencl import sync as k_sync

    x = sync_codes(60_001, 2500.0, t0=100.0, noise=5.0, seed=7)
    want = sync.fitted(x, 2500.0)
    redone = []
    monkeypatch.setattr(k_sync, "slots", lambda factor, half_period: 1)
    monkeypatch.setattr(sync, "changes", lambda *a, real=sync.changes: redone.append(1) or real(*a))
    got = backend._fitted(x, 2500.0)
    assert redone and want.centre.size > 8
    assert_fitted_equal(got, want)


def test_coarse_crossings_of_a_triangle():
    """The hysteresis on the block sums: one crossing per level crossing of a noisy
    triangle, alternating in direction, at the right block; none in a flat stretch."""
    half = 2500.0
    x = sync_codes(100_001, half, t0=300.0, noise=5.0, seed=3)
    x[60_000:75_000] = x[60_000]                                  # the sync stops
    f = sync.block_length(half)
    co = sync.coarse_from_codes(x, f)
    t = co.block * f + 0.5 * (f - 1)
    # crossings of the middle: a quarter period after each minimum (t0 + k * 2 half)
    expect = 300.0 + half / 2 + half * np.arange(-1, 41)
    expect = expect[(expect > 0) & (expect < 100_000) & ~((expect > 60_000) & (expect < 75_000))]
    near = np.abs(t[:, None] - expect[None, :]).min(axis=0)
    assert (near < f).sum() >= expect.size - 1
    assert np.all(co.direction[1:] != co.direction[:-1]) or np.sum(co.direction[1:] == co.direction[:-1]) <= 1
    assert not np.any((t > 60_000 + f) & (t < 75_000 - f))


@pytest.mark.parametrize("rows,points,half", [(0, 1000, 50), (1, 1000, 50), (7, 1000, 3), (2000, 1000, 50),
                                              (301, 61, 200)])
def test_clutter_kernel_matches_numpy_bit_for_bit(backend, rows, points, half):
    """Rows of a still tone, a drifting one and noise, fewer rows than the window, a
    window wider than the rows: the kernel's running sum is its twin's, in its order."""
    rng = np.random.default_rng(rows)
    j = np.arange(points)
    x = (900 * np.cos(0.3 * j)[None, :] + 200 * np.cos(0.01 * np.arange(rows)[:, None] * j[None, :] / points)
         + rng.normal(0, 30, (rows, points))).astype(np.float32)
    got = backend.without_still(k_spectrum.as_device(backend.bufs, x), half)
    want = clutter.without_still(x, half)
    np.testing.assert_array_equal(got.get(), want)
    assert rows < 2 or np.abs(want).mean() < 0.5 * np.abs(x).mean()


@pytest.mark.parametrize("n,block", [(100_003, 256), (255, 256), (4097, 16), (1, 256), (0, 256)])
def test_clip_kernel_matches_numpy(backend, n, block):
    """Clipped codes of both signs and both full-scale codes, at block edges, in a last
    partial block; lengths that are no multiple of the vector loads."""

    rng = np.random.default_rng(n)
    codes = rng.integers(-8000, 8000, n).astype(np.int16)
    for at in rng.integers(0, max(n, 1), 6) if n else []:
        codes[at] = rng.choice([-8192, 8190, 8191])
    if n > 300:
        codes[[block - 1, block, n - 1]] = -8192
    want = faults.clip_counts(codes, block, 8192)
    got = backend.clip_counts(codes, block, 8192)
    assert want.any() == (n > 0) and got.dtype == np.uint16
    np.testing.assert_array_equal(got, want)


def test_prepared_chunk_equals_numpy(backend, static_capture, monkeypatch):
    """What a chunk's codes say whatever the delay: the turning points and the clipping
    counts, which ride on the sync's first download (no copy of their own), or where the
    sync is too short for a crossing search come down by themselves."""
    from fmcw_cl.capture import Capture, Chunk
    from fmcw_cl.processor import NumpyProcessor

    own, real = [], k_faults.clip_counts
    monkeypatch.setattr(k_faults, "clip_counts", lambda *a: own.append(1) or real(*a))
    with Capture(static_capture) as cap:
        info = cap.info
        beat, sy = cap.read(1234, 1234 + 40_001)
    beat = beat.copy()
    beat[[0, 4095, 4096, 17_000, 40_000]] = [-info.full_scale - 1, info.full_scale, -info.full_scale - 1,
                                            info.full_scale, info.full_scale]
    for n, copies in ((beat.size, 0), (300, 1)):
        chunk = Chunk(1234, beat[:n], sy[:n], 1234, 1234 + n)
        got, want = backend.prepare(chunk, info), NumpyProcessor().prepare(chunk, info)
        assert len(own) == copies
        assert (want.turns.time.size > 10) == (n > 300) and want.clip_counts.sum() == (5 if n > 300 else 1)
        for a, b in ((got.turns.time, want.turns.time), (got.turns.is_max, want.turns.is_max),
                     (got.turns.segment, want.turns.segment), (got.clip_counts, want.clip_counts)):
            np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("name", ["static_capture", "jump_capture"])
def test_opencl_track_equals_numpy_track(request, name):
    path = request.getfixturevalue(name)
    same = Options(chunk_periods=1024)       # each backend's own size differs (plan.fit_chunks)
    a = process(path, same, make_processor("numpy"))
    b = process(path, same, make_processor("opencl"))
    np.testing.assert_array_equal(a.valid, b.valid)
    v = a.valid
    assert np.abs(a.distance_m[v] - b.distance_m[v]).max() < 0.01e-3
    assert np.abs(a.velocity_mps[v] - b.velocity_mps[v]).max() < 1e-3
    assert b.attrs["backend"] == "opencl" and b.attrs["device"] == OpenCLProcessor().device
    assert a.attrs["chunk_periods"] == b.attrs["chunk_periods"] == 1024


def test_forked_backend_converts_the_same_track(backend, static_capture):
    """Two captures at once, each worker on its own queue, kernels and buffers
    (OpenCLProcessor.fork, batch.process_each): each track equals the one converted alone."""
    from fmcw_cl.batch import process_each

    alone = process(static_capture, Options(), backend)
    fork = backend.fork()
    assert fork.rt.queue is not backend.rt.queue and fork.rt.context is backend.rt.context
    assert fork.bufs is not backend.bufs and fork.rt.programs is backend.rt.programs
    got = list(process_each([static_capture] * 3, Options(), backend, workers=2))
    for _, track in got:
        np.testing.assert_array_equal(track.valid, alone.valid)
        np.testing.assert_array_equal(track.distance_m, alone.distance_m)
        np.testing.assert_array_equal(track.velocity_mps, alone.velocity_mps)


def test_a_gpus_path_reads_codes_into_page_locked_memory(backend, jump_capture, monkeypatch):
    """Where the device copies (a GPU: not zero-copy), the codes are read into
    page-locked memory of its context and go up without waiting, their copies held
    until a download has waited for them; the track equals the zero-copy one. Run on
    PoCL by taking its zero-copy away."""
    from fmcw_cl import pool
    from fmcw_cl.opencl import context
    from fmcw_cl.opencl.buffers import page_locked

    alone = process(jump_capture, Options(), backend)
    monkeypatch.setattr(context.Runtime, "zero_copy", property(lambda self: False))
    leased = []
    lease = pool.lease
    monkeypatch.setattr(pool, "lease", lambda n: leased.append(lease(n)) or leased[-1])
    try:
        copying = OpenCLProcessor()
        assert pool._allocate is page_locked(copying.rt.context)
        track = process(jump_capture, Options(), copying)
        assert leased and all(isinstance(a.base, cl.MemoryMap) for a in leased)
        rt = copying.rt
        codes = np.arange(1001, dtype=np.int16)
        copying.bufs.upload_once("codes", codes)
        assert len(rt.in_flight) == 1                 # not waited for: held
        got = np.empty_like(codes)
        rt.copy(got, copying.bufs.upload_once("codes", codes))     # the same array: no copy
        assert not rt.in_flight
        np.testing.assert_array_equal(got, codes)
    finally:
        pool.use(None)
    np.testing.assert_array_equal(track.valid, alone.valid)
    np.testing.assert_array_equal(track.distance_m, alone.distance_m)
    np.testing.assert_array_equal(track.velocity_mps, alone.velocity_mps)


def buffers_made(monkeypatch, counts) -> list[bool]:
    """From now on, `counts(flags)` of every device buffer `Buffers` makes (its one place
    that makes them, `_new`), in a list."""
    from fmcw_cl.opencl.buffers import Buffers

    made = []
    new = Buffers._new

    def counted(self, flags, *args, **kwargs):
        made.append(counts(flags))
        return new(self, flags, *args, **kwargs)

    monkeypatch.setattr(Buffers, "_new", counted)
    return made


def first_part(path, out, share: float):
    """A capture of the first `share` of `path`'s samples (no truth)."""
    from fmcw_cl.capture import Capture
    from fmcw_cl.capture_writer import CaptureWriter

    with Capture(path) as cap:
        info = cap.info
        n = int(info.samples * share)
        with CaptureWriter(out, n, info.sample_rate_hz, info.bits, info.modulation, info.tuning_current_a,
                           info.tuning_frequency_hz, refractive_index=info.refractive_index) as w:
            w.write(0, *cap.read(0, n))
    return out


def test_buffers_are_made_as_often_for_a_long_capture_as_for_a_short_one(tmp_path, monkeypatch):
    """Device buffers are made for the first chunks of each shape and reused: chunks
    that differ by a few percent in size (their sync crossings, their half-sweeps) find
    room in them, so a rail of sixteen chunks makes no more buffers than one of eight,
    which meets every shape (the range check's every 4th pair near the limit too; wraps
    of host memory on a CPU device, one per chunk, are no buffers made)."""
    import fmcw_cl
    from fmcw_cl.opencl.context import cl

    made = buffers_made(monkeypatch, lambda flags: not flags & cl.mem_flags.USE_HOST_PTR)
    long = tmp_path / "rail_0.8.h5"
    fmcw_cl.simulate(long, "rail", duration=0.8, seed=4)
    short = first_part(long, tmp_path / "rail_0.4.h5", 0.5)       # the same samples as a 0.4 s simulation
    counts = []
    for cap in (short, long):
        made.clear()
        processor = OpenCLProcessor()
        process(cap, Options(chunk_periods=800), processor)
        counts.append((sum(made), processor.chunks))
    (short, n_short), (long, n_long) = counts
    assert n_long >= n_short + 3
    assert long <= short, counts


def test_a_packeds_sub_buffers_are_its_own(backend):
    """A Packed's sub-buffers live as long as it (and what it gave them to), none kept
    by the Buffers for the next chunk's, and no two live Packed share a buffer:
    sub-buffers of two layouts of one buffer overlapped, and NVIDIA's OpenCL (an H200)
    crashed the process releasing them or their buffer, at every conversion
    (2026-12-04). A Packed's buffer is free again once it and its sub-buffers are gone."""
    import sys

    from fmcw_cl.opencl.buffers import Buffers, Packed

    bufs = Buffers(backend.rt)
    packed = Packed(bufs, "packed", [(np.float32, 10), (np.int32, 3)])
    again = Packed(bufs, "packed", [(np.float32, 12), (np.int32, 3)])     # beside it: another buffer
    assert not set(map(id, packed.buffers)) & set(map(id, again.buffers))
    assert packed._parent is bufs.get("packed", 4) and again._parent is not packed._parent
    first, sub = packed._parent, packed.buffers[1]
    del packed
    assert Packed(bufs, "packed", [(np.float32, 10)])._parent is not first    # its sub-buffer lives
    del again
    assert sys.getrefcount(sub) == 2                  # this name's and the call's: nothing kept it
    del sub
    assert Packed(bufs, "packed", [(np.float32, 10)])._parent is first        # all gone: free again


@pytest.mark.parametrize("dechirp", [True, False])
def test_a_second_capture_uploads_no_constants(static_capture, dechirp, monkeypatch):
    """A plan's window, Doppler bases and LUTs are the same objects capture after capture
    (plan.shaped, build_lut): the device keeps them from the first conversion, and the
    second makes no constant's buffer (and no copy of one)."""
    from fmcw_cl.opencl.context import cl

    made = buffers_made(monkeypatch, lambda flags: flags == cl.mem_flags.READ_ONLY)   # Buffers.constant's
    processor = OpenCLProcessor()
    counts = []
    for _ in range(2):
        made.clear()
        process(static_capture, Options(dechirp=dechirp), processor)
        counts.append(sum(made))
    assert counts[0] > 0 and counts[1] == 0, counts


def test_every_kernel_launches_with_one_local_size(static_capture, monkeypatch):
    """PoCL builds a kernel anew (0.1-0.2 s) for each local size it meets, and picks one
    that follows the global size when the launch leaves it open: across chunks of other
    lengths (and counts of sync crossings), each kernel must keep one fixed local size."""
    from fmcw_cl.opencl import context

    seen: dict[str, set] = {}
    launch = context._Counted.__call__

    def spy(self, queue, global_size, local_size, *args):
        seen.setdefault(self.kernel.function_name, set()).add(local_size)
        return launch(self, queue, global_size, local_size, *args)

    monkeypatch.setattr(context._Counted, "__call__", spy)
    be = make_processor("opencl")
    for periods in (97, 160):         # cores and the last partial chunk of other lengths
        process(static_capture, Options(chunk_periods=periods), be)
    cpu = {"resample_rows", "spectrum_lanes", "block_sum_span", "line_fit_lanes"}
    variant = cpu if be.rt.lanes else {"resample", "spectrum_peak", "block_sum", "line_fit"}    # a GPU's
    assert variant | {"sync_levels", "span_ends", "span_carries", "span_crossings", "clip_blocks",
                      "cic_decimate", "fir_same", "track_pass", "block_sums", "delay_centre",
                      "delay_correlate", "delay_coarse", "delay_fit", "copy_words"} <= set(seen)
    assert all(len(sizes) == 1 and None not in sizes for sizes in seen.values()), seen


def test_a_conversion_on_the_device_imports_no_scipy(static_capture):
    """scipy.signal and scipy.ndimage took a second to import in every fresh process
    that converted a capture: the OpenCL path imports no scipy module at all."""
    import subprocess
    import sys

    code = ("import sys; from fmcw_cl.backend import make_processor; from fmcw_cl.engine import process; "
            f"process({str(static_capture)!r}, processor=make_processor('opencl')); "
            "print(sorted(m for m in sys.modules if m.split('.')[0] == 'scipy'))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout


def test_kernel_build_failure_falls_back_or_fails(monkeypatch):
    """A kernel that does not build: auto warns and takes numpy, opencl fails, and the
    build log is saved where the message says."""
    import re

    import fmcw_cl.kernels

    from fmcw_cl.errors import FmcwError
    from fmcw_cl.opencl import context

    monkeypatch.setattr(fmcw_cl.kernels, "source", lambda name: "__kernel void broken( {")
    monkeypatch.setattr(context, "_RUNTIMES", {})            # a fresh context, no cached builds
    files = r"\w+\.cl( \+ \w+\.cl)*"                          # a program's files, as built
    with pytest.raises(FmcwError, match=rf"kernel {files} failed to build on .*; build log: ") as err:
        make_processor("opencl")
    log = re.search(r"build log: (\S+)", str(err.value)).group(1)
    assert "broken" in open(log).read() or "error" in open(log).read().lower()
    warnings = []
    backend = make_processor("auto", warn=warnings.append)
    assert backend.name == "numpy"
    assert len(warnings) == 1 and re.match(r"warning: OpenCL unavailable \(kernel \w+\.cl", warnings[0])


def test_no_opencl_platform(monkeypatch):
    from fmcw_cl.errors import FmcwError
    from fmcw_cl.opencl import choice

    monkeypatch.setattr(choice, "devices", lambda: [])
    with pytest.raises(FmcwError, match="no OpenCL device found: pip install pocl-binary-distribution"):
        make_processor("opencl")
    warnings = []
    assert make_processor("auto", warn=warnings.append).name == "numpy"
    assert len(warnings) == 1 and "no OpenCL device found" in warnings[0]


@pytest.mark.parametrize("rows,n,period", [(1, 441, 200), (3, 1237, 200), (6, 9999, 160)])
def test_delay_fit_kernel_matches_numpy(backend, rows, n, period):
    """The per-period Gauss-Newton fit of the sync delay (delay_fit) against its twin on
    noisy triangles moved by lags of up to 9 samples, from coarse lags up to half a
    sample off, a silent row among them: the same NaNs, lags within 1e-3 decimated
    samples (the estimate's own noise, about 0.1, is larger), near the true lag."""
    from fmcw_cl.opencl.selftest import delay_rows

    rng = np.random.default_rng(n)
    y, z, coarse, lag = delay_rows(rng, rows, n, period)
    span = 17
    got = backend.fit_periods(y, z, coarse, period, span)
    want = delay.fit_periods(y, z, coarse, period, span)
    assert got[0].shape == want[0].shape == (rows, len(range(span, n - span - period, period)))
    for g, w in zip(got, want, strict=True):
        np.testing.assert_array_equal(np.isnan(g), np.isnan(w))
    ok = np.isfinite(want[0])
    heard = np.arange(rows) < max(1, rows - 1)              # of two rows or more the last is silent
    assert (ok.all(axis=1) == heard).all() and not ok[~heard].any()
    assert np.abs(got[0][ok] - want[0][ok]).max() < 1e-3
    assert np.abs(got[1][ok] - want[1][ok]).max() < 1e-4
    assert np.abs(got[0][heard] - lag[heard, None]).max() < 0.5         # noise: about 0.1 a period


@pytest.mark.parametrize("n", [200_003, 9_000])
def test_delay_estimate_on_the_device_equals_numpy(backend, kernel_variant, n):
    """The sync delay's estimate from the codes on the device (low-pass, trimmed and
    centred rows, coarse lags, fits: OpenCLProcessor.period_delays, one download) against
    the device's stages driven from the host (the rows down, centred and correlated by
    numpy, up again) and numpy's, with each variant of the rows' centring (a row a
    work-item, a row a work-group): stretches of an odd length whose lags reach both ends
    of the coarse search, a lab's weak triangle (+-150 codes under 600 rms), a row of
    noise alone. Against the stages: the same NaNs, lags within 1e-4 samples; against
    numpy on the rows with a triangle: the same NaNs, lags within 0.03 samples (1e-3
    decimated), near the truth."""
    from fmcw_cl.processor import NumpyProcessor

    half = 2500.0
    lags = np.array([17.3, -380.5, 391.0, 0.0])
    rng = np.random.default_rng(n)

    def tri(t0, amp):
        p = ((np.arange(n) - t0) / (2 * half)) % 1.0
        return amp * (np.where(p < 0.5, 2 * p, 2 - 2 * p) - 0.5)

    sy = np.stack([tri(777.0 + 131 * k, 6000) + rng.normal(0, 4, n) for k in range(lags.size)])
    beat = np.stack([tri(777.0 + 131 * k - lag, 300 * (k < 3)) + rng.normal(0, 600, n)
                     for k, lag in enumerate(lags)])
    sy, beat = (np.rint(x).astype(np.int16) for x in (sy, beat))
    got = backend.period_delays(beat, sy, 100e6, half)
    staged = delay.period_delays(beat, sy, 100e6, half, backend.intensity_each, backend.fit_periods)
    want = NumpyProcessor().period_delays(beat, sy, 100e6, half)
    if n < 10_000:                         # too short for a period between the coarse lags' reach
        assert got[0].size == staged[0].size == want[0].size == 0
        return
    assert got[0].shape == staged[0].shape == want[0].shape and got[0].size % lags.size == 0
    for g, w in zip(got, staged, strict=True):
        np.testing.assert_array_equal(np.isnan(g), np.isnan(w))
        np.testing.assert_allclose(g, w, rtol=0, atol=1e-4)
    heard = np.repeat(np.arange(lags.size) < 3, got[0].size // lags.size)
    for g, w in zip(got, want, strict=True):
        np.testing.assert_array_equal(np.isnan(g[heard]), np.isnan(w[heard]))
    ok = heard & np.isfinite(want[0])
    assert ok.mean() > 0.7
    assert np.abs(got[0][ok] - want[0][ok]).max() < 0.03
    assert np.abs(got[1][ok] - want[1][ok]).max() < 1e-4
    for row, lag in zip(want[0].reshape(lags.size, -1)[:3], lags[:3], strict=True):
        assert abs(np.nanmedian(row) - lag) < 40        # a weak triangle: some 50 samples' noise a period


@pytest.mark.parametrize("n", [400_003, 5_000, 73, 72, 0])
def test_lpf_kernel_matches_numpy(backend, n):
    """The CIC decimator and the centred FIR (zero-padded ends), on a chirped beat that
    sweeps through multiples of the decimated rate, plus the intensity triangle."""
    t = np.arange(n) / 100e6
    x = 3000 * np.cos(2 * np.pi * (1e6 * t + 0.5 * 2e12 * t**2)) + 400 * np.sin(2 * np.pi * 2e4 * t)
    codes = np.rint(x + np.random.default_rng(n).normal(0, 30, n)).astype(np.int16)
    ref = lpf.intensity(codes, 100e6)
    got = backend.intensity(codes, 100e6)
    assert got[0].shape == ref[0].shape and got[1:] == ref[1:]
    assert np.all(np.abs(got[0] - ref[0]) < 1e-3)     # codes; float32 sums of 73 taps


@pytest.mark.parametrize("rows,n", [(6, 40_013), (3, 5_000), (2, 73), (4, 60), (0, 500)])
def test_lpf_kernel_rows_match_numpy(backend, rows, n):
    """Rows (the sync delay's stretches) low-passed by one launch: each row as if alone
    (its own zero-padded ends), against numpy's row by row."""
    rng = np.random.default_rng(rows * n)
    t = np.arange(n) / 100e6
    codes = np.rint(400 * np.sin(2 * np.pi * 2e4 * t + rng.uniform(0, 6, (rows, 1)))
                    + rng.normal(0, 300, (rows, n))).astype(np.int16)
    ref = lpf.intensity(codes, 100e6)
    got = backend.intensity(codes, 100e6)
    assert got[0].shape == ref[0].shape == (rows, lpf.outputs(n)) and got[1:] == ref[1:]
    assert np.all(np.abs(got[0] - ref[0]) < 1e-3)
    for r in range(rows):                                   # and the same as each row alone
        assert np.all(np.abs(got[0][r] - backend.intensity(codes[r], 100e6)[0]) < 1e-3)
    # with a second channel of other rows (the beat and the sync), by one download
    other = codes[:, : n // 2 + 1][::-1].copy()
    before = backend.traffic()["downloads"]
    both = backend.intensity_each([codes, other], 100e6)
    assert backend.traffic()["downloads"] == before + (both[0][0].size + both[1][0].size > 0)  # none: none
    np.testing.assert_array_equal(both[0][0], got[0])
    np.testing.assert_array_equal(both[1][0], backend.intensity(other, 100e6)[0])
    assert both[1][1:] == ref[1:]


def test_kernels_build_without_warnings(backend):
    """Every program builds with -Werror: a program built with warnings can come back
    from PoCL's kernel cache without its kernels (shared notes, pitfall 3)."""
    import pyopencl as cl
    from fmcw_cl.kernels import source

    for name in backend.programs:
        for width in {4, 8, backend.rt.width}:
            for shuffles in (0, 1):
                cl.Program(backend.rt.context, source(name)).build(
                    options=["-cl-std=CL1.2", "-Werror", f"-DLANES={width}", f"-DSHUFFLES={shuffles}"])


@pytest.mark.parametrize("points, nfft", [(1000, 2048), (999, 2048), (2000, 4096)])
def test_spectrum_lanes_of_any_width_and_load_are_the_same(backend, points, nfft):
    """spectrum_lanes at 4, 8 and 16 lanes a work-item (fft_lanes.cl's LANES; 16 where
    the device prefers float16, 4 where 8 do not fit its local memory: the range
    check's 4096 points on Intel's runtime), its rows loaded a value a row or by vectors
    transposed in registers (SHUFFLES; a simulator gathers): the same peaks, echoes and
    power bit for bit, plain (two rows a transform, a lone last row) and de-chirped at
    picked rows, with idle lanes and samples past the last whole vector."""
    rt = backend.rt
    rng = np.random.default_rng(5)
    sweeps = 41
    x = (rng.normal(0, 10, (sweeps, points)) + 80 * np.cos(np.outer(rng.uniform(0.2, 2.5, sweeps),
                                                                    np.arange(points)))).astype(np.float32)
    beta = rng.uniform(-30, 30, points)
    rows = np.sort(rng.choice(sweeps, 19, replace=False))
    v = rng.uniform(-8, 8, rows.size)
    chosen = rt.lanes, rt.width, rt.shuffles
    got = []
    try:
        for width, shuffles in itertools.product([4, 8, lanes_width(rt.device)], (False, True)):
            rt.lanes, rt.width, rt.shuffles = True, width, shuffles
            if k_spectrum.lanes_of(rt, nfft) != width:      # not held by this device's local memory
                continue
            plain = k_spectrum.measure(rt, backend.bufs, x, None, None, nfft, 3, keep_power=True, echoes=True)
            dechirped = k_spectrum.measure(rt, backend.bufs, x, beta, v, nfft, 3, index=rows)
            (peaks, power, echoes), (picked, _, _) = plain, dechirped
            got.append([peaks.bin, peaks.snr_db, power, echoes.bin, echoes.snr_db, echoes.count, picked.bin,
                        picked.snr_db])
    finally:
        rt.lanes, rt.width, rt.shuffles = chosen
    assert len(got) >= 2 and np.all(got[0][5] > 0)
    ref = spectrum.power_spectra(x.astype(np.float64), nfft)          # each width against numpy
    assert np.abs(got[0][2] - ref).max() <= 1e-5 * ref.max()
    np.testing.assert_allclose(got[0][0], spectrum.find_peaks(ref, 3).bin, atol=1e-3)
    for other in got[1:]:
        for a, b in zip(got[0], other, strict=True):
            np.testing.assert_array_equal(a, b)


def test_transform_too_large_for_local_memory_runs_on_the_host(backend, static_capture, monkeypatch):
    """A device whose local memory cannot hold the plan's transforms (a GPU's 48 KB and
    the 8192-point range check of --points 2048): `open` hands the spectra to the numpy
    twins, the rows come down once, and the track equals numpy's."""
    assert k_spectrum.fits(backend.rt, 2048)
    assert k_spectrum.local_bytes(backend.rt, 8192) > 48 * 1024 >= k_spectrum.local_bytes(backend.rt, 4096)
    same = Options(chunk_periods=1024)
    a = process(static_capture, same, make_processor("numpy"))
    monkeypatch.setattr(k_spectrum, "fits", lambda rt, nfft: False)
    b = process(static_capture, same, backend)
    np.testing.assert_array_equal(a.valid, b.valid)
    assert a.valid.mean() > 0.9
    assert np.abs(a.distance_m[a.valid] - b.distance_m[a.valid]).max() < 1e-5


def test_wall_track_and_echoes_equal_numpy(wall_capture):
    """Several echoes through the whole pipeline: same track, same echoes."""
    same = Options(chunk_periods=1024)
    a = process(wall_capture, same, make_processor("numpy"))
    b = process(wall_capture, same, make_processor("opencl"))
    np.testing.assert_array_equal(a.valid, b.valid)
    ok = a.valid
    assert np.abs(a.distance_m[ok] - b.distance_m[ok]).max() < 1e-5
    assert a.echoes.time_s.size == b.echoes.time_s.size
    np.testing.assert_allclose(a.echoes.distance_m, b.echoes.distance_m, atol=1e-6)
    np.testing.assert_allclose(a.echoes.snr_db, b.echoes.snr_db, atol=0.02)
    np.testing.assert_array_equal(a.echoes.tracked, b.echoes.tracked)
    assert a.attrs["rival_echo_m"] == pytest.approx(b.attrs["rival_echo_m"], abs=1e-5, nan_ok=True)
    # the same target chosen, in the same band
    assert a.attrs["target_choice"] == b.attrs["target_choice"]
    np.testing.assert_allclose(a.attrs["target_band_m"], b.attrs["target_band_m"], atol=1e-5)


def test_range_check_and_survey_in_one_trip_equal_each_alone(backend, kernel_variant, wall_capture,
                                                              monkeypatch):
    """A chunk's range check and survey by one copy each way (launched with the next
    chunk's resampling and carried down with its tracker's state, or the last chunk's by
    a trip of its own: OpenCLProcessor.check_and_survey), on a jump past a wall: each
    result bitwise equal to the two run apart on the device, and to numpy's within
    float32."""
    from dataclasses import replace

    from fmcw_cl.processor import ChunkProcessor, NumpyProcessor

    seen = []
    finished = OpenCLProcessor._finished

    def both(self, chunk, got):
        if chunk.check is not None and chunk.survey is not None:
            apart = ChunkProcessor.check_and_survey(self, chunk)
            rows = tuple(x.get() for x in chunk.survey.args[0])
            on_host = replace(chunk, survey=replace(chunk.survey, args=(rows, *chunk.survey.args[1:])))
            seen.append((got, apart, NumpyProcessor().check_and_survey(on_host)))
        return finished(self, chunk, got)

    monkeypatch.setattr(OpenCLProcessor, "_finished", both)
    process(wall_capture, Options(chunk_periods=1024), backend)
    assert len(seen) >= 3
    assert sum(b is not None for _, (_, _, b), _ in seen) >= 2         # the first conversion's bank
    for (checked, surveyed, banked), (checked1, surveyed1, banked1), (checked0, surveyed0, banked0) in seen:
        for got, apart in zip((*checked, *surveyed), (*checked1, *surveyed1), strict=True):
            for a, b in zip(got, apart, strict=True):
                np.testing.assert_array_equal(a, b)
        assert (banked is None) == (banked1 is None) == (banked0 is None)
        for det, det1, det0 in zip(banked or (), banked1 or (), banked0 or (), strict=True):
            for name in ("bin", "snr_db", "count"):
                np.testing.assert_array_equal(getattr(det, name), getattr(det1, name))
            # float32 against float64: an echo at the CFAR's threshold may differ; the rest agree
            same = det.count == det0.count
            assert same.mean() > 0.99 and det0.count.sum() > 0
            np.testing.assert_allclose(det.bin[same], det0.bin[same], atol=2e-3)
        for (d, snr), (d0, snr0) in zip(checked, checked0, strict=True):
            strong = snr0 > 15
            assert strong.mean() > 0.5
            np.testing.assert_allclose(d[strong], d0[strong], atol=1e-5)
            np.testing.assert_allclose(snr[strong], snr0[strong], atol=0.05)
        for (ratio, centroid, found, sums), (ratio0, centroid0, found0, sums0) in zip(surveyed, surveyed0,
                                                                                      strict=True):
            np.testing.assert_array_equal(found, found0)
            np.testing.assert_allclose(ratio, ratio0, rtol=1e-3, atol=1e-4)
            # bins: float32 sums of unclipped weights, a centre near bin 0 within 2e-4 of numpy's
            np.testing.assert_allclose(centroid, centroid0, rtol=1e-4, atol=1e-3)
            assert sums.shape == sums0.shape and sums.shape[0] == -(-ratio.size // echoes.MEAN_ROWS)
            np.testing.assert_allclose(sums, sums0, rtol=2e-4, atol=1e-3 * sums0.max())


def _one_by_one(backend, cap, plan) -> list:
    """The measurements of `cap`'s chunks under `plan`, each processed alone (no chunk
    after it given: nothing launched ahead)."""
    options = plan.options
    backend.open(plan)
    got = []
    for chunk in cap.chunks(options.chunk_periods, margin_samples(cap.info, options), 0, None, held=3):
        got += backend.process(chunk)
    return got


def test_a_chunk_makes_two_trips_each_way(backend, wall_capture, monkeypatch):
    """Two copies up and two down a chunk (and the chunk's codes, where the device does
    not read them from the host's memory). Up: the positions of a chunk's resampling with
    its pairs' times, and the range check and survey inputs of the chunk before. Down:
    the following chunk's sync fits and clipping counts, before the tracker's passes
    (whose time the next chunk's resampling is launched in), and the tracker's state
    with the range check and survey results of the chunk before (2n uploads and 2n + 1
    downloads for n chunks: the first chunk's own sync fits, no following chunk after
    the last, the last chunk's own range check). What each chunk was found to hold (the
    first by a trip of its own) equals its own `prepare` made apart, and the
    measurements equal those of chunks processed one by one."""
    from fmcw_cl.capture import Capture
    from fmcw_cl.chunks import capture_parts
    from fmcw_cl.plan import make_plan
    from fmcw_cl.processor import ChunkProcessor

    options = Options(chunk_periods=1024)
    with Capture(wall_capture) as cap:
        plan = make_plan(cap, options, processor=backend)
        capture_parts(cap, plan, backend)    # a context's constants (twiddles, tables) go up once
        backend.close()                      # ... but what the chunks gave is made again (chunk_memo)
        before = backend.traffic()
        parts = capture_parts(cap, plan, backend)
        after = backend.traffic()
        backend.close()
        ahead = []
        later = OpenCLProcessor.prepare_later

        def kept(self, chunk, info):
            got = later(self, chunk, info)
            ahead.append((got, ChunkProcessor.prepare(self, chunk, info)))
            return got

        monkeypatch.setattr(OpenCLProcessor, "prepare_later", kept)
        capture_parts(cap, plan, backend)
        monkeypatch.undo()
        one_by_one = _one_by_one(backend, cap, plan)
    n = len(parts)
    assert n >= 3
    codes = 0 if backend.rt.wraps_host else 2 * n     # a copy of each chunk's beat and sync codes
    assert after["uploads"] - before["uploads"] == 2 * n + codes
    assert after["downloads"] - before["downloads"] == 2 * n + 1
    assert len(ahead) == n and all(got.rider is None for got, _ in ahead)   # every chunk's, each landed
    for got, own in ahead:
        for a, b in zip(vars(got.value.turns).values(), vars(own.turns).values(), strict=True):
            np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(got.value.clip_counts, own.clip_counts)
    assert len(one_by_one) == n
    for a, b in zip(parts, one_by_one, strict=True):
        np.testing.assert_array_equal(a.reason, b.reason)
        np.testing.assert_array_equal(a.result.distance, b.result.distance)
        for key in a.survey:
            np.testing.assert_array_equal(a.survey[key], b.survey[key])


def test_weak_chunks_resampled_while_the_one_before_integrates(backend, tmp_path):
    """A chunk's integrated passes run after its tracker's first download, by which time
    the next chunk's resampling (its positions and pairs' times) has gone up
    (`ChunkProcessor.meanwhile`): on a static target at -20 dB per sample, whose every
    chunk the tracker integrates, the chunks converted in a row equal the same chunks
    converted one by one (nothing launched ahead). With the two chunks' times in one
    buffer, the integrated passes read the next chunk's bounds past their rows."""
    from fmcw_cl.capture import Capture
    from fmcw_cl.chunks import capture_parts
    from fmcw_cl.plan import make_plan
    from fmcw_cl.simulator import SimulationConfig, simulate_capture, static

    path = tmp_path / "weak.h5"
    simulate_capture(path, static(0.02, 0.25), 0.02, seed=5, config=SimulationConfig(snr_db=-20.0))
    options = Options(chunk_periods=128)
    with Capture(path) as cap:
        plan = make_plan(cap, options, processor=backend)
        parts = capture_parts(cap, plan, backend)
        one_by_one = _one_by_one(backend, cap, plan)
    assert len(parts) == len(one_by_one) >= 3
    assert all(p.result.integrated.max() > 1 for p in parts)
    for a, b in zip(parts, one_by_one, strict=True):
        np.testing.assert_array_equal(a.reason, b.reason)
        np.testing.assert_array_equal(a.result.distance, b.result.distance)
        np.testing.assert_array_equal(a.result.integrated, b.result.integrated)


@pytest.mark.parametrize("rows,nfft,lo", [(1, 2048, 64), (37, 2048, 20), (9, 4096, 100), (5, 128, 3),
                                         (25, 2048, 50)])
def test_survey_kernel_matches_numpy(backend, kernel_variant, rows, nfft, lo):
    """The echo survey (kernels/survey.cl against echoes.hidden): a target, sometimes a
    smeared rival the other echoes explain or not, sometimes a sharp one no echo
    explains, noise; medians of odd and even band sizes."""
    from fmcw_cl import spectrum_ops
    from fmcw_cl.stages import doppler

    rng = np.random.default_rng(rows + nfft)
    points = nfft // 2 - 7
    j = np.arange(points)
    x = rng.normal(0, 30, (2 * rows + 3, points))
    tone = lambda b, span=0.0: np.cos(2 * np.pi / nfft * (b * j + span * (j**2 / (2 * points) - j / 2)))  # noqa: E731
    band = nfft // 2 - lo
    target, rival, lump = lo + 0.3 * band, lo + 0.7 * band, lo + 0.5 * band
    x += 400 * tone(target)
    x[::2] += 300 * tone(rival, min(60, band / 4))   # smeared over up to 60 bins
    x[1::4] += 300 * tone(lump)
    x *= np.hanning(points)
    pick = np.sort(rng.choice(x.shape[0], rows, replace=False))
    beta = rng.uniform(-3, 3, points)
    v = rng.uniform(-0.1, 0.1, rows)
    others = np.full((rows, 3), np.nan)
    others[::3] = rival + np.array([-20, 0, 20])    # explained in every third row
    args = (beta, v, nfft, pick, lo, np.full(rows, target), np.full(rows, target), others)
    got = backend.survey(x.astype(np.float32), *args)
    want = spectrum_ops.NUMPY.survey(x, *args)
    np.testing.assert_array_equal(got[2], want[2])
    np.testing.assert_allclose(got[0], want[0], rtol=1e-3, atol=1e-4)
    np.testing.assert_allclose(got[1], want[1], rtol=1e-4)
    # the plain spectra's sums in blocks of MEAN_ROWS rows (the last one shorter)
    assert got[3].shape == want[3].shape == (-(-rows // echoes.MEAN_ROWS), nfft // 2)
    np.testing.assert_allclose(got[3], want[3], rtol=2e-4, atol=1e-5 * want[3].max())
    picked = doppler.power(x, None, None, nfft, pick)
    np.testing.assert_allclose(want[3][-1], picked[(want[3].shape[0] - 1) * echoes.MEAN_ROWS:].sum(axis=0))
    if rows >= 9:
        assert want[2].any() and not want[2].all()  # the rival is found where nothing explains it
    # two directions in one trip: each as alone
    flipped = x[:, ::-1].astype(np.float32)
    both = backend.survey_each([x.astype(np.float32), flipped], [beta, -beta], v, nfft, pick, lo,
                               [args[5]] * 2, [args[6]] * 2, [others] * 2)
    alone = backend.survey(flipped, -beta, *args[1:])
    for a, b in zip((*got, *alone), (*both[0], *both[1]), strict=True):
        np.testing.assert_array_equal(a, b)
    # hidden_lanes at 8 lanes and at the device's width (lanes.cl LANES): bit for bit
    rt, chosen = backend.rt, backend.rt.width
    try:
        for width in {8, lanes_width(rt.device)}:
            rt.width = width
            for a, b in zip(got, backend.survey(x.astype(np.float32), *args), strict=True):
                np.testing.assert_array_equal(a, b)
    finally:
        rt.width = chosen


def _tracker_scene(backend, scene: str, pairs: int, iterations: int, groups, amplitude: float = 1.0):
    """The tracker's rows on the device: an accelerating target whose beat folds
    ("fold"), a still one ("still"), noise alone ("noise") or silence ("silent"), with a
    fade; its times (in `groups` tracked apart), Doppler model and search band."""
    from fmcw_cl.physics import C
    from fmcw_cl.stages import doppler, pairing

    rng = np.random.default_rng(pairs + iterations)
    lut, win = bent_lut()
    half_s = 25e-6
    model = doppler.doppler_model(lut, half_s, 1024, win)
    t_mid = 0.01 + np.arange(pairs) * 50e-6
    v = np.linspace(1.0, 7.0, pairs) if scene == "fold" else np.zeros(pairs)
    r = 0.12 + np.cumsum(v) * 50e-6
    amp = np.full(pairs, amplitude) if scene in ("fold", "still") else np.zeros(pairs)
    amp[pairs // 3: pairs // 3 + 12] = 0.0                       # a fade
    rows = []
    for beta, dt in ((model.beta_rise, -half_s / 2), (model.beta_fall, half_s / 2)):
        phase = np.outer(2 * (r + v * dt) / C, lut.nu_hz) + v[:, None] * beta + rng.uniform(0, 1, (pairs, 1))
        noise = rng.normal(0, 0.3 if scene != "silent" else 0.0, (pairs, lut.points))
        x = amp[:, None] * np.cos(2 * np.pi * phase) + noise
        rows.append(k_spectrum.as_device(backend.bufs, (x - x.mean(axis=1, keepdims=True)) * win))
    times = pairing.Times(t_mid - half_s / 2, t_mid + half_s / 2, groups and np.array(groups))
    search = Search(int(0.03 / model.metres_per_bin), model.nfft // 2, echoes=True)
    return tuple(rows), times, model, search


@pytest.mark.parametrize("scene,pairs,iterations,groups", [
    ("fold", 301, 6, None), ("fold", 301, 2, None), ("still", 40, 6, None), ("noise", 77, 6, None),
    ("fold", 5, 6, None), ("silent", 30, 6, None), ("fold", 301, 6, (0, 3, 4, 96, 107, 250)),
    ("noise", 77, 6, (0, 40))])
def test_tracker_passes_on_the_device_equal_the_host_passes(backend, kernel_variant, monkeypatch, scene,
                                                            pairs, iterations, groups):
    """kernels/track.cl (the regularisation between the passes on the device, one copy
    each way, and the verdict after them) against pairing.passes and pairing.verdict
    driven by the same device's measurements: an
    accelerating target whose beat folds, with a fade (untrusted pairs interpolated)
    and noise; passes cut short by `iterations`; a still target (the passes stop
    after one); noise alone (few trusted pairs), silence (no spectrum at all); fewer
    pairs than the median's window; pairs in groups tracked apart (one of a single
    pair, one of 11 inside the fade with no trusted pair, groups that split the
    kernel's runs of pairs)."""
    from fmcw_cl import spectrum_ops
    from fmcw_cl.opencl import track as k_track

    rows, times, model, search = _tracker_scene(backend, scene, pairs, iterations, groups)
    assert k_track.supported(backend.rt)
    launched = monkeypatch_count(monkeypatch, k_track, "track")
    first, state = backend.track(rows, times, model, search, iterations, True)
    assert launched == [1]
    want_first, want = spectrum_ops.SpectrumOps.track(backend, rows, times, model, search, iterations, True)
    for a, b in zip(first, want_first, strict=True):
        np.testing.assert_array_equal(a[0], b[0])
        np.testing.assert_array_equal(a[1], b[1])
        np.testing.assert_array_equal(a[2].bin, b[2].bin)
    _assert_same_passes(state, want, times, model)
    valid, resid = state.verdict
    if scene == "fold" and pairs > 100:
        assert np.ptp(state.vd) > 3.0            # the passes moved the de-chirp velocities
        assert 0 < valid.sum() < pairs and np.isinf(resid).any() and np.ptp(resid[np.isfinite(resid)]) > 0
    if groups is not None and scene == "fold":   # the groups changed what the passes decided
        _, one = spectrum_ops.SpectrumOps.track(backend, rows, replace(times, groups=None), model, search,
                                           iterations, True)
        assert not np.array_equal(one.vd, state.vd)


def _assert_same_passes(state, want, times, model) -> None:
    """The device's tracker `state` (with its verdict) equals the host's `want` and
    pairing.verdict of it."""
    from fmcw_cl.stages import pairing

    for key in ("d_r", "s_r", "d_f", "s_f", "vd", "count"):
        np.testing.assert_array_equal(getattr(state, key), getattr(want, key), err_msg=key)
    valid, resid = pairing.verdict(want, times, model)
    assert want.verdict is None
    np.testing.assert_array_equal(state.verdict[0], valid)
    np.testing.assert_array_equal(state.verdict[1], resid)


@pytest.mark.parametrize("scene,pairs,iterations,groups,k,amplitude", [
    ("fold", 301, 6, None, 4, 0.1), ("fold", 301, 3, (0, 3, 4, 96, 107, 250), 16, 0.07),
    ("fold", 130, 6, (0, 65), 5, 0.14), ("still", 40, 6, None, 16, 0.05), ("noise", 77, 6, (0, 40), 8, 1.0),
    ("fold", 5, 6, None, 32, 0.1), ("silent", 30, 6, None, 4, 1.0)])
def test_integrated_passes_on_the_device_equal_the_host_passes(backend, kernel_variant, monkeypatch, scene,
                                                               pairs, iterations, groups, k, amplitude):
    """The tracker's passes on K-window integrated spectra on the device (kernels/track.cl
    with `every`: the displacement along the track from each pass's velocities, the
    floors by count of spectra; integrate.cl, both directions a launch; one copy down)
    against pairing.passes driven by the same device's spectra and integrated peaks: a
    weak folding target (few single pairs heard) with a fade, in groups whose windows
    are cut at their ends (counts under K: lower floors) and that split the kernel's runs
    of pairs (the displacement carried across work-items); a still weak target, noise
    alone, silence; fewer pairs than the window."""
    from fmcw_cl import spectrum_ops
    from fmcw_cl.opencl import track as k_track

    rows, times, model, search = _tracker_scene(backend, scene, pairs, iterations, groups, amplitude)
    search = replace(search, echoes=False)
    launched = monkeypatch_count(monkeypatch, k_track, "integrated")
    state = backend.integrated(rows, times, model, search, iterations, k)
    assert launched == [1]
    want = spectrum_ops.SpectrumOps.integrated(backend, rows, times, model, search, iterations, k)
    _assert_same_passes(state, want, times, model)
    assert state.k == k and state.count.max() == min(k, pairs)
    if scene == "fold" and pairs > 100:
        assert np.ptp(state.vd) > 2.0            # the passes moved the de-chirp velocities
        single = spectrum_ops.SpectrumOps.track(backend, rows, times, model, search, iterations, True)[1]
        assert state.heard.mean() > single.heard.mean() + 0.3       # integration heard what one did not
        assert 0 < state.verdict[0].sum() < pairs


@pytest.mark.parametrize("pairs", [0, 1, 2, 49, 5001])
def test_verification_tests_on_the_device_equal_numpys(backend, monkeypatch, pairs):
    """kernels/verify.cl (`kinematic_drop`) and track.cl's `track_residual` over one
    group against verification.disagreed and the numpy residuals, and verification.verify with the
    processor's tests (on the device from PAIRS_MIN pairs) against its numpy run: a
    take-off at 300 m/s^2 with wrong pairs (an echo 3 mm off for 30 pairs, single noise
    peaks), gaps in time of 1 and 6 ms (beyond KINEMATIC_S), a fade (few valid pairs:
    too few neighbours), NaN distances on invalid pairs; fewer pairs than the kinematic
    and the continuity windows."""
    from fmcw_cl import spectrum_ops
    from fmcw_cl.opencl import verify as k_verify
    from fmcw_cl.stages import verification

    rng = np.random.default_rng(pairs)
    t = 0.01 + np.arange(pairs) * 50e-6
    t[pairs // 3:] += 1e-3
    t[2 * pairs // 3:] += 6e-3
    v = 1.0 + 300.0 * (t - 0.01) + rng.normal(0, 0.01, pairs)
    d = 0.1 + 0.5 * (v + 1.0) * (t - 0.01) + rng.normal(0, 30e-6, pairs)
    d[pairs // 2: pairs // 2 + 30] += 3e-3                  # another echo, followed a while
    d[rng.random(pairs) < 0.01] += rng.normal(0, 2e-3)      # single noise peaks
    ok = rng.random(pairs) < 0.9
    fade = slice(pairs // 4, pairs // 4 + 60)
    ok[fade] &= rng.random(ok[fade].size) < 0.1
    d[~ok & (rng.random(pairs) < 0.5)] = np.nan
    want = verification.disagreed(t, d, v, ok)
    np.testing.assert_array_equal(k_verify.disagreed(backend.rt, backend.bufs, t, d, v, ok), want)
    resid, support = spectrum_ops.NUMPY.residuals(t, d, v, ok)
    got = k_verify.residuals(backend.rt, backend.bufs, t, d, v, ok)
    np.testing.assert_array_equal(got[0], resid)
    np.testing.assert_array_equal(got[1], support)
    launched = monkeypatch_count(monkeypatch, k_verify, "residuals")
    for rows in (np.flatnonzero(ok), np.flatnonzero(ok)[::9]):     # every pair's on the device, a few here
        want_rows = spectrum_ops.NUMPY.residuals(t, d, v, ok, rows)
        for a, b in zip(backend.residuals(t, d, v, ok, rows), want_rows, strict=True):
            np.testing.assert_array_equal(a, b)
    assert launched == [int(pairs >= k_verify.PAIRS_MIN)]
    for a, b in zip(verification.verify(t, d, v, ok, backend), verification.verify(t, d, v, ok), strict=True):
        np.testing.assert_array_equal(a, b)
    if pairs > 1000:      # the scene exercises both tests
        assert 30 <= want.sum() < 0.2 * pairs
        assert np.isinf(resid).any() and np.isfinite(resid).sum() > 0.8 * pairs


def monkeypatch_count(monkeypatch, module, name: str) -> list[int]:
    """Count the calls of module.name (a one-item list, updated in place)."""
    calls, inner = [0], getattr(module, name)

    def counted(*args, **kwargs):
        calls[0] += 1
        return inner(*args, **kwargs)

    monkeypatch.setattr(module, name, counted)
    return calls


def test_no_kernel_reads_a_scalar_local_buffer_as_vectors():
    """A local buffer read as floatN (intN, ...) is declared so: a device need align a
    local argument for its declared type only, and a CPU device never shows the fault.
    While `integrate_lanes` read a float buffer as float8, the H100's check failed there
    (OUT_OF_RESOURCES); a cast the other way (float8 buffer, float reads) is safe."""
    import re
    from pathlib import Path

    cast = re.compile(r"\(\s*__local\s+(?:const\s+)?(?:u?char|u?short|u?int|u?long|float|double|half)"
                      r"(?:2|3|4|8|16)\s*\*\s*\)")
    kernels = Path(__file__).resolve().parents[1] / "kernels"
    hits = [f"{p.name}:{i}: {line.strip()}" for p in sorted(kernels.glob("*.cl"))
            for i, line in enumerate(p.read_text().splitlines(), 1) if cast.search(line)]
    assert len(list(kernels.glob("*.cl"))) > 10
    assert hits == []


def test_waits_polled_asleep_as_on_a_gpu_give_the_same_track(backend, static_capture, monkeypatch):
    """A GPU's waits poll the event asleep (`Runtime.wait`): the same path on this
    device, in chunks of 128 periods (downloads that ride, copies that wait, a finish),
    gives the track its own waits give, bitwise, and did sleep between polls."""
    from fmcw_cl.opencl import context

    options = Options(chunk_periods=128)
    own = process(static_capture, options, backend)
    naps = []
    sleep = context.time.sleep
    monkeypatch.setattr(context.time, "sleep", lambda s: (naps.append(s), sleep(s)))
    monkeypatch.setattr(backend.rt, "polls", True)
    polled = process(static_capture, options, backend)
    assert naps and max(naps) <= context.POLL_LAST_S and min(naps) == context.POLL_FIRST_S
    assert own.valid.sum() > 0.9 * own.valid.size
    for name in ("distance_m", "velocity_mps", "valid", "distance_uncertainty_m", "displacement_m"):
        np.testing.assert_array_equal(getattr(polled, name), getattr(own, name))
