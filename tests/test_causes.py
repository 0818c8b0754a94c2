"""What a newcomer gets wrong is answered by its cause, in one line: a range gate that
leaves the target out, swapped channels, a sample-rate attribute that disagrees with
the signal, a calibration distance far from the table's; and a warning only where its
cause is: no chirp mismatch for noise, a vibration or a target out of the band."""

from __future__ import annotations

import json
import shutil
from dataclasses import replace

import h5py
import numpy as np
import pytest

from fmcw_cl.simulator import SimulationConfig, simulate_capture, static
from fmcw_cl.simulator.scene import Trajectory
from fmcw_cl.tuning import WIDTH_LIMIT

MISMATCH = "does not match the G(I) table"


def _vibration(duration: float, r0: float, amplitude: float, hz: float) -> Trajectory:
    w = 2 * np.pi * hz
    return Trajectory.from_velocity(0.0, duration, lambda t: amplitude * w * np.cos(w * t),
                                    lambda t: -amplitude * w * w * np.sin(w * t), r0)


@pytest.fixture(scope="module")
def scenes(tmp_path_factory):
    """30 ms captures at a lab's SNR (0 dB per sample): a target at 0.3 m, no target at
    all (noise only), a target vibrating 50 um at 1 kHz."""
    d = tmp_path_factory.mktemp("causes")
    lab = SimulationConfig(snr_db=0.0)
    simulate_capture(d / "target.h5", static(0.03, 0.3), 0.03, seed=1, config=lab)
    simulate_capture(d / "empty.h5", static(0.03, 0.3), 0.03, seed=2,
                     config=replace(SimulationConfig(), echo_codes=0.0, noise_codes=100.0))
    simulate_capture(d / "vibrating.h5", _vibration(0.03, 0.3, 50e-6, 1000.0), 0.03, seed=3, config=lab)
    return d


def _warnings(res) -> list[str]:
    return [line for line in res.stderr.splitlines() if line.startswith("warning:")]


def test_a_band_that_leaves_the_target_out_says_so(scenes, tmp_path, fmcw):
    for flag, value in (("--max-range", "0.2"), ("--min-range", "0.35")):
        res = fmcw("process", scenes / "target.h5", "-o", tmp_path, flag, value)
        warned = _warnings(res)
        assert len(warned) == 1, res.stderr
        assert "0.0 % valid in the band" in warned[0] and "the strongest echo lies outside it, at 0.300 m" \
            in warned[0] and "widen the band" in warned[0]
        assert MISMATCH not in res.stderr
    assert _warnings(fmcw("process", scenes / "target.h5", "-o", tmp_path, "--max-range", "0.4")) == []


def test_swapped_channels_are_refused_naming_the_order(scenes, tmp_path, fmcw):
    swapped = tmp_path / "swapped.h5"
    shutil.copy(scenes / "target.h5", swapped)
    with h5py.File(swapped, "r+") as f:
        beat, sync = f["adc/beat"][...], f["adc/sync"][...]
        f["adc/beat"][...], f["adc/sync"][...] = sync, beat
    res = fmcw("process", swapped, "-o", tmp_path / "t", check=False)
    assert res.returncode == 1 and res.stderr.count("\n") == 1
    assert "swapped.h5: the channels look swapped" in res.stderr and "--order beat,sync" in res.stderr


def test_roughness_of_codes_is_that_of_their_values():
    """plan.roughness sums ADC codes as integers (exact): the figure float64 passes give
    for a sync triangle, a beat, a constant and a step."""
    from fmcw_cl.plan import roughness

    def in_floats(codes):
        x = codes.astype(np.float64)
        spread = float(np.std(x))
        return float(np.sqrt(np.mean(np.square(np.diff(x)))) / spread) if spread > 0 else 0.0

    rng = np.random.default_rng(3)
    tri = (1000 * np.abs((np.arange(200_000) / 5000) % 1 - 0.5)).astype(np.int16)
    for codes in (tri, rng.integers(-32768, 32767, 200_000).astype(np.int16), np.full(50, 7, np.int16),
                  np.r_[np.zeros(10, np.int16), np.ones(10, np.int16)]):
        assert roughness(codes) == pytest.approx(in_floats(codes), rel=1e-12, abs=0)
    assert roughness(tri) < 0.01 < roughness(rng.integers(-100, 100, 5000).astype(np.int16))


def test_no_target_is_said_and_no_chirp_is_blamed(scenes, tmp_path, fmcw):
    res = fmcw("process", scenes / "empty.h5", scenes / "target.h5", "-o", tmp_path)
    assert MISMATCH not in res.stderr
    assert "warning: " + str(scenes / "empty.h5") + ": no valid pair; 598 of 598 are no_echo: no echo " \
        "stands out of the noise" in res.stderr
    assert "2 captures: 2 converted (1 with no valid pair), 0 failed, 0 skipped" in res.stderr


def test_a_vibration_is_not_taken_for_a_chirp_mismatch(scenes, tmp_path, fmcw):
    """Its peaks would be wide from its own Doppler terms were they not followed: the
    tracker follows it (fmcw_cl.motion.FAST), its de-chirped peaks match the table."""
    res = fmcw("process", scenes / "vibrating.h5", "-o", tmp_path, "--json")
    assert MISMATCH not in res.stderr
    with h5py.File(tmp_path / "vibrating.track.h5") as f:
        assert f.attrs["motion"] == "fast" and f["track/valid"][()].mean() >= 0.95
        assert f.attrs["tuning_peak_width_ratio"] <= WIDTH_LIMIT and f.attrs["tuning_matches"]


@pytest.mark.parametrize("group,attr,value,off", [("adc", "sample_rate_hz", 101e6, "-0.99 %"),
                                                   ("modulation", "frequency_hz", 20.2e3, "+1.00 %")])
def test_an_attribute_the_signal_contradicts_is_named(scenes, tmp_path, fmcw, group, attr, value, off):
    wrong = tmp_path / "wrong.h5"
    shutil.copy(scenes / "target.h5", wrong)
    with h5py.File(wrong, "r+") as f:
        f[group].attrs[attr] = value
    warned = _warnings(fmcw("process", wrong, "-o", tmp_path / "t"))
    assert len(warned) == 1 and off in warned[0] and "sample_rate_hz and frequency_hz" in warned[0]
    assert _warnings(fmcw("process", scenes / "target.h5", "-o", tmp_path / "t")) == []


def test_a_calibration_distance_far_from_the_tables_is_warned_of(tmp_path, fmcw):
    cap = tmp_path / "still.h5"
    simulate_capture(cap, static(0.06, 0.3), 0.06, seed=7)
    for distance, warned in (("0.30", False), ("0.25", True)):
        res = fmcw("calibrate", cap, "--distance", distance, "-o", tmp_path / "chirp.h5", "--periods", "1000")
        assert ("warning: " in res.stderr) == warned, res.stderr
        assert "the target at 0.300" in res.stdout
    assert "-16.7 % from --distance 0.25" in res.stderr and "check --distance" in res.stderr


def test_a_report_says_why_the_spectra_are_left_out(scenes, tmp_path, fmcw):
    cap = tmp_path / "moved.h5"
    shutil.copy(scenes / "target.h5", cap)
    fmcw("process", cap, "-o", tmp_path, "-q")
    cap.rename(tmp_path / "elsewhere.h5")
    res = fmcw("report", tmp_path / "moved.track.h5", "-o", tmp_path / "r", "-q")
    assert "spectra.png and the truth left out: its capture " + str(cap) + " is not there" in res.stderr
    assert not (tmp_path / "r" / "spectra.png").exists()
    res = fmcw("report", tmp_path / "moved.track.h5", "-o", tmp_path / "r2", "-q", "--capture",
               tmp_path / "elsewhere.h5")
    assert res.stderr == "" and (tmp_path / "r2" / "spectra.png").exists()


def test_info_says_the_quick_facts_first(scenes, fmcw):
    full = fmcw("info", scenes / "target.h5").stdout.splitlines()
    quick = fmcw("info", scenes / "target.h5", "--no-delay").stdout.splitlines()
    assert full[-1].startswith("sync delay     sync lags the optics by") and full[:-1] == quick
    assert not any("sync delay" in line for line in quick)


def test_the_json_summary_of_an_empty_capture(scenes, tmp_path, fmcw):
    got = json.loads(fmcw("process", scenes / "empty.h5", "-o", tmp_path, "--json").stdout)[0]
    assert got["valid_share"] == 0.0 and got["invalid"]["no_echo"] == got["pairs"]
