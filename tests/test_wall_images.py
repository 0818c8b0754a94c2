"""A fixed echo's image in half-sweeps de-chirped for a moving target (fmcw_cl.wall_images)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from conftest import scene_of

from fmcw_cl import wall_images
from fmcw_cl.physics import C
from fmcw_cl.simulator import paper_dfb
from fmcw_cl.stages import doppler, resample, spectrum
from fmcw_cl.stages.lut import build_lut

WALL_M = 0.09


@pytest.fixture(scope="module")
def shaped():
    cur = np.linspace(0.02, 0.5, 25)
    lut = build_lut(cur, paper_dfb().frequency(cur), 0.16, 0.48, points=1000)
    win = resample.window(1000)
    return lut, win, doppler.doppler_model(lut, 25e-6, spectrum.fft_length(1000), win)


@pytest.mark.parametrize("v", [-6.0, -3.3, -1.0, 0.4, 2.5, 5.0])
def test_the_image_is_where_and_as_strong_as_the_de_chirped_spectrum_shows(shaped, v):
    """A still wall's real beat de-chirped at v: the strongest peak the tracker finds in
    each direction (the tone's or its mirror's image) has the power image_gain_db gives
    at that offset, and no offset is stronger; an image at negative frequencies (the
    de-chirped spectrum's other half) does not show."""
    lut, win, model = shaped
    x = np.cos(2 * np.pi * (lut.nu_hz * 2 * WALL_M / C + 0.3)) * win
    own = spectrum.power_spectra(x[None], model.nfft).max()        # the plain peak
    seen = 0
    for beta in (model.beta_rise, model.beta_fall):
        power = doppler.power(x[None], beta, np.array([v]), model.nfft)[0]
        peak = spectrum.find_peaks(power[None], 1).bin[0] * model.metres_per_bin
        offsets = np.array([peak - WALL_M, peak + WALL_M])          # from the tone, from its mirror
        gains, top = wall_images.image_gain_db(beta, np.full(2, v), offsets, win, model)
        measured = 10 * np.log10(power.max() / own)
        if gains.max() < -40:           # both images at negative frequencies: none to see
            assert measured < -40
            continue
        seen += 1
        assert measured == pytest.approx(gains.max(), abs=0.3)
        assert gains.max() == pytest.approx(top[0], abs=0.3)       # the peak is the image's top
        grid = np.arange(-0.3, 0.3, model.metres_per_bin)
        everywhere, _ = wall_images.image_gain_db(beta, np.full(grid.size, v), grid, win, model)
        assert everywhere.max() <= gains.max() + 0.3
    assert seen >= 1


def test_a_peak_is_confused_with_an_image_only_where_the_image_is_as_strong(shaped):
    """Falling half-sweeps de-chirped at -3.3 m/s beside a wall at 30 dB: a peak at the
    image's top is confused when the image there comes within IMAGE_MARGIN_DB of it,
    not when it is stronger by more; a peak on the image's tail (6 dB under its top) as
    strong as the image there is not; nor is one far from the image, nor a pair not
    asked about, nor a rising half-sweep (its image lies elsewhere). The echo's level
    is its pair's weaker peak: a falling peak stronger by more than the margin whose
    rising one reads 10 dB is the image's, added to a weak echo."""
    lut, win, model = shaped
    v = np.full(6, -3.3)
    grid = WALL_M - v[0] * model.k_fall + np.arange(-0.05, 0.05, model.metres_per_bin)
    gain, top = wall_images.image_gain_db(model.beta_fall, v[:1].repeat(grid.size), grid - WALL_M, win, model)
    at = grid[np.argmax(gain)]                                  # the image's top
    tail = grid[np.flatnonzero(gain >= top[0] - 6.0)[-1] + 2]   # just outside its -6 dB span
    level = 30.0 + top[0]
    margin = wall_images.IMAGE_MARGIN_DB
    fall = np.array([at, at, at + 0.15, at, tail, at])
    snr_fall = np.array([level + margin - 0.5, level + margin + 0.5, 15.0, level - 1.0,
                         30.0 + float(np.interp(tail, grid, gain)), level + margin + 0.5])
    snr_rise = np.r_[snr_fall[:5], 10.0]
    rows = np.array([True, True, True, False, True, True])
    got = wall_images.confused(v, (np.full(6, 0.25), fall), (snr_rise, snr_fall), np.array([WALL_M]),
                               np.array([30.0]), model, win, rows)
    assert got.tolist() == [True, False, False, False, False, True]


def test_a_landing_never_follows_a_walls_image(tmp_path):
    """benchmarks/hunt.py seed 8, capture 20: a landing (-5 m/s at 0.14 m) weak beside a
    wall of 1500 codes at 0.087 m left out of its band. After a 1.4 ms fade its falling
    half-sweeps' peak (folded to the lowest bins) was gone, and the tracker followed the
    wall's image de-chirped at -3.3 m/s for 2.2 ms: 41 valid pairs 45 mm off, their
    velocities consistent with their distances, on both processors."""
    from fmcw_cl.backend import make_processor
    from fmcw_cl.capture import Capture
    from fmcw_cl.engine import process
    from fmcw_cl.evaluate import valid_errors
    from fmcw_cl.simulator import LAB, jump, simulate_capture

    path = tmp_path / "landing.h5"
    walls = ((0.44587680401798757, 150.0), (0.08681912414824695, 1500.0))
    simulate_capture(path, jump(0.3), 0.05, seed=654, config=replace(LAB, reflectors=walls), start_s=0.18)
    with Capture(path) as cap:
        truth = cap.truth()
    for backend in ("numpy", "opencl"):
        track = process(path, processor=make_processor(backend))
        assert np.sum(valid_errors(track, truth) > 2e-3) == 0, backend
        assert track.valid.mean() > 0.08, backend                 # the right pairs stand (10.1 %)
        assert "0.087" in track.attrs["target_choice"]            # the wall was left out


def test_a_weak_walls_image_reads_its_power_and_the_noise(shaped):
    """Levels are peaks read over the floor: a tone's power plus the noise's. A wall
    read at 7 dB, its image 11.7 dB under, reads 1.0 dB where its top lies (a sum in
    dB, -4.7 dB, missed the K = 32 integrated peak that was the image, at 2.7 dB:
    benchmarks/hunt.py seed 24, capture 50); a strong wall's image reads as the sum."""
    lut, win, model = shaped
    assert wall_images.image_level_db(7.0, -11.7) == pytest.approx(1.04, abs=0.01)
    assert wall_images.image_level_db(40.0, -11.7) == pytest.approx(28.3, abs=0.01)
    assert wall_images.image_level_db(0.0, 0.0) == 0.0              # noise alone: no image
    v = np.full(2, 3.04)
    grid = WALL_M - v[0] * model.k_fall + np.arange(-0.05, 0.05, model.metres_per_bin)
    gain, top = wall_images.image_gain_db(model.beta_fall, np.full(grid.size, v[0]), grid - WALL_M, win,
                                          model)
    at = grid[np.argmax(gain)]
    got = wall_images.confused(v, (np.full(2, 0.3), np.full(2, at)), (np.full(2, 5.0), np.array([2.7, 8.0])),
                               np.array([WALL_M]), np.array([7.0]), model, win, np.ones(2, bool))
    assert got.tolist() == [True, False]


def test_a_movers_image_is_as_strong_as_its_level_in_that_direction(shaped):
    """A mover at 0.29 m, +1.95 m/s, seen from a pair de-chirped at -1.7 m/s whose rising
    peak lies at the mover's image's top: given the mover's level per direction, the
    pair is confused where its rising level makes the image strong enough (3 dB over
    its median: its own half-sweeps there read it so, movers.py seed 17, capture 15),
    not at the median alone, nor where only its falling level is louder (that
    direction's image lies elsewhere)."""
    lut, win, model = shaped
    v, u, at_m = np.full(3, -1.7), np.full(3, 1.95), np.full(3, 0.29)
    rel = v[0] - u[0]
    grid = at_m[0] - rel * model.k_rise + np.arange(-0.06, 0.06, model.metres_per_bin)
    gain, top = wall_images.image_gain_db(model.beta_rise, np.full(grid.size, rel), grid - at_m[0], win,
                                          model)
    peak = grid[np.argmax(gain)]
    median = 20.0
    own = float(wall_images.image_level_db(median, top[0])) + wall_images.IMAGE_MARGIN_DB + 1.0
    peaks, snr = (np.full(3, peak), np.full(3, 0.15)), (np.full(3, own), np.full(3, own + 3))
    rows = np.ones(3, bool)
    assert not wall_images.confused_moving(v, peaks, snr, at_m, u, median, model, win, rows).any()
    levels = np.array([[median, median + 3.0, median], [median, median, median + 3.0]])
    got = wall_images.confused_moving(v, peaks, snr, at_m, u, levels, model, win, rows)
    assert got.tolist() == [False, True, False]


@pytest.mark.parametrize("seed", [532, 533])
def test_a_take_off_past_a_weak_wall_under_full_scale_noise_makes_no_phantom(tmp_path, seed):
    """benchmarks/hunt.py seed 24, capture 50 (and the next seed of the simulator): a
    take-off at 5 m/s towards a wall of 400 codes at 0.255 m, noise at full scale. Its
    weak echoes integrated (K = 32), one pair's rising peak was the foot's and its falling
    one the wall's image: 27 (22) valid pairs at 3.0 (1.6) m/s, 65 (49) mm short of the
    foot, an object of their own. On OpenCL, the processor it was found on."""
    from fmcw_cl.backend import make_processor
    from fmcw_cl.engine import process
    from fmcw_cl.simulator import LAB, jump, simulate_capture

    path = tmp_path / "take_off.h5"
    lab = replace(LAB, reflectors=((0.25472898298392943, 400.0),), noise_codes=3000.0, headroom=None)
    simulate_capture(path, jump(0.3), 0.05, seed=seed, config=lab, start_s=0.06)
    scores = scene_of(process(path, processor=make_processor("opencl")), path)
    assert {s["truth"] for s in scores if s["tracked"] > 0.2} == {0, 1}       # the foot and the wall


def test_a_weak_wall_beside_a_rail_holds_no_blend(tmp_path):
    """benchmarks/hunt.py seed 30, capture 24: a rail at 0.7 m/s 17-22 mm beyond a wall of
    150 codes, whose rising half-sweeps hold the rail's image (its raw peak) 25-26.5 dB
    over the floor, 12-18 dB over the wall's own falling peaks. Measured against the
    rising peaks the image made, it passed as 3.5-5 dB under them: 34 of the wall's pairs
    stood, 0.6-2.0 mm off at 0.06 m/s. On OpenCL, the processor it was found on."""
    from fmcw_cl.backend import make_processor
    from fmcw_cl.engine import process
    from fmcw_cl.simulator import LAB, rail, simulate_capture

    path = tmp_path / "rail.h5"
    lab = replace(LAB, reflectors=((0.05637574048233334, 150.0),))
    simulate_capture(path, rail(0.4), 0.05, seed=658, config=lab, start_s=0.05)
    scores = scene_of(process(path, processor=make_processor("opencl")), path)
    assert max(s["tracked"] for s in scores if s["truth"] == 0) > 0.3           # the rail (37 %)


def test_pairs_no_image_can_reach_take_no_spectrum_and_lose_nothing(shaped, monkeypatch):
    """`confused` and `confused_moving` skip the spectra of pairs that an image at the
    window's whole power could not reach within the margin (`_may_reach`); on pairs
    whose levels lie on both sides of that bound, near the images and far from them,
    the answers are those of taking every spectrum, and some pairs were skipped."""
    lut, win, model = shaped
    rng = np.random.default_rng(5)
    n = 400
    v = np.r_[rng.uniform(-0.05, 0.05, n // 2), rng.uniform(-5.0, 5.0, n // 2)]   # images sharp and smeared
    peaks = tuple(WALL_M - v * k + rng.normal(0.0, 2e-4, n) for k in (model.k_rise, model.k_fall))
    # levels about the image's top there (30 dB + its gain), within the margin and beyond
    snr = tuple(30.0 + wall_images.image_gain_db(beta, v, np.zeros(n), win, model)[1]
                + rng.uniform(-4.0, 4.0, n) for beta in (model.beta_rise, model.beta_fall))
    rows = rng.random(n) < 0.9
    walls_db = np.array([30.0])
    other_m, other_mps = np.full(n, WALL_M), np.full(n, 0.3)
    got = (wall_images.confused(v, peaks, snr, np.array([WALL_M]), walls_db, model, win, rows),
           wall_images.confused_moving(v, peaks, snr, other_m, other_mps, 30.0, model, win, rows))
    own = np.fmin(*snr)
    assert 0 < wall_images._may_reach(30.0, own).mean() < 1
    monkeypatch.setattr(wall_images, "_may_reach", lambda level_db, own_db: np.ones(np.broadcast(
        level_db, own_db).shape, bool))
    every = (wall_images.confused(v, peaks, snr, np.array([WALL_M]), walls_db, model, win, rows),
             wall_images.confused_moving(v, peaks, snr, other_m, other_mps, 30.0, model, win, rows))
    assert got[0].tolist() == every[0].tolist() and got[0].any()
    assert got[1].tolist() == every[1].tolist() and got[1].any()


def test_the_de_chirped_window_is_the_window_times_the_basis(shaped):
    """`_dechirped` (cosine and sine of the real phase) gives window * exp(-2 pi i v
    beta), the values exp gives, to its last bits here."""
    lut, win, model = shaped
    v = np.array([-7.3, -0.005, 0.0, 0.4, 5.0])[:, None]
    want = win * np.exp(-2j * np.pi * v * model.beta_rise)
    np.testing.assert_allclose(wall_images._dechirped(win, v, model.beta_rise), want, rtol=1e-14, atol=1e-15)
