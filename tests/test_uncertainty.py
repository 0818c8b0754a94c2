"""Per-pair uncertainty and validity per quantity (fmcw_cl.uncertainty): the sources
on arrays whose answer is known, and the coverage on captures of a lab's kind."""

from __future__ import annotations

from dataclasses import replace

import h5py
import numpy as np
import pytest
from conftest import process

from fmcw_cl.capture import Capture
from fmcw_cl.evaluate import truth_at
from fmcw_cl.report import make_report
from fmcw_cl.simulator import LAB, SimulationConfig, jump, rail, simulate_capture, static
from fmcw_cl.track import OPTIONAL_PAIR_DATASETS, read_track, write_track
from fmcw_cl.uncertainty import (
    SLOPE_MIN_PAIRS,
    budget_from_attrs,
    correlated_scatter,
    course_scatter,
    distance_slope,
    local_scatter,
    transferred_mps,
    velocity_verified,
)

T = 50e-6


def motion(n: int, seed: int, sigma_m: float = 5e-6, sigma_mps: float = 1e-3):
    """A target accelerating at 300 m/s^2 from 2 m/s, sampled every T, with white noise
    on its distances and velocities."""
    rng = np.random.default_rng(seed)
    t = T * np.arange(n)
    d = 0.2 + 2.0 * t + 150.0 * t * t + rng.normal(0, sigma_m, n)
    v = 2.0 + 300.0 * t + rng.normal(0, sigma_mps, n)
    return t, d, v


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_local_scatter_is_the_noise_not_the_motion(seed):
    _, d, v = motion(2000, seed)
    ok = np.ones(d.size, bool)
    ok[700:703] = False
    s = local_scatter(d, ok)
    assert np.all(np.isnan(s[700:703]))
    assert 4.0e-6 < np.nanmedian(s) < 6.0e-6     # 5 um drawn; 300 m/s^2 adds 0.75 um a second difference
    assert 0.8e-3 < np.nanmedian(local_scatter(v, ok)) < 1.2e-3


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_correlated_scatter_sees_errors_correlated_over_a_few_pairs(seed):
    # distance errors correlated +0.50, +0.33, +0.18 at 1-3 pairs (a moving average of
    # four; the rail's read +0.3, +0.2, +0.1), a 5 um standard deviation, on a target
    # accelerating at 300 m/s^2
    t, d, _ = motion(4000, seed, sigma_m=0.0)
    rng = np.random.default_rng(seed)
    taps = np.array([1.0, 0.45, 0.35, 0.25])
    e = np.convolve(rng.normal(0, 1, d.size + 3), taps, "valid")
    d = d + 5e-6 * e / np.sqrt(np.sum(taps**2))
    ok = np.ones(d.size, bool)
    ok[1500:1503] = False
    acc = np.where(ok, 300.0, np.nan)
    white = np.nanmedian(local_scatter(d, ok))
    seen = correlated_scatter(d, ok, acc, T)
    assert white < 4.4e-6                              # neighbours' differences read it low
    assert 4.6e-6 < np.nanmedian(seen) < 5.6e-6
    assert np.all(np.isnan(seen[1500:1503]))
    # the motion's a (4 T)^2 = 12 um is taken off, not read as noise
    assert np.nanmedian(correlated_scatter(d, ok, np.zeros(d.size), T)) > 1.3 * np.nanmedian(seen)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_course_scatter_sees_velocity_errors_that_wander(seed):
    """Velocity errors of 0.1 mm/s like a static target's under speckle decorrelating in
    3 ms (a third of their variance a moving average of 16 pairs: correlated +0.3 at one
    pair, +0.25 at four, +0.15 at eight), on a velocity of constant jerk: neighbours'
    second differences read under 0.85 of them, the residuals about the course 0.88-1.1;
    the motion alone reads nothing."""
    n = 6000
    t = T * np.arange(n)
    v = 2.0 + 300.0 * t - 2e3 * t * t
    rng = np.random.default_rng(seed)
    e = np.sqrt(0.65) * rng.normal(0, 1, n) + np.sqrt(0.35) * np.convolve(rng.normal(0, 1, n + 15),
                                                                          np.ones(16), "valid") / 4.0
    ok = np.ones(n, bool)
    ok[2000:2003] = False
    seen = course_scatter(v + 1e-4 * e, ok, 21)
    assert np.nanmedian(local_scatter(v + 1e-4 * e, ok)) < 0.85e-4
    assert 0.88e-4 < np.nanmedian(seen) < 1.1e-4
    assert np.all(np.isnan(seen[2000:2003]))
    assert np.nanmax(course_scatter(v, ok, 21)) < 1e-9


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_delay_refined_on_another_echo_passes_its_bias_on(seed):
    """A target whose velocities read 0.25 mm/s off (the delay refined on a wall's
    fold): its own kinematic mismatch states it, where the delay was refined outside
    its span; a consistent accelerating track states about its error; refined on the
    pairs themselves, or without a run long enough to measure, nothing."""
    t, d, v = motion(2000, seed, sigma_m=2e-6, sigma_mps=1e-4)
    ok = np.ones(d.size, bool)
    ok[900:903] = False
    off = transferred_mps(t, d, v - 2.5e-4, ok, refined_at_m=0.45 + d.max())
    assert 2.0e-4 < off < 3.0e-4
    assert transferred_mps(t, d, v, ok, refined_at_m=0.45 + d.max()) < 5e-5
    assert transferred_mps(t, d, v - 2.5e-4, ok, refined_at_m=float(np.median(d))) == 0.0
    short = np.zeros(d.size, bool)
    short[::50] = True
    assert transferred_mps(t, d, v - 2.5e-4, short, refined_at_m=0.45 + d.max()) == 0.0


def test_slope_of_a_quadratic_course_and_its_gain():
    t, d, _ = motion(200, 1, sigma_m=0.0)
    ok = np.ones(d.size, bool)
    ok[100] = False
    ok[150:170] = False
    ok[160:160 + SLOPE_MIN_PAIRS - 1] = True          # a run too short to check
    slope, gain = distance_slope(d, ok, T)
    run = np.r_[0:100, 101:150, 170:200]
    assert np.allclose(slope[run], 2.0 + 300.0 * t[run], rtol=0, atol=1e-6)
    assert np.all(np.isnan(slope[~ok])) and np.all(np.isnan(slope[160:170]))
    # the centred window's gain is 1 / (T sqrt(sum k^2)); the ends' are larger
    assert gain[50] == pytest.approx(1 / (T * np.sqrt(np.sum(np.arange(-10, 11) ** 2))), rel=1e-9)
    assert gain[0] > 3 * gain[50]


@pytest.mark.parametrize("seed", [1, 2])
def test_a_velocity_off_its_distances_course_is_not_verified(seed):
    t, d, v = motion(600, seed)
    ok = np.ones(d.size, bool)
    ok[400:410] = False
    v = v.copy()
    v[200:230] += 0.08            # a delay fault's or a neighbouring echo's velocity, distances right
    got = velocity_verified(d, v, ok, T, local_scatter(d, ok), local_scatter(v, ok))
    assert not got[200:230].any()
    assert got[:180].all() and got[250:400].all() and got[410:].all()
    assert not got[400:410].any()


QUANTITIES = (("distance", "distance_m", "distance_uncertainty_m", "valid"),
              ("velocity", "velocity_mps", "velocity_uncertainty_mps", "velocity_valid"),
              ("acceleration", "acceleration_mps2", "acceleration_uncertainty_mps2", "acceleration_valid"))


def pooled(tracks_truths):
    """Per quantity: share of valid pairs within their k = 2 uncertainty, and median
    uncertainty over the rms error, over all the captures together."""
    out = {}
    for name, value, unc, flag in QUANTITIES:
        err, u = [], []
        for track, truth in tracks_truths:
            ok = getattr(track, flag)
            true = truth_at(truth, track.time_s)[[q[0] for q in QUANTITIES].index(name)]
            err.append(np.abs(getattr(track, value) - true)[ok])
            u.append(getattr(track, unc)[ok])
        err, u = np.concatenate(err), np.concatenate(u)
        out[name] = (float(np.mean(err <= u)), float(np.median(u) / np.sqrt(np.mean(err**2))), err, u)
    return out


def convert(tmp_path, scenes, seeds):
    got = []
    for i, (traj, dur, start, cfg) in enumerate(scenes):
        for seed in seeds:
            path = tmp_path / f"c{i}-{seed}.h5"
            simulate_capture(path, traj, dur, seed=seed, config=cfg, start_s=start)
            track = process(path)
            assert track.valid.mean() > 0.95
            with Capture(path) as cap:
                got.append((track, cap.truth()))
    return pooled(got)


def test_uncertainties_cover_a_moving_target(tmp_path):
    """Valid pairs within their expanded uncertainty (k = 2) on the rail's start and the
    jump's landing at a lab's SNR, two seeds the benchmark does not use; the median
    uncertainty at most 3x the rms error. The goal is 95 % of the pairs; here 94.1 %
    (benchmarks/uncertainty.py, seeds 1-6: 95.7-97.3 %): the scale's error is one draw
    per capture, so four captures pass or miss it together."""
    landing = (jump(0.3), 0.05, 0.18, replace(LAB, speckle_s=3e-3))
    res = convert(tmp_path, [(rail(0.4), 0.05, 0.05, LAB), landing], (5, 6))
    assert res["distance"][0] >= 0.93 and res["distance"][1] <= 3.0
    assert res["velocity"][0] >= 0.95 and res["velocity"][1] <= 3.5
    assert res["acceleration"][0] >= 0.95 and res["acceleration"][1] <= 3.0
    assert np.all(res["acceleration"][2] <= 3 * res["acceleration"][3])


def test_uncertainties_cover_a_static_target(tmp_path):
    """A static target's error is mostly the distance scale's: one draw of the G(I)
    table per capture, the same for all its pairs, so its coverage is counted over
    captures: twelve of them, both instruments, six seeds."""
    res = convert(tmp_path, [(static(0.02, 0.3), 0.02, 0.0, cfg) for cfg in (SimulationConfig(), LAB)],
                  range(1, 7))
    assert res["distance"][0] >= 0.9 and res["distance"][1] <= 3.0
    assert res["velocity"][0] >= 0.95 and res["velocity"][1] <= 3.0
    assert res["acceleration"][0] >= 0.95 and res["acceleration"][1] <= 3.0


def test_the_track_file_carries_validity_and_uncertainty(tmp_path, jump_track, jump_capture):
    track = read_track(jump_track)
    assert track.velocity_valid is not None and track.distance_uncertainty_m is not None
    assert not np.any(track.velocity_valid & ~track.valid)
    assert not np.any(track.acceleration_valid & ~track.velocity_valid)
    assert np.all(np.isnan(track.distance_uncertainty_m[~track.valid]))
    assert np.all(np.isfinite(track.distance_uncertainty_m[track.valid]))
    assert np.all(np.isfinite(track.velocity_uncertainty_mps[track.velocity_valid]))
    # the jump at the default instrument's SNR: every valid pair within 3x its uncertainty.
    # Its velocities share one draw of the sync delay's error (here 1.2 of its sigmas: -0.04
    # mm/s at rest, where the noise is 0.03), so one capture's velocity coverage is a draw
    # too (94.8 %; pooled over 12 seeds, benchmarks/uncertainty.py: 95.5-98.6 %)
    with Capture(jump_capture) as cap:
        res = pooled([(track, cap.truth())])
    assert np.all(res["distance"][2] <= 3 * res["distance"][3])
    assert res["distance"][0] >= 0.95 and res["velocity"][0] >= 0.93 and res["acceleration"][0] >= 0.95
    assert np.all(res["velocity"][2] <= 3 * res["velocity"][3])
    assert np.all(res["acceleration"][2] <= 3 * res["acceleration"][3])
    names = [name for name, _, _ in budget_from_attrs(track.attrs, "distance")]
    assert names == ["noise", "scale", "resampling", "sync delay", "model", "integration", "combined"]
    shares = [s for _, _, s in budget_from_attrs(track.attrs, "distance")[:-1]]
    assert sum(shares) == pytest.approx(1.0)

    # a track written before these datasets: its velocities as valid as its distances
    old = tmp_path / "old.track.h5"
    write_track(old, track)
    with h5py.File(old, "r+") as f:
        for name in OPTIONAL_PAIR_DATASETS:
            del f["track"][name]
    back = read_track(old)
    assert np.array_equal(back.velocity_valid, back.valid) and back.distance_uncertainty_m is None


def test_report_writes_the_budget(tmp_path, jump_track, jump_capture):
    out = make_report(jump_track, tmp_path / "rep", capture=jump_capture)
    assert str(tmp_path / "rep" / "uncertainty.md") in out["written"]
    text = (tmp_path / "rep" / "uncertainty.md").read_text()
    assert "| noise |" in text and "| sync delay |" in text and "| time base |" in text
    row = next(line for line in text.splitlines() if line.startswith("| distance |"))
    assert float(row.split("|")[3].strip().rstrip(" %")) >= 95.0


def test_no_acceleration_is_centred_in_a_run_shorter_than_its_window():
    from fmcw_cl.stages.kinematics import WINDOW_PAIRS, centred

    ok = np.zeros(100, bool)
    ok[:5] = True                      # a short run at the start: its end index less half a window is < 0
    ok[40:40 + WINDOW_PAIRS] = True
    got = centred(ok)
    assert np.flatnonzero(got).tolist() == [40 + WINDOW_PAIRS // 2]


def test_the_resampling_bound_grows_with_the_beat_frequency():
    from fmcw_cl.uncertainty import resampling_m

    d = np.array([0.1, 0.3, 0.45, 0.8])
    u = resampling_m(d, 1 / (0.937e-3 * 2500), 0.937e-3)
    assert np.all(np.diff(u) > 0)
    # a noise-free table's static biases (seeds 1-5): within 1 um at 0.1-0.3 m, up to
    # 5.6 um at 0.45 m; the bound (sqrt 3 u) holds the latter
    assert 0.5e-6 < np.sqrt(3) * u[1] < 5e-6 and 5.6e-6 < np.sqrt(3) * u[2] < 15e-6


def _uncertainty_of(integrated: np.ndarray, period_ratio: float = 1.0):
    """pair_uncertainty of 2000 noise-free pairs accelerating at 300 m/s^2."""
    from fmcw_cl.uncertainty import pair_uncertainty

    t, d, v = motion(2000, 1, sigma_m=0.0, sigma_mps=0.0)
    n = d.size
    ok = np.ones(n, bool)
    zero = np.zeros(n)
    return pair_uncertainty(d, v, ok, ok, zero, zero, np.full(n, 1e-7), np.full(n, 300.0), zero,
                            integrated, period_s=T, scale_ppm=0.0, delay_m=0.0, delay_mps=0.0,
                            period_ratio=period_ratio)


def test_a_single_pairs_velocity_carries_no_integration_smear():
    """A pair's two half-sweeps give their mean velocity, which under a steady
    acceleration is the truth at the pair's centre: no integration term at K = 1 (it
    made a clean jump's velocity uncertainty 13x its error); K half-sweeps summed along
    the tracked velocity keep a K T / sqrt(12)."""
    single = _uncertainty_of(np.ones(2000))
    assert np.all(single.velocity_sources["integration"] == 0.0)
    summed = _uncertainty_of(np.full(2000, 16))
    assert np.allclose(summed.velocity_sources["integration"], 300.0 * 16 * T / np.sqrt(12))
    assert np.all(summed.velocity_mps > single.velocity_mps)


def test_an_accelerations_uncertainty_holds_a_wrong_clock():
    """A clock 1 % off scales a 300 m/s^2 acceleration by about 2 %: 6 m/s^2, held in
    its uncertainty (k = 2: 12 m/s^2), none where the clock is right."""
    from fmcw_cl.uncertainty import acceleration_uncertainty

    n = 400
    a = np.full(n, 300.0)
    ok = np.ones(n, bool)
    right = acceleration_uncertainty(a, ok, np.zeros(n), T)
    wrong = acceleration_uncertainty(a, ok, np.zeros(n), T, period_ratio=1.01)
    assert np.allclose(right[20:-20], 0.0)
    assert np.allclose(wrong[20:-20], 2 * 2 * 0.01 * 300.0)


def _acceleration_coverage(wander_mps: float, seed: int) -> tuple[float, float, float]:
    """Velocities of a steady 300 m/s^2 with white noise (0.1 mm/s) and a wander over a
    few pairs (`wander_mps` rms): the share of accelerations within their uncertainty
    from the white noise alone and with the measured scatter, and the median of the
    latter over the former."""
    from scipy.ndimage import gaussian_filter1d

    from fmcw_cl.stages import kinematics
    from fmcw_cl.uncertainty import acceleration_uncertainty, derivative_scatter, local_scatter

    rng = np.random.default_rng(seed)
    n = 3000
    ok = np.ones(n, bool)
    wander = gaussian_filter1d(rng.normal(0, 1, n), 3.0)
    v = 300.0 * T * np.arange(n) + 1e-4 * rng.normal(0, 1, n) + wander_mps * wander / wander.std()
    a = kinematics.acceleration(v, ok, T)
    err = np.abs(a - 300.0)
    noise = local_scatter(v, ok)
    white = acceleration_uncertainty(a, ok, noise, T)
    both = acceleration_uncertainty(a, ok, noise, T, scatter_mps2=derivative_scatter(v, ok, T))
    inner = np.isfinite(a) & np.isfinite(white)
    return (float(np.mean(err[inner] <= white[inner])), float(np.mean(err[inner] <= both[inner])),
            float(np.median(both[inner] / white[inner])))


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_an_accelerations_uncertainty_holds_velocities_that_wander(seed):
    """Velocities whose errors wander over a few pairs (as a jump's do at speed) move
    the acceleration far beyond what their second differences state; the measured
    scatter of the derivative holds it. White noise alone: the same uncertainty as
    before, within a third."""
    white, both, _ = _acceleration_coverage(3e-4, seed)
    assert white < 0.6
    assert both >= 0.95
    white, both, ratio = _acceleration_coverage(0.0, seed)
    assert white >= 0.9 and both >= 0.9
    assert ratio <= 1.35
