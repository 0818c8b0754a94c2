"""Chirp self-calibration (issue: thermal lag of the DFB's tuning): calibrated on one
static capture, applied to other captures of the same laser."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from conftest import process, two_movers

import fmcw_cl
from fmcw_cl.calibration import measure_chirp
from fmcw_cl.capture import Capture
from fmcw_cl.chirp import Chirp, Direction, read_chirp, write_chirp
from fmcw_cl.errors import CaptureError
from fmcw_cl.evaluate import accuracy, best_held
from fmcw_cl.options import Options
from fmcw_cl.plan import make_plan
from fmcw_cl.simulator import SimulationConfig, jump, simulate_capture, static
from fmcw_cl.simulator.writer import thermal_offset
from fmcw_cl.track import read_track

LAGS_US = (0.5, 2.0, 5.0)


def lagged(path, trajectory, duration, seed, lag_us, start=0.0):
    cfg = replace(SimulationConfig(), thermal_lag_s=lag_us * 1e-6)
    simulate_capture(path, trajectory, duration, seed=seed, config=cfg, start_s=start)
    return path


@pytest.fixture(scope="module", params=LAGS_US, ids=lambda x: f"lag{x}us")
def setup(request, tmp_path_factory):
    lag = request.param
    d = tmp_path_factory.mktemp(f"lag{lag}")
    cal = lagged(d / "cal.h5", static(0.02, 0.3), 0.02, 101, lag)
    chirp = write_chirp(d / "chirp.h5", fmcw_cl.calibrate(cal, 0.3))
    return lag, d, chirp


def test_calibration_measures_the_shrunk_sweep(setup):
    lag, _, chirp_file = setup
    chirp = read_chirp(chirp_file)
    # the true optical sweep of the simulated laser (G over the lagged current)
    phase = np.linspace(0, 1, 200_001)
    tri = np.where(phase < 0.5, 2 * phase, 2 - 2 * phase)
    x, _ = thermal_offset(phase, lag * 1e-6, 50e-6, 0.32)
    cfg = SimulationConfig()
    nu = cfg.laser.frequency(0.16 + 0.32 * tri + cfg.thermal_fraction * x)
    true_b = nu.max() - nu.min()
    assert 0.93 * true_b < chirp.bandwidth_hz <= true_b      # the steep part of the true sweep
    assert chirp.attrs["residual_phase_rad"] < 0.2 and chirp.attrs["periods_used"] >= 350


def test_static_elsewhere(setup):
    lag, d, chirp = setup
    other = lagged(d / f"static_{lag}.h5", static(0.02, 0.18), 0.02, 202, lag)
    track = process(other, Options(chirp=str(chirp)))
    with Capture(other) as cap:
        acc = accuracy(track, cap.truth())
    assert acc["valid_share"] >= 0.99
    assert abs(acc["distance_bias_m"]) <= 0.2e-3 and acc["distance_std_m"] <= 0.05e-3
    assert track.attrs["sync_delay_refined"] and track.attrs["chirp"].endswith("chirp.h5")
    assert track.attrs["tuning_matches"] and track.attrs["tuning_peak_width_ratio"] < 1.1


def test_jump_takeoff(setup):
    lag, d, chirp = setup
    take_off = lagged(d / f"jump_{lag}.h5", jump(0.3), 0.06, 303, lag, start=0.05)
    track = process(take_off, Options(chirp=str(chirp)))
    with Capture(take_off) as cap:
        acc = accuracy(track, cap.truth())
    assert acc["valid_share"] >= 0.98
    assert acc["distance_p95_m"] <= 0.5e-3
    assert acc["velocity_p95_mps"] <= 0.02


def test_without_calibration_the_lag_hurts(tmp_path):
    """The effect is real: 2 us of lag with the static table. The delay's refinement
    takes the velocity's bias out by moving the delay far from the intensity estimate
    (the lag looks like a delay to the velocity), but the distance stays biased and the
    peaks smeared: the tuning check gives it away."""
    cap = lagged(tmp_path / "st.h5", static(0.02, 0.3), 0.02, 5, 2.0)
    track = process(cap)
    a = track.attrs
    assert abs(np.nanmedian(track.velocity_mps)) < 0.01
    assert abs(a["sync_delay_samples"] - a["sync_delay_intensity_samples"]) > 50
    assert abs(np.median(track.distance_m) - 0.3) > 0.3e-3
    assert not a["tuning_matches"]
    if a["tuning_peak_width_ratio"] > 1.5:                 # so far off that nothing is vouched for
        assert not track.valid.any() and a["invalid_uncalibrated"] > 0


def test_opencl_with_a_chirp_equals_numpy(tmp_path):
    from fmcw_cl.backend import make_processor
    cap = lagged(tmp_path / "cal.h5", static(0.02, 0.3), 0.02, 7, 2.0)
    chirp = str(write_chirp(tmp_path / "chirp.h5", measure_chirp(cap, 0.3)))
    a = process(cap, Options(chirp=chirp), make_processor("numpy"))
    b = process(cap, Options(chirp=chirp), make_processor("opencl"))
    # the refinement's trial conversions run on each backend (float32 on the device):
    # its secant steps stop within TOLERANCE_SAMPLES of the root, on either side
    from fmcw_cl.refine import TOLERANCE_SAMPLES

    lags = a.attrs["sync_delay_samples"], b.attrs["sync_delay_samples"]
    assert lags[0] == pytest.approx(lags[1], abs=TOLERANCE_SAMPLES)
    np.testing.assert_array_equal(a.valid, b.valid)
    np.testing.assert_allclose(a.distance_m, b.distance_m, atol=1e-5)
    np.testing.assert_allclose(a.velocity_mps, b.velocity_mps, atol=1e-3)


def test_chirp_file_errors(tmp_path, static_capture, setup):
    _, _, chirp = setup
    with pytest.raises(CaptureError, match="not a chirp file"):
        read_chirp(static_capture)
    other = tmp_path / "fast.h5"
    simulate_capture(other, static(0.004, 0.2), 0.004, seed=1,
                     config=replace(SimulationConfig(), sample_rate_hz=125e6))
    with pytest.raises(CaptureError, match="calibrated at sample_rate_hz"):
        process(other, Options(chirp=str(chirp)))


def test_report_spectra_use_the_tracks_chirp(setup):
    """The report's "after" spectra of a calibrated track are made with its calibration."""
    from fmcw_cl.report.spectra import stretch_spectra

    lag, d, chirp = setup
    cal = d / "cal.h5"
    track = process(cal, Options(chirp=str(chirp)))
    sp = stretch_spectra(cal, 0.009, 0.011, 1000, float(track.attrs["sync_delay_samples"]),
                         chirp=track.chirp)
    i = sp.distance_m.searchsorted(0.05)
    peak = sp.distance_m[i + np.argmax(sp.corrected_db[:, i:], axis=1)]
    np.testing.assert_allclose(peak, 0.3, atol=0.5e-3)                  # a bin is ~0.5 mm
    for row in sp.corrected_db[:, i:]:
        assert np.ptp(sp.distance_m[i:][row >= -6]) < 5e-3           # sharp: ~2 resolution cells


def test_calibration_at_minus_10_db_and_behind_a_stronger_wall(tmp_path):
    """A lab's calibration capture: a diffuse end stop at -10 dB per sample, or at 0 dB
    with a wall behind it stronger than the target; both calibrate a 2 us lagged laser
    as well as a clean capture does. Far below, it is refused, naming the SNR."""
    target = lagged(tmp_path / "t.h5", static(0.02, 0.18), 0.02, 7, 2.0)
    with Capture(target) as cap:
        truth = cap.truth()
    scenes = (("noisy", {"snr_db": -10.0}), ("wall", {"snr_db": 0.0, "reflectors": ((0.42, 900.0),)}))
    for k, (name, extra) in enumerate(scenes):
        cal = tmp_path / f"{name}.h5"
        simulate_capture(cal, static(0.1, 0.3), 0.1, seed=70 + k,
                         config=SimulationConfig(thermal_lag_s=2e-6, **extra))
        chirp = fmcw_cl.calibrate(cal, 0.3)
        assert chirp.attrs["other_echo_isolated"] == (name == "wall")
        acc = accuracy(process(target, Options(chirp=str(write_chirp(tmp_path / f"{name}.chirp.h5", chirp)))),
                       truth)
        assert acc["valid_share"] >= 0.99, name
        assert abs(acc["distance_bias_m"]) <= 0.05e-3, name
        assert acc["velocity_p95_mps"] <= 0.01, name
    cal = tmp_path / "dark.h5"
    dark = SimulationConfig(thermal_lag_s=2e-6, snr_db=-20.0)
    simulate_capture(cal, static(0.1, 0.3), 0.1, seed=79, config=dark)
    with pytest.raises(CaptureError, match=r"too noisy to calibrate: the target's SNR is -1\d\.\d dB"):
        fmcw_cl.calibrate(cal, 0.3)


def test_a_chirp_far_from_its_table_is_calibrated_on_its_own_rest(tmp_path, fmcw):
    """The jump under 5 us of thermal lag: with the static table its peaks are twice the
    window's width and its distances centimetres off, smooth enough to pass every
    neighbour test. Its foot rests before and after the jump: the chirp is calibrated
    there (at the table's rough distance, 12 % short) and scaled by the motion, and the
    pairs are valid again at a calibration's precision; the CLI says what was done. The
    OpenCL processor takes the same path."""
    path = lagged(tmp_path / "lag5.h5", jump(0.3), 0.3, 165, 5.0)
    track = process(path)
    a = track.attrs
    with Capture(path) as cap:
        acc = accuracy(track, cap.truth())
    assert a["rest_calibration"] == "made" and a["tuning"] == "chirp calibrated on its own rest"
    assert a["table_peak_width_ratio"] > 1.5 and a["tuning_peak_width_ratio"] < 1.1
    assert 0.85 < a["rest_calibration_scale"] < 0.9                  # the rough distance's error
    assert abs(a["rest_calibration_distance_m"] - 0.07) < 0.2e-3
    assert a["scale_uncertainty_ppm"] < 1000 and a["invalid_uncalibrated"] == 0
    assert acc["valid_share"] >= 0.99
    assert acc["distance_p95_m"] <= 0.1e-3 and acc["distance_max_m"] <= 0.4e-3
    assert acc["velocity_p95_mps"] <= 0.01
    proc = fmcw("process", path, "-o", tmp_path / "o", "--backend", "opencl")
    assert "calibrated on its own rest" in proc.stderr and "warning" not in proc.stderr
    back = read_track(tmp_path / "o" / "lag5.track.h5")
    assert back.attrs["rest_calibration"] == "made" and back.valid.mean() >= 0.99
    # the track keeps its chirp, and the report's "after" spectra are made with it:
    # sharp at the foot's rest (0.07 m), where the table's smear over centimetres
    assert abs(back.chirp.bandwidth_hz / track.chirp.bandwidth_hz - 1) < 1e-3
    from fmcw_cl.report.spectra import stretch_spectra
    for chirp, sharp in ((back.chirp, True), (None, False)):
        sp = stretch_spectra(path, 0.28, 0.282, 1000, float(back.attrs["sync_delay_samples"]), chirp=chirp)
        i = sp.distance_m.searchsorted(0.03)
        for row in sp.corrected_db[:, i:]:
            assert (np.ptp(sp.distance_m[i:][row >= -6]) < 5e-3) == sharp
            if sharp:
                assert abs(sp.distance_m[i + np.argmax(row)] - 0.07) < 1e-3


@pytest.mark.parametrize("seed", [1, 2])
def test_a_lab_jump_far_from_its_table_finds_its_rest_in_sparse_pairs(tmp_path, seed):
    """At a lab's SNR 5 us of lag leave 14 % of the jump's pairs to find the rest in (7 a
    50-pair block): these seeds found none while a block needed 13 and one silent block
    ended a rest (0 % valid). Now calibrated, every pair within 0.5 mm."""
    path = tmp_path / "lab_lag5.h5"
    fmcw_cl.simulate(path, "jump", duration=0.3, seed=seed, thermal_lag_us=5.0, lab=True)
    track = process(path)
    with Capture(path) as cap:
        acc = accuracy(track, cap.truth())
    assert track.attrs["rest_calibration"] == "made"
    assert acc["valid_share"] >= 0.99 and acc["distance_max_m"] <= 0.5e-3


def test_a_rest_calibration_reads_the_whole_conversion_of_one_candidate(tmp_path):
    """The jump under 5 us of lag, seed 162: with the static table its bent distances
    pass from one body to another where no body moves, so the scene's one candidate is
    two bodies and its pairs `ambiguous` (lone_bodies.one_body). The tuning check and the
    rest calibration still read the whole conversion: calibrated, every pair is valid
    (read on the ambiguous copy, no rest was found and none was valid)."""
    path = tmp_path / "lag5_162.h5"
    fmcw_cl.simulate(path, "jump", duration=0.3, seed=162, thermal_lag_us=5.0)
    track = process(path)
    with Capture(path) as cap:
        acc = accuracy(track, cap.truth())
    assert track.attrs["rest_calibration"] == "made"
    assert acc["valid_share"] >= 0.99 and acc["distance_max_m"] <= 0.5e-3


def test_a_chirp_far_from_its_table_without_motion_leaves_no_valid_pair(tmp_path, fmcw):
    """A still target under 5 us of lag: a rest to calibrate on, but no motion to set the
    chirp's scale. None of its centimetre-biased distances may be valid: they are marked
    uncalibrated, and the warning says why and what calibrating gives."""
    from fmcw_cl.stages import faults

    path = lagged(tmp_path / "still5.h5", static(0.05, 0.07), 0.05, 170, 5.0)
    track = process(path)
    assert track.attrs["tuning_peak_width_ratio"] > 1.5 and not track.valid.any()
    assert track.attrs["invalid_uncalibrated"] > 500
    assert (track.reason == faults.UNCALIBRATED).sum() == track.attrs["invalid_uncalibrated"]
    assert "moves less than 20 mm" in track.attrs["rest_calibration"]
    proc = fmcw("process", path, "-o", tmp_path / "o")
    assert "pairs marked uncalibrated: a chirp calibrated on a static target" in proc.stderr
    assert f"not calibrated on its own rest: {track.attrs['rest_calibration']}" in proc.stderr


def test_rest_and_scale_estimates():
    """The rest is the longest steady run of blocks, in distance and velocity, less the
    block that borders the motion; the scale is distance over
    integrated velocity, with an uncertainty that covers its noise, and none without
    motion."""
    from fmcw_cl.numeric import travelled
    from fmcw_cl.rest_calibration import choose_rest, kinematic_scale, rest_stretch

    rng = np.random.default_rng(3)
    t = np.arange(4000) * 50e-6
    v = np.where(t < 0.05, 0.0, 2.0 * np.sin(2 * np.pi * 10 * (t - 0.05)))
    d = 0.2 + travelled(t, v)
    noisy = 0.9 * d + rng.normal(0, 20e-6, t.size)
    i, j = rest_stretch(noisy, v + 0.06 + rng.normal(0, 5e-3, t.size))    # a biased velocity
    assert i == 0 and 700 <= j <= 800           # its last 4 blocks, bordering the motion, trimmed
    # a slow onset from 0.05 s (pair 1000), 0.15 mm by 0.06 s: the distance's tolerance
    # alone sees it 0.3 mm on; the velocity's, trimmed, ends the rest before it
    creep = np.where(t < 0.05, 0.0, 0.03 * np.minimum((t - 0.05) / 0.01, 1.0))
    d = 0.2 + travelled(t, creep)
    d += rng.normal(0, 20e-6, t.size)
    creep += rng.normal(0, 5e-3, t.size)
    i, j = rest_stretch(d, creep)
    assert i == 0 and j <= 1000 and abs(d[j] - d[0]) < 0.02e-3
    assert rest_stretch(d, creep, tol_v=np.inf)[1] >= j + 150
    # a lab's SNR: block medians wandering by 0.5 mm; a short rest (600 periods, 400 once
    # trimmed) is taken only where no long one (900) is found within looser tolerances
    wander = np.repeat(rng.normal(0, 0.25e-3, 80), 50)
    moving = 0.2 + 0.05 * np.sin(2 * np.pi * 30 * (t - 0.03))
    rests = (t < 0.03) | (t >= 0.155)
    lab_d = np.where(t < 0.03, 0.2, np.where(t >= 0.155, moving[3100], moving)) + wander
    lab_v = np.where(rests, 0.0, np.gradient(moving, t)) + rng.normal(0, 5e-3, t.size)
    i, j, loosen = choose_rest(lab_d, lab_v)
    assert i >= 3250 and j == 4000 and loosen > 1
    i, j, _ = choose_rest(lab_d[:3000], lab_v[:3000])
    assert i == 0 and 200 <= j <= 600
    assert choose_rest(moving[:3000], lab_v[:3000]) is None
    # sparse pairs (a lab's uncalibrated chirp): up to REST_GAP silent blocks in a row
    # are part of a rest that resumes after them; more, or a step across them, end it
    rest = np.full(2000, 0.2) + rng.normal(0, 20e-6, 2000)
    still_v = rng.normal(0, 5e-3, 2000)
    sparse = rest.copy()
    sparse[250:300] = np.nan                     # block 5
    sparse[550:650] = np.nan                     # blocks 11-12
    assert rest_stretch(sparse, still_v) == (0, 2000)
    sparse[1000:1150] = np.nan                   # blocks 20-22: one too many
    assert rest_stretch(sparse, still_v) == (0, 1000 - 4 * 50)
    stepped = rest.copy()
    stepped[1000:1100] = np.nan
    stepped[1100:] += 2e-3                       # it moved while silent
    assert rest_stretch(stepped, still_v)[1] <= 1000
    gaps = noisy.copy()
    gaps[2000:2100] = np.nan
    ok = np.isfinite(gaps)
    k, sigma = kinematic_scale(t, gaps, v + rng.normal(0, 1e-3, t.size), ok)
    assert abs(k - 0.9) < 3 * sigma and sigma < 1e-3
    still = np.full(t.size, 0.2) + rng.normal(0, 20e-6, t.size)
    assert np.isnan(kinematic_scale(t, still, np.zeros(t.size), np.ones(t.size, bool))[0])


@pytest.mark.parametrize("sigma", [0.8, 3.0, 20.0, 60.0])
def test_peak_widths_near_and_far(sigma):
    """The half-power width of Gaussian peaks (2.3548 sigma) whether its half-power
    points lie within tuning.WIDTH_REACH bins of the peak or beyond (the whole band
    searched); none where a side never falls to half in the band."""
    from fmcw_cl.tuning import WIDTH_REACH, _widths

    x = np.arange(1024.0)
    centres = np.array([100.3, 500.0, 900.7])
    p = np.exp(-0.5 * ((x - centres[:, None]) / sigma) ** 2) + 1e-9
    got = _widths(p, 10)
    expect = 2 * np.sqrt(2 * np.log(2)) * sigma
    assert (np.sqrt(2 * np.log(2)) * sigma > WIDTH_REACH) == (sigma > 20)   # half power beyond the reach
    np.testing.assert_allclose(got, expect, rtol=0.02 if sigma > 1 else 0.15)
    edge = _widths(p[:1], 95)                    # the band from 95: 100.3's left side is outside it
    assert np.isnan(edge[0]) == (sigma > 4)


def test_a_calibrated_chirp_of_a_shorter_range_ends_the_band_with_it(static_capture):
    """A band checked against the G(I) table's unambiguous range, then resampled on a
    chirp of a wider bandwidth (a rest calibration's), ends where the chirp's range ends
    instead of refusing the capture (`max_range` 0.335315 m beyond the unambiguous range
    0.335 m, from a two-mover scene); a band whose top the chirp's range holds is kept."""
    with Capture(static_capture) as cap:
        table = make_plan(cap, Options())
        unamb = table.lut.unambiguous_range_m
        plan = make_plan(cap, Options(max_range=0.99 * unamb), lag=table.lag)
        s = np.linspace(0.0, 1.0, 64)

        def chirp(factor):
            nu = (s - 0.5) * table.lut.bandwidth_hz * factor
            return Chirp(Direction(s, nu), Direction(s, -nu))

        wide = plan.with_chirp(chirp(1.02), "own rest")
        assert wide.lut.unambiguous_range_m < 0.99 * unamb
        assert wide.options.max_range is None and wide.search.hi == wide.model.nfft // 2
        narrow = plan.with_chirp(chirp(0.98), "own rest")
        assert narrow.options.max_range == 0.99 * unamb and narrow.search.hi < narrow.model.nfft // 2


@pytest.mark.parametrize("glided, amplitude, lab, seed, start, span", [
    ((0.3697415512212193, 0.04781662794050249, 0.1644821855772409, 0.4140957777397375), 558.3597919036532,
     False, 832, 0.2663622281084007, 0.11709999393486868),
    ((0.39343945403244684, 0.03552033943706347, 0.2267221414032449, 0.6267221414032449), 294.7288383666272,
     True, 15, 0.4775990234928413, 0.0787789085885622)])
def test_another_movers_peaks_are_no_sign_of_the_tuning(tmp_path, glided, amplitude, lab, seed, start, span):
    """The jump's foot at rest at 0.07 m and a hand gliding down past it at -0.5 m/s
    (movers.py seed 8, capture 37, clean; seed 10, capture 12, lab): the track's
    stillest stretch is the hand's, de-chirped at its velocity, where the foot's
    smeared image lies 3 mm from the hand's peak in one direction, and the strongest
    peak of the band was read: 1.6 and 2.2x the window's width, no rest to calibrate
    on, no valid pair of either. Each row's own peak (tuning.OWN_BINS about the
    track's), in the narrower direction: the tuning matches; both objects are held."""
    from fmcw_cl.simulator.scene import glide

    track, scores = two_movers(tmp_path / "jump_hand.h5", jump(0.7), glide(0.7, *glided), amplitude, lab,
                               seed, start, span)
    assert track.attrs["tuning_matches"] and track.attrs["tuning_peak_width_ratio"] < 1.1
    best = best_held(scores, 2)
    assert min(best) >= 0.6, best
