"""The sync delay measured from the capture's own target (refine): a lab's weak
intensity triangle leaves the first estimate samples off; kinematic consistency moves
it to where a static target reads no velocity, with its uncertainty stated."""

from __future__ import annotations

import numpy as np
import pytest

from fmcw_cl import refine
from fmcw_cl.engine import process
from fmcw_cl.options import Options

# a lab: an intensity triangle of +-150 codes under 600 codes rms, a 20 MHz G(I) table
from fmcw_cl.simulator import LAB, SimulationConfig, jump, simulate_capture, static


@pytest.mark.parametrize(("seed", "distance", "points"), [(2, 0.4, 1000), (3, 0.7, 2048)])
def test_a_static_target_under_lab_conditions_reads_no_velocity(tmp_path, fmcw, seed, distance, points):
    path = tmp_path / "static.h5"
    true = simulate_capture(path, static(0.05, distance), 0.05, seed=seed, config=LAB)["sync_delay_samples"]
    track = process(path, Options(points=points))
    a = track.attrs
    assert abs(a["sync_delay_intensity_samples"] - true) > 1.0         # the triangle alone is off
    assert a["sync_delay_refined"] and abs(a["sync_delay_samples"] - true) <= 1.0
    assert abs(np.mean(track.velocity_mps[track.valid])) <= 0.003
    assert 0 < a["sync_delay_uncertainty_samples"] < 0.5
    assert 0 < a["sync_delay_velocity_uncertainty_mps"] < 0.002
    assert abs(a["sync_delay_refined_at_m"] - distance) < 1e-3 and a["sync_delay_reliable"]
    proc = fmcw("process", path, "-o", tmp_path / "o", "--points", points)
    assert "sync delay" not in proc.stderr                              # nothing to warn of
    info = fmcw("info", path, "--points", points).stdout
    assert "samples, refined on the target (velocities +-" in info and "the intensity triangle gave" in info


def test_no_target_keeps_the_intensity_estimate_and_says_why(tmp_path, fmcw):
    """A blocked beam under a weak triangle: nothing to refine on, nothing clean to align
    on; the warning names both."""
    path = tmp_path / "dark.h5"
    cfg = SimulationConfig(leak_codes=150.0, noise_codes=600.0, echo_codes=0.0, lens_codes=0.0)
    simulate_capture(path, static(0.02, 0.3), 0.02, seed=5, config=cfg)
    track = process(path)
    assert not track.attrs["sync_delay_refined"] and not track.valid.any()
    proc = fmcw("process", path, "-o", tmp_path / "o")
    assert ("no valid run of the target to align the sync delay on, and no clear intensity triangle"
            in proc.stderr)


def test_a_capture_shorter_than_the_stretches_is_refined(tmp_path):
    path = tmp_path / "short.h5"
    true = simulate_capture(path, static(0.006, 0.3), 0.006, seed=6, config=LAB)["sync_delay_samples"]
    track = process(path)
    assert track.attrs["sync_delay_refined"] and abs(track.attrs["sync_delay_samples"] - true) <= 1.5


def test_trial_conversions_with_fewer_passes_find_the_same_delay(tmp_path, monkeypatch):
    """refine's trial conversions make TRIAL_ITERATIONS de-chirp passes, not the
    tracker's six: on a landing under lab conditions (each pass moves its velocities;
    two passes left the delay 2 samples off here) they find the delay six find."""
    path = tmp_path / "landing.h5"
    simulate_capture(path, jump(0.3), 0.05, start_s=0.18, seed=2, config=LAB)
    few = process(path).attrs
    monkeypatch.setattr(refine, "TRIAL_ITERATIONS", Options().iterations)
    full = process(path).attrs
    assert refine.TRIAL_ITERATIONS > 3 and few["sync_delay_refined"] and full["sync_delay_refined"]
    assert abs(few["sync_delay_samples"] - full["sync_delay_samples"]) < 0.05
