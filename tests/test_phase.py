"""The displacement from the beat's phase: the peak's phasor (numpy and its kernel), the
unwrapping along time and its slips, and nanometres on simulated captures (static at a
lab's SNR, a creep, the 7 m/s jump) against their truth."""

from __future__ import annotations

from dataclasses import replace

import h5py
import numpy as np
import pytest
from conftest import process
from scipy.interpolate import CubicSpline

from fmcw_cl import displacement, spectrum_ops
from fmcw_cl.simulator import LAB, SimulationConfig, creep, simulate_capture, static
from fmcw_cl.stages import phase
from fmcw_cl.stages.resample import window
from fmcw_cl.track import read_track, write_track

N, NFFT = 1000, 2048
K = phase.radians_per_metre(np.array([193.4e12]))      # rad/m at 1550 nm


def _rows(rng, rows, bins, v, beta, offset, n=N):
    """Windowed tones of `n` points at `bins` with the Doppler phase v beta and the
    phase `offset` at the centre point, under noise."""
    j = np.arange(n) - 0.5 * (n - 1)
    psi = 2 * np.pi * (np.outer(bins, j) / NFFT + np.outer(v, beta)) + offset[:, None]
    return (np.cos(psi) * window(n) * 1000 + rng.normal(0, 1, (rows, n))).astype(np.float32)


def test_phasor_reads_the_phase_at_the_centre():
    """The angle is the tone's phase at the centre point, de-chirped at the velocity,
    and moves by mrad only for a peak 0.1 bin or a velocity 1 mm/s off."""
    rng = np.random.default_rng(1)
    beta = np.linspace(-16, 16, N) + 0.5 * np.linspace(-1, 1, N) ** 2
    bins = rng.uniform(40, 900, 50)
    v = rng.uniform(-7, 7, 50)
    offset = rng.uniform(-np.pi, np.pi, 50)
    x = _rows(rng, 50, bins, v, beta, offset)
    err = np.angle(phase.phasors(x, beta, v, bins, NFFT) * np.exp(-1j * offset))
    # what is left: the real beat's image, de-chirped into a chirp twice as steep (0.7 nm)
    assert np.max(np.abs(err)) < 1e-2 and np.median(np.abs(err)) < 1e-3
    off = np.angle(phase.phasors(x, beta, v + 1e-3, bins + 0.1, NFFT) * np.exp(-1j * offset))
    assert np.max(np.abs(off)) < 0.02
    # without the de-chirp a 7 m/s row's phase is lost
    plain = np.angle(phase.phasors(x, beta, None, bins, NFFT) * np.exp(-1j * offset))
    assert np.max(np.abs(plain)) > 0.5


@pytest.fixture(scope="module")
def backend():
    from fmcw_cl.opencl.processor import OpenCLProcessor

    return OpenCLProcessor()


@pytest.mark.parametrize("rows,points", [(1, N), (37, N), (700, N), (37, 999), (5, 2047)])
def test_kernel_matches_numpy(backend, kernel_variant, rows, points):
    """peak_phasor against its twin, both variants (a work-group a row; a work-item a
    row in float8, its cycles split so that float keeps them): both directions,
    de-chirped and plain, peaks near the band's top (250 cycles a row in float32) and
    near 0 Hz; rows whose points are no multiple of eight, and 2047 of them."""
    rng = np.random.default_rng(rows)
    beta = np.linspace(-16, 16, points)
    bins = rng.uniform(2, 1020, rows)
    v = rng.uniform(-8, 8, rows)
    xr = _rows(rng, rows, bins, v, beta, rng.uniform(-3, 3, rows), points)
    xf = _rows(rng, rows, bins + 3, v, -beta, rng.uniform(-3, 3, rows), points)
    for vel in (v, None):
        got = backend.phasors_each((xr, xf), (beta, -beta), vel, (bins, bins + 3), NFFT)
        want = spectrum_ops.NUMPY.phasors_each((xr, xf), (beta, -beta), vel, (bins, bins + 3), NFFT)
        for g, w, x in zip(got, want, (xr, xf), strict=True):
            scale = np.sum(np.abs(x), axis=1)         # float32 sums of these terms
            assert np.all(np.abs(g - w) <= 1e-5 * scale)
            strong = np.abs(w) > 0.05 * scale
            assert np.max(np.abs(np.angle(g[strong] / w[strong])), initial=0) < 1e-3


def _synthetic(seed, pairs=2000, sigma=0.02, v0=0.3):
    """The phases of both directions of a target moving at v0 + a sine (m/s), with phase
    noise `sigma` (rad), its velocities with 0.2 mm/s of noise."""
    rng = np.random.default_rng(seed)
    t_mid = 50e-6 * np.arange(pairs)
    t_r, t_f = t_mid - 12.5e-6, t_mid + 12.5e-6

    def r(t):
        return 0.3 + v0 * t + 1e-4 * np.sin(2 * np.pi * 40 * t)

    def vel(t):
        return v0 + 1e-4 * 2 * np.pi * 40 * np.cos(2 * np.pi * 40 * t)

    v = vel(t_mid) + rng.normal(0, 2e-4, pairs)
    ph = [1e3 * np.exp(1j * (K * r(t) + c + rng.normal(0, sigma, pairs)))
          for t, c in ((t_r, 0.4), (t_f, -1.1))]
    snr = np.full(pairs, 10 * np.log10(1 / (2 * sigma**2)))
    dist = r(t_mid) + rng.normal(0, 3e-6, pairs)
    return t_r, t_f, ph, snr, dist, v, r(t_mid)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_unwrapping_follows_the_motion(seed):
    """0.3 m/s (19 half wavelengths a period) and a sine: one stretch, nanometres."""
    t_r, t_f, ph, snr, dist, v, truth = _synthetic(seed)
    got = displacement.displacement(t_r, t_f, *ph, snr, snr, dist, v, np.ones(v.size, bool), K)
    assert got.valid.all() and got.stretch.max() == 0
    err = got.metres - (truth - _zero(truth, got))
    assert np.sqrt(np.mean(err**2)) < 5e-9
    assert np.mean(np.abs(err) <= got.uncertainty_m) >= 0.9


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_never_a_hidden_slip(seed):
    """One pair's velocity off by 6 mm/s to 0.3 m/s (its step predicted 1-45 rad
    wrong, some by whole turns in both directions): within every stretch no valid pair
    is a turn off, and the first stretch keeps nanometres; at a low SNR (0.7 rad of
    phase noise) the stretches are many, and none holds a slip."""
    lam4 = np.pi / K
    for dv in (6e-3, 41e-3, 124e-3, 0.3):
        t_r, t_f, ph, snr, dist, v, truth = _synthetic(seed)
        v[700] += dv
        sd = np.full(v.size, 6e-6)
        got = displacement.displacement(t_r, t_f, *ph, snr, snr, dist, v, np.ones(v.size, bool), K, sd)
        _no_slip(got, truth, lam4)
        err = got.metres - (truth - _zero(truth, got))
        assert np.all(np.abs(err[got.stretch == 0]) < 1e-8)
        later = got.valid & (got.stretch > 0)
        assert np.all(np.abs(err[later]) <= got.uncertainty_m[later])
    t_r, t_f, ph, snr, dist, v, truth = _synthetic(seed, sigma=0.7)
    got = displacement.displacement(t_r, t_f, *ph, snr, snr, dist, v, np.ones(v.size, bool), K,
                                    np.full(v.size, 6e-6))
    assert got.stretch.max() >= 2
    _no_slip(got, truth, lam4)


@pytest.mark.parametrize("seed", [1, 2])
def test_stretches_at_once_equal_one_at_a_time(seed):
    """The unwrapping's running sums and the jerk check, every stretch at once
    (numeric.segment_cumsum, a running median of segments), give what a loop over the
    stretches gives, to the bit: on a low SNR's many stretches (0.7 rad of noise)."""
    from fmcw_cl.numeric import running_median, segment_cumsum

    t_r, t_f, (pr, pf), snr, dist, v, _ = _synthetic(seed, sigma=0.7)
    use = np.arange(v.size)
    x, incs, starts, ends = displacement._unwrapped(use, t_r, t_f, np.angle(pr), np.angle(pf), v, (0.0, 0.0),
                                                    K)
    assert starts.size >= 3
    h = 0.5 * (t_f - t_r)
    bent = np.gradient(v, 0.5 * (t_r + t_f)) * (0.5 * h * h)
    want = np.zeros(use.size)
    for a, b in zip(starts, ends, strict=True):
        want[a + 1:b] = 0.5 * (np.cumsum(incs[0][a:b - 1]) + np.cumsum(incs[1][a:b - 1]))
        want[a:b] -= bent[a:b] - bent[a]
    np.testing.assert_array_equal(x, want)
    lo, hi = starts[:-1], ends[:-1] - 1
    want = np.concatenate([np.cumsum(incs[0][a:b]) for a, b in zip(lo, hi, strict=True)])
    np.testing.assert_array_equal(segment_cumsum(incs[0], lo, hi), want)
    t = 0.5 * (t_r + t_f)
    x = x + np.random.default_rng(seed).normal(0, 2e-7, x.size)    # some thirds beyond the bound
    bad = np.zeros(x.size, bool)
    for a, b in zip(starts, ends, strict=True):
        if b - a >= 4:
            d, ts = x[a:b], t[a:b]
            for k in (1, 2, 3):
                d = np.diff(d) / (ts[k:] - ts[:-k])
            third = 6.0 * d * ((ts[3:] - ts[:-3]) / 3.0) ** 3
            hit = np.abs(third - running_median(third, 3)) > np.pi / K
            for k in range(4):
                bad[a + k: b - 3 + k] |= hit
    assert bad.any() and not bad.all()
    np.testing.assert_array_equal(displacement._jerked(x, t, starts, ends, K), bad)


def _vibrating(seed, bias=0.0, pairs=2000, sigma=0.02, outlier=0.0):
    """A target at 0.3 m vibrating 50 um at 1 kHz (0.31 m/s, 1970 m/s^2): both
    directions' phases with `sigma` rad of noise, its velocities with 0.5 mm/s of noise,
    a common `bias` (m/s) and one velocity `outlier` m/s off."""
    rng = np.random.default_rng(seed)
    t_mid = 50e-6 * np.arange(pairs)
    t_r, t_f = t_mid - 12.5e-6, t_mid + 12.5e-6
    w = 2 * np.pi * 1000.0

    def r(t):
        return 0.3 + 50e-6 * np.sin(w * t)

    v = 50e-6 * w * np.cos(w * t_mid) + bias + rng.normal(0, 5e-4, pairs)
    v[pairs // 3] += outlier
    ph = [1e3 * np.exp(1j * (K * r(t) + c + rng.normal(0, sigma, pairs)))
          for t, c in ((t_r, 0.4), (t_f, -1.1))]
    snr = np.full(pairs, 10 * np.log10(1 / (2 * sigma**2)))
    return t_r, t_f, ph, snr, r(t_mid) + rng.normal(0, 3e-6, pairs), v, r(t_mid)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_fast_vibration_is_followed_by_curved_steps(seed):
    """Trapezoids of its velocity miss its steps by up to 2 rad: the stretches break,
    none holds a slip; cubics through four velocities follow it: one stretch, nm."""
    t_r, t_f, ph, snr, dist, v, truth = _vibrating(seed)
    ok = np.ones(v.size, bool)
    straight = displacement.displacement(t_r, t_f, *ph, snr, snr, dist, v, ok, K)
    assert straight.valid.mean() < 0.5
    _no_slip(straight, truth, np.pi / K)
    curved = displacement.displacement(t_r, t_f, *ph, snr, snr, dist, v, ok, K, curved=True)
    assert curved.valid.all() and curved.stretch.max() == 0
    err = curved.metres - (truth - _zero(truth, curved))
    assert np.sqrt(np.mean(err**2)) < 5e-9
    # a wrong velocity (0.1 m/s: its four steps 20 rad off) breaks the stretch, no slip
    t_r, t_f, ph, snr, dist, v, truth = _vibrating(seed, outlier=0.1)
    got = displacement.displacement(t_r, t_f, *ph, snr, snr, dist, v, ok, K, curved=True)
    assert got.valid.mean() > 0.9
    _no_slip(got, truth, np.pi / K)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_velocity_bias_is_taken_off_as_far_as_stated(seed):
    """The velocities' common bias (a sync delay's) moves every step alike: 3 mm/s is
    1.2 rad a step, and the phase noise breaks the stretch again and again. Where the
    delay states 2.9 mm/s (k = 2) it is taken off: one stretch; where it
    states more than 3/8 of a turn a step, nothing is. Biases up to four of the stated
    standard uncertainties end stretches, never hide a turn."""
    ok = np.ones(2000, bool)
    t_r, t_f, ph, snr, dist, v, truth = _vibrating(seed, bias=3e-3, sigma=0.12)
    for stated in (0.0, 5e-3):
        alone = displacement.displacement(t_r, t_f, *ph, snr, snr, dist, v, ok, K, curved=True,
                                          bias_mps=stated)
        assert alone.stretch.max() >= 10
        _no_slip(alone, truth, np.pi / K)
    got = displacement.displacement(t_r, t_f, *ph, snr, snr, dist, v, ok, K, curved=True, bias_mps=2.9e-3)
    assert got.valid.mean() > 0.99 and got.stretch.max() == 0
    _no_slip(got, truth, np.pi / K)
    for bias in (4.5e-3, 5.8e-3, -5.8e-3):
        t_r, t_f, ph, snr, dist, v, truth = _vibrating(seed, bias=bias)
        got = displacement.displacement(t_r, t_f, *ph, snr, snr, dist, v, ok, K, curved=True, bias_mps=2.9e-3)
        _no_slip(got, truth, np.pi / K)


def _zero(truth, stretch):
    """The truth at the displacement's zero: the mean of the first stretch's first pairs
    (`stretch`: a Displacement or its stretches)."""
    stretch = getattr(stretch, "stretch", stretch)
    return np.mean(truth[np.flatnonzero(stretch == 0)[:displacement.ZERO_PAIRS]])


def _no_slip(got, truth, lam4):
    for s in range(got.stretch.max() + 1):
        mine = np.flatnonzero(got.stretch == s)
        rel = got.metres[mine] - got.metres[mine[0]] - (truth[mine] - truth[mine[0]])
        assert np.all(np.abs(rel) < lam4), f"a slip inside stretch {s}"


def _truth_at(capture, times):
    with h5py.File(capture) as f:
        return CubicSpline(f["truth/time_s"][()], f["truth/distance_m"][()])(times)


def _error(capture, track):
    r = _truth_at(capture, track.time_s)
    ok = track.displacement_valid
    if not ok.any():
        return ok, np.full(ok.size, np.nan)
    return ok, track.displacement_m - (r - _zero(r, track.displacement_stretch))


@pytest.mark.parametrize("seed", [1, 2])
def test_static_target_at_a_labs_snr(tmp_path, seed):
    """0.4 m, 50 ms, a lab's instrument (-1 dB per sample at 0.3 m, 20 MHz table
    scatter): std <= 10 nm, >= 95 % valid, the error within its uncertainty."""
    path = tmp_path / "static.h5"
    simulate_capture(path, static(0.05, 0.4), 0.05, seed=seed, config=LAB)
    track = process(path)
    ok, err = _error(path, track)
    assert ok.mean() >= 0.95
    assert np.std(track.displacement_m[ok]) <= 10e-9
    assert np.mean(np.abs(err[ok]) <= track.displacement_uncertainty_m[ok]) >= 0.8
    out = write_track(tmp_path / "t.h5", track)
    back = read_track(out)
    assert np.array_equal(back.displacement_valid, ok)
    assert np.allclose(back.displacement_m[ok], track.displacement_m[ok], rtol=0, atol=0)
    assert back.attrs["displacement_stretches"] == 1


def test_creep_slope_and_error(tmp_path):
    """1 mm/s for 100 ms at the default SNR: the slope within 0.5 %, rms <= 100 nm."""
    path = tmp_path / "creep.h5"
    simulate_capture(path, creep(0.1, 0.3, 1e-3), 0.1, seed=4, config=SimulationConfig())
    track = process(path)
    ok, err = _error(path, track)
    assert ok.mean() >= 0.95
    slope = np.polyfit(track.time_s[ok], track.displacement_m[ok], 1)[0]
    assert slope == pytest.approx(1e-3, rel=5e-3)
    assert np.sqrt(np.mean(err[ok] ** 2)) <= 100e-9


def test_jump_displacement_agrees_with_truth_and_peaks(jump_capture, jump_track):
    """Through the 7 m/s jump: nanometres from the truth where valid, and the peaks'
    distance within their joint uncertainty of the displacement."""
    track = read_track(jump_track)
    ok, err = _error(jump_capture, track)
    assert ok.mean() >= 0.9
    assert np.sqrt(np.mean(err[ok] ** 2)) <= 20e-9
    first = np.flatnonzero(track.displacement_stretch == 0)[0]
    moved = track.distance_m - _zero(track.distance_m, track.displacement_stretch)
    joint = (track.displacement_uncertainty_m + track.distance_uncertainty_m
             + track.distance_uncertainty_m[first])
    assert np.mean(np.abs(moved[ok] - track.displacement_m[ok]) <= joint[ok]) >= 0.95


def test_a_lost_pair_ends_its_stretch(jump_track):
    """objects.invalidate: the displacement after a pair found ambiguous is not valid in
    its stretch (it was followed across that pair)."""
    from fmcw_cl.objects import invalidate

    track = read_track(jump_track)
    ok = np.flatnonzero(track.displacement_valid)
    hit = np.zeros(track.pairs, bool)
    hit[ok[100]] = True
    s = track.displacement_stretch[ok[100]]
    after = (track.displacement_stretch == s) & (np.arange(track.pairs) > ok[100])
    invalidate(track, hit)
    assert not track.displacement_valid[ok[100]]
    assert not track.displacement_valid[after].any()
    assert track.displacement_valid[ok[:100]].all()
    assert np.isnan(track.displacement_m[after]).all()


def test_simulated_phase_follows_the_optical_carrier(tmp_path):
    """The simulator's beat phase moves 2 pi per half wavelength: a target 0.2 um
    further (0.26 turn) reads that much more phase in every pair, to a few mrad (one
    seed: the same noise and scene phase in both)."""
    cfg = replace(SimulationConfig(), sync_delay_samples=0.0, start_phase=0.0)
    phases = []
    for r in (0.3, 0.3 + 0.2e-6):
        path = tmp_path / f"at{r}.h5"
        simulate_capture(path, static(0.004, r), 0.004, seed=5, config=cfg)
        track = process(path)
        phases.append(track.sweep_phase_rad)
        k = track.attrs["displacement_rad_per_m"]
    # each conversion estimates its own sync delay: a grid 0.2 samples apart turns the
    # rising and falling phases by -+0.17 rad, which the pair's mean cancels
    moved = np.angle(np.exp(1j * (phases[1] - phases[0]))).reshape(-1, 2).mean(axis=1)
    assert np.median(moved) == pytest.approx(k * 0.2e-6, abs=5e-3)
    assert np.std(moved) < 5e-3


def test_spectrum_reads_a_vibration():
    """The report's amplitude spectrum: a 1 kHz line of 50 nm over 2 nm of white noise
    (a creep taken off): its frequency, its amplitude within 2 %, the floor in m/sqrt(Hz)."""
    from fmcw_cl.report.figures import displacement_spectrum

    rng = np.random.default_rng(3)
    t = 50e-6 * np.arange(4000)
    x = 50e-9 * np.sin(2 * np.pi * 1000 * t) + 1e-3 * t + rng.normal(0, 2e-9, t.size)
    x[100:103] = np.nan                                       # a gap
    f, asd, amp = displacement_spectrum(t, x)
    line = 1 + np.argmax(amp[1:])
    assert f[line] == pytest.approx(1000, abs=5)
    assert amp[line] == pytest.approx(50e-9, rel=0.02)
    # white noise of 2 nm at 20 kHz: 2 nm / sqrt(10 kHz) = 2e-11 m/sqrt(Hz)
    assert np.median(asd[1:]) == pytest.approx(2e-9 / np.sqrt(1e4), rel=0.3)


def test_report_draws_the_displacement(tmp_path):
    """A creeping target's report holds displacement.png."""
    from fmcw_cl.report import make_report

    path = tmp_path / "creep.h5"
    simulate_capture(path, creep(0.02, 0.3, 1e-3), 0.02, seed=6, config=SimulationConfig())
    out = write_track(tmp_path / "creep.track.h5", process(path))
    got = make_report(out, tmp_path / "report")
    assert str(tmp_path / "report" / "displacement.png") in got["written"]
    assert (tmp_path / "report" / "displacement.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("seed", [1, 2])
def test_speckle_decorrelating_is_refused(tmp_path, seed):
    """A static target whose speckle decorrelates in 3 ms (its amplitude and phase
    wander together: micrometres of false motion over 50 ms) has no valid
    displacement beyond short stretches referred by the peaks, none a turn off beyond
    its uncertainty; without speckle, all of it is valid."""
    path = tmp_path / "speckle.h5"
    simulate_capture(path, static(0.05, 0.3), 0.05, seed=seed, config=SimulationConfig(speckle_s=3e-3))
    track = process(path)
    assert track.attrs["displacement_scintillating_stretches"] >= 1
    ok, err = _error(path, track)
    assert ok.mean() < 0.5
    assert np.all(np.abs(err[ok]) <= np.fmax(track.displacement_uncertainty_m[ok], np.pi / K))


def test_a_small_fast_vibration(tmp_path):
    """1 um at 1 kHz (6 mm/s, 39 m/s^2), 50 ms at 0.3 m: one stretch, nanometres, the
    amplitude read from the spectrum."""
    from fmcw_cl.report.figures import displacement_spectrum, longest_stretch
    from fmcw_cl.simulator import vibration

    path = tmp_path / "vibration.h5"
    simulate_capture(path, vibration(0.05, 0.3, 1e-6, 1000.0), 0.05, seed=7, config=SimulationConfig())
    track = process(path)
    ok, err = _error(path, track)
    assert ok.mean() >= 0.95
    assert np.sqrt(np.mean(err[ok] ** 2)) <= 10e-9
    run = longest_stretch(track)
    f, _, amp = displacement_spectrum(track.time_s[run], track.displacement_m[run])
    line = 1 + np.argmax(amp[1:])
    assert f[line] == pytest.approx(1000, abs=25) and amp[line] == pytest.approx(1e-6, rel=0.05)


@pytest.mark.parametrize("seed", [1, 2])
def test_a_large_fast_vibration(tmp_path, seed):
    """50 um at 1 kHz (0.31 m/s, 1970 m/s^2), 40 ms at 0.3 m: its velocity reverses
    within the tracker's leg-sized windows; the capture is converted over a
    vibration's (fmcw_cl.motion.FAST): every pair valid, the swing's Doppler in the
    mean spectra taken for no other echo, the displacement to nanometres."""
    from fmcw_cl.simulator import vibration

    path = tmp_path / "vibration.h5"
    simulate_capture(path, vibration(0.04, 0.3, 50e-6, 1000.0), 0.04, seed=seed, config=SimulationConfig())
    track = process(path)
    assert track.attrs["motion"] == "fast" and track.valid.mean() >= 0.95
    assert track.attrs["target_choice"] == "one echo: the target"
    ok, err = _error(path, track)
    assert ok.mean() >= 0.95 and np.sqrt(np.mean(err[ok] ** 2)) <= 20e-9
    assert np.mean(np.abs(err[ok]) <= track.displacement_uncertainty_m[ok]) >= 0.9
