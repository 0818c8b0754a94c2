"""Real scenes at a lab's SNR (0 dB per sample): a stronger wall behind the target,
speckle fading, a landing at close range, and the echoes a track lists."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import realistic

from fmcw_cl.capture import Capture
from fmcw_cl.engine import Options, process
from fmcw_cl.evaluate import accuracy, truth_at
from fmcw_cl.simulator import SimulationConfig, simulate_capture, static
from fmcw_cl.stages import faults
from fmcw_cl.track import read_track, track_path


def scored(path, **opts):
    track = process(path, Options(**opts))
    with Capture(path) as cap:
        return accuracy(track, cap.truth()), track


def test_wall_is_named_and_max_range_keeps_the_target(wall_capture, tmp_path, fmcw):
    # as a user runs it first: the wall wins the band, and the warning says so
    proc = fmcw("process", wall_capture, "-o", tmp_path, "--json", "--backend", "numpy")
    line = [w for w in proc.stderr.splitlines() if "another echo" in w]
    assert len(line) == 1 and "m is" in line[0] and "--max-range" in line[0], proc.stderr
    rival = json.loads(proc.stdout)[0]["rival_echo"]
    track = read_track(track_path(tmp_path, wall_capture))
    assert np.isfinite(track.attrs["rival_echo_m"])
    assert rival["relative_db"] >= -10
    # the wall is among the persistent echoes at its distance
    pers = track.echoes.persistent
    assert np.any(np.abs(pers["distance_m"] - 0.42) < 2e-3)
    # with the band closed before the wall: the target, with the pipeline's figures
    acc, track = scored(wall_capture, max_range_m=0.40)
    assert acc["valid_share"] >= 0.98
    assert acc["distance_p95_m"] <= 0.5e-3
    assert acc["velocity_p95_mps"] <= 0.02
    assert not np.any(track.distance_m[track.valid] > 0.40)
    # the wall is still listed, never hidden, but no longer rivals the target
    pers = track.echoes.persistent
    assert np.any((np.abs(pers["distance_m"] - 0.42) < 2e-3) & ~pers["in_band"])
    assert np.isnan(track.attrs["rival_echo_m"])


def test_two_static_reflectors_listed_at_their_distances(tmp_path):
    path = tmp_path / "two.h5"
    cfg = SimulationConfig(snr_db=0.0, reflectors=((0.37, 400.0),))
    simulate_capture(path, static(0.02, 0.21), 0.02, seed=41, config=cfg)
    track = process(path)
    e = track.echoes
    assert np.all(np.abs(track.distance_m[track.valid] - 0.21) < 0.5e-3)   # the stronger one
    near = lambda d: np.abs(e.distance_m - d) < 1e-3  # noqa: E731
    sweeps = track.sweep_time_s.size
    assert near(0.21).sum() >= 0.98 * sweeps and e.tracked[near(0.21)].all()
    assert near(0.37).sum() >= 0.98 * sweeps and not e.tracked[near(0.37)].any()
    assert np.sum(~near(0.21) & ~near(0.37)) <= 0.02 * sweeps        # false echoes are rare
    # 400 codes at 0.37 m against 1500 * 0.1/0.21 = 714 at 0.21 m: about 5 dB weaker
    assert track.attrs["rival_echo_m"] == pytest.approx(0.37, abs=1e-3)
    assert -8 < track.attrs["rival_echo_db"] < -2


def test_speckle_fades_are_flagged_never_wrong(tmp_path):
    path = realistic(tmp_path / "speckle.h5", seed=32, speckle_s=3e-3)
    acc, track = scored(path)
    assert acc["valid_share"] >= 0.90
    assert acc["distance_p95_m"] <= 0.2e-3
    assert acc["distance_max_m"] <= 0.5e-3
    assert acc["velocity_p95_mps"] <= 0.02
    assert track.attrs["invalid_no_echo"] > 0           # the fades are there, and flagged


def test_close_range_fold_keeps_the_landing(tmp_path):
    """Landing at 0.06 m near 2 m/s: one direction's beat sits within a few cycles of
    0 Hz; the de-chirp and the neighbours' velocity keep those pairs."""
    path = realistic(tmp_path / "close.h5", ground_m=0.06, seed=33)
    acc, track = scored(path)
    with Capture(path) as cap:
        _, v, _ = truth_at(cap.truth(), track.time_s)
    landing = (track.distance_m < 0.1) & (np.abs(v) > 1.0)
    assert np.sum((track.time_s > 0.19) & (track.time_s < 0.21) & (np.abs(v) > 1.0)) > 20
    assert acc["valid_share"] >= 0.995
    assert acc["distance_p95_m"] <= 0.2e-3
    assert acc["distance_max_m"] <= 0.5e-3
    assert acc["velocity_p95_mps"] <= 0.01
    assert track.valid[landing].all() or not landing.any()


def test_continuity_flags_a_common_mode_jump():
    from fmcw_cl.stages import pairing

    rng = np.random.default_rng(0)
    t = np.arange(400) * 50e-6
    v = 3.0 + 200 * t                                        # accelerating
    d = 0.1 + 3.0 * t + 100 * t**2 + rng.normal(0, 30e-6, t.size)
    d[[50, 51, 300]] += 1.7e-3                                # both sweeps on a wrong peak
    ok = pairing.continuity(t, d, v, np.ones(t.size, bool))
    assert not ok[[50, 51, 300]].any()
    assert ok.sum() == t.size - 3
    code = faults.reasons(np.ones(t.size, bool), np.ones(t.size, bool), np.zeros(t.size, bool),
                          np.zeros(t.size, bool), ok)
    assert (code[[50, 51, 300]] == faults.DISCONTINUOUS).all()


def test_noise_beyond_the_range_is_not_an_alias():
    u = 0.47
    d2 = np.array([0.60, 0.60, 0.30])
    dn = np.array([2 * u - 0.60, 0.10, 0.30])     # a true alias, a noise peak, in range
    got = faults.beyond_range(d2, np.full(3, 15.0), u, 10.0, dn)
    assert got.tolist() == [True, False, False]


def test_a_wide_target_peak_is_not_taken_for_another_echo(tmp_path, jump_capture):
    """Without de-chirp (the paper's method), or with a chirp that left its G(I) table,
    the target's own peak is wide; its energy must not pass for a hidden echo."""
    _, paper = scored(jump_capture, dechirp=False)
    assert np.isnan(paper.attrs["rival_echo_m"])
    path = tmp_path / "lag.h5"
    cfg = SimulationConfig(thermal_lag_s=5e-6)
    simulate_capture(path, static(0.02, 0.18), 0.02, seed=62, config=cfg)
    lagged = process(path)
    assert not lagged.attrs["tuning_matches"]         # the tuning warning says what is wrong
    assert np.isnan(lagged.attrs["rival_echo_m"])
