"""The velocity bank (stages.bank) and its bodies (fmcw_cl.fast_echoes): movers too
fast for a plain peak, found on the surveyed half-sweeps de-chirped at trial velocities."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import two_movers

from fmcw_cl import engine, fast_echoes
from fmcw_cl.evaluate import best_held, truth_at
from fmcw_cl.simulator.laser import paper_dfb
from fmcw_cl.simulator.scene import glide
from fmcw_cl.spectrum_ops import NUMPY
from fmcw_cl.stages import bank, cfar, doppler, resample, spectrum
from fmcw_cl.stages.lut import build_lut
from fmcw_cl.track import read_track, write_track

HALF_S = 25e-6
PERIOD_S = 50e-6


@pytest.fixture(scope="module")
def backend():
    from fmcw_cl.opencl.processor import OpenCLProcessor

    return OpenCLProcessor()


@pytest.fixture(scope="module")
def shaped():
    cur = np.linspace(0.02, 0.5, 25)
    lut = build_lut(cur, paper_dfb().frequency(cur), 0.16, 0.48, points=1000)
    win = resample.window(1000)
    return win, doppler.doppler_model(lut, HALF_S, spectrum.fft_length(1000), win)


def _pairs(shaped, echoes, pairs: int, seed: int) -> tuple:
    """Resampled rising and falling half-sweeps (windowed, float32) of `pairs` pairs, each
    echo (distance m at the pair's centre, velocity m/s, amplitude over a unit noise)
    moving on at its velocity; and the half-sweeps' centre times (s)."""
    win, m = shaped
    rng = np.random.default_rng(seed)
    t = np.arange(pairs) * PERIOD_S
    t_r, t_f = t - 0.25 * PERIOD_S, t + 0.25 * PERIOD_S
    j = np.arange(win.size)
    cycles = 1.0 / (m.metres_per_bin * m.nfft)          # cycles a point per metre
    xs = []
    for t_half, beta in ((t_r, m.beta_rise), (t_f, m.beta_fall)):
        x = rng.normal(0.0, 1.0, (pairs, win.size))
        for r0, v, amp in echoes:
            r = r0 + v * t_half
            phase = rng.uniform(0, 2 * np.pi, (pairs, 1))
            x += amp * np.cos(2 * np.pi * (np.outer(r * cycles, j) + v * beta[None, :]) + phase)
        xs.append((x * win).astype(np.float32))
    return xs, (t_r, t_f), t


def test_a_fast_mover_the_plain_spectra_miss_is_a_point_of_every_pair(shaped):
    """A mover at 3.1 m/s whose de-chirped peak stands about 22 dB over the noise: its
    plain peak (smeared by 11 dB) is no CFAR echo in most half-sweeps, but every picked
    pair gives a point within 0.3 mm and 0.05 m/s of it; a still wall 30 dB over the
    noise gives none (it solves to 0 m/s at every trial)."""
    win, m = shaped
    mover, wall = (0.21, 3.1, 1.1), (0.40, 0.0, 3.0)
    xs, (t_r, t_f), t = _pairs(shaped, [mover, wall], 24, seed=5)
    rows = np.arange(24)
    lo = 60
    plain = [cfar.detect(spectrum.power_spectra(x, m.nfft), lo) for x in xs]
    for det, k in zip(plain, (m.k_rise, m.k_fall), strict=True):
        at = mover[0] + k * mover[1]
        seen = np.any(np.abs(det.bin * m.metres_per_bin - at) < 0.005, axis=1)
        assert seen.mean() < 0.3
    pts = bank.points(NUMPY.bank_each(xs, (m.beta_rise, m.beta_fall), rows, m.nfft, lo), t_r, t_f, m)
    d, v = pts["fast_distance_m"], pts["fast_velocity_mps"]
    assert np.all(np.abs(d - wall[0]) > 0.02)
    on = (np.abs(d - (mover[0] + mover[1] * pts["fast_time_s"])) < 3e-4) & (np.abs(v - mover[1]) < 0.05)
    assert np.unique(pts["fast_time_s"][on]).size == rows.size


@pytest.mark.parametrize("v", [-5.3, -1.4, 2.2, 6.1])
def test_every_speed_of_the_bank_is_found_within_its_step(shaped, v):
    """Speeds between trials (a quarter step off or more) and at both ends of the bank."""
    win, m = shaped
    xs, (t_r, t_f), _ = _pairs(shaped, [(0.25, v, 1.2)], 8, seed=int(10 * abs(v)))
    pts = bank.points(NUMPY.bank_each(xs, (m.beta_rise, m.beta_fall), np.arange(8), m.nfft, 60), t_r, t_f, m)
    on = np.abs(pts["fast_velocity_mps"] - v) < 0.05
    assert np.unique(pts["fast_time_s"][on]).size == 8


def test_the_device_bank_matches_numpy(shaped, backend, kernel_variant):
    """OpenCLProcessor.bank_each (kernels/fft.cl's spectrum_peak on the picked rows, one
    launch per direction) against stages.bank.detect: the same echoes."""
    win, m = shaped
    xs, _, _ = _pairs(shaped, [(0.21, 3.1, 0.9), (0.33, 0.0, 3.0), (0.12, -1.7, 0.5)], 20, seed=2)
    rows = np.array([0, 3, 4, 9, 19])
    got = backend.bank_each(xs, (m.beta_rise, m.beta_fall), rows, m.nfft, 60)
    want = NUMPY.bank_each(xs, (m.beta_rise, m.beta_fall), rows, m.nfft, 60)
    for g, w in zip(got, want, strict=True):
        assert w.count.shape == (rows.size * bank.TRIALS_MPS.size,) and w.count.sum() > rows.size
        np.testing.assert_array_equal(g.count, w.count)
        np.testing.assert_allclose(g.bin, w.bin, atol=2e-3)
        np.testing.assert_allclose(g.snr_db, w.snr_db, atol=0.02)


def _truth_points(rng, r0: float, v0: float, a: float, t: np.ndarray, miss: float) -> np.ndarray:
    """Points (time, distance, velocity) of one body accelerating at `a`, a share `miss`
    of its picks without one, read with 0.05 mm and 0.01 m/s of noise."""
    keep = rng.random(t.size) >= miss
    tt = t[keep]
    return np.c_[tt, r0 + v0 * tt + 0.5 * a * tt**2 + rng.normal(0, 5e-5, tt.size),
                 v0 + a * tt + rng.normal(0, 0.01, tt.size)]


@pytest.mark.parametrize("seed", [1, 2, 3, 4])
def test_two_crossing_bodies_among_noise_points_are_two_bodies(seed):
    """A hand at +3 m/s and a leg at -2.5 m/s (braking at 40 m/s^2) crossing, a fifth of
    each one's picks missed, and two noise points a pick (anywhere, any velocity): two
    bodies, each on its own truth; the noise alone makes none."""
    rng = np.random.default_rng(seed)
    t = np.arange(0, 0.06, 32 * PERIOD_S)
    hand, leg = (0.08, 3.0, 0.0), (0.33, -2.5, 40.0)
    noise = np.c_[np.repeat(t, 2), rng.uniform(0.03, 0.45, 2 * t.size), rng.uniform(-7, 7, 2 * t.size)]
    every = np.vstack([_truth_points(rng, *hand, t, 0.2), _truth_points(rng, *leg, t, 0.2), noise])
    pts = dict(zip(bank.POINT_KEYS, (*every.T, np.full(len(every), 20.0)), strict=True))
    found = fast_echoes.bodies(pts)
    assert len(found) == 2
    for grid, at, _ in found:
        errs = [np.abs(at - (r0 + v0 * grid + 0.5 * a * grid**2)).max() for r0, v0, a in (hand, leg)]
        assert min(errs) < 1e-3
    alone = dict(zip(bank.POINT_KEYS, (*noise.T, np.full(len(noise), 20.0)), strict=True))
    assert fast_echoes.bodies(alone) == []


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_short_chain_carries_a_bodys_course_on_across_a_fade(seed):
    """A hand at +2.2 m/s seen for 24 ms, lost 8 ms, then three picks (a fade of a weak
    mover at a lab's SNR: movers.py seed 2, capture 12), noise points among them: the
    three are a fragment (fast_echoes.fragments), too short for a body, that carries the
    body's course on (`carried`); not one 10 mm off its motion, nor one 25 ms on."""
    rng = np.random.default_rng(seed)
    pick = 32 * PERIOD_S
    t = np.arange(0, 0.024, pick)
    hand = (0.11, 2.2, 10.0)
    later = 0.032 + pick * np.arange(3)
    noise_t = np.arange(0, 0.07, pick)
    noise = np.c_[noise_t, rng.uniform(0.25, 0.45, noise_t.size), rng.uniform(-7, 7, noise_t.size)]
    every = np.vstack([_truth_points(rng, *hand, t, 0.0), _truth_points(rng, *hand, later, 0.0), noise])
    pts = dict(zip(bank.POINT_KEYS, (*every.T, np.full(len(every), 20.0)), strict=True))
    body, = fast_echoes.bodies(pts)
    short = fast_echoes.fragments(pts)
    assert any(abs(f[0][0] - later[0]) < 1e-9 for f in short)
    got = fast_echoes.carried(body, short)
    assert len(got) == 1 and abs(got[0][0][0] - later[0]) < 1e-9
    r0, v0, a = hand
    off = _truth_points(rng, r0 + 0.01, v0, a, later, 0.0)
    far = _truth_points(rng, *hand, later + 0.025, 0.0)
    for wrong in (off, far):
        f = (wrong[:, 0], wrong[:, 1], wrong[:, 2])
        assert fast_echoes.carried(body, [f]) == []


def test_a_glide_no_tracker_held_is_found_fast_and_followed_along_its_course(tmp_path, monkeypatch):
    """Two glides (movers.py seed 3, capture 18): the second, 4.4 dB stronger, at rest
    then away at up to 3.4 m/s, leaves no plain line, and its candidate's band (from its
    last 40 mm) lost its Doppler-shifted rising peaks: no valid pair. The first
    conversion's table (written and read back) holds its fast stretches as bodies within
    0.1 mm of its truth for 20 ms or more, nothing slower than the bank's floor;
    converted along their course, its object holds 10 % of its visible periods or more
    (0 without), no valid pair off it."""
    from fmcw_cl.capture import Capture

    target = glide(0.7, 0.10501, 0.35304, 0.096, 0.27048)
    other = glide(0.7, 0.07663, 0.33033, 0.05864, 0.20603)
    path = tmp_path / "g.h5"
    made = []
    assemble = engine.assemble
    monkeypatch.setattr(engine, "assemble", lambda *a, **k: made.append(assemble(*a, **k)) or made[-1])
    _, scores = two_movers(path, target, other, 829.5, False, 719, 0.00688, 0.13914)
    assert best_held(scores, 2)[1] >= 0.10
    with Capture(path) as cap:
        truth = cap.truth_objects()[1]
    first = read_track(write_track(tmp_path / "first.track.h5", made[0]))
    found = fast_echoes.bodies(first.echoes.fast)
    on = [g for g, at, _ in found if np.median(np.abs(at - truth_at(truth, g)[0])) < 1e-4]
    assert sum(g[-1] - g[0] for g in on) >= 0.02
    assert np.all(np.abs(first.echoes.fast["fast_velocity_mps"]) >= bank.MIN_MPS)
