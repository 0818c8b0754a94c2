"""The simulator's physics, checked numerically against the paper and first principles."""

from __future__ import annotations

import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest

from fmcw_cl.capture import Capture
from fmcw_cl.physics import C
from fmcw_cl.simulator import SimulationConfig, Trajectory, jump, paper_dfb, rail, simulate_capture, static
from fmcw_cl.simulator.laser import DfbLaser
from fmcw_cl.simulator.many import simulate_captures


def test_dfb_tuning_matches_paper_fig3():
    laser = paper_dfb()
    assert C / laser.frequency(0.020) == pytest.approx(1548.12e-9, abs=1e-13)
    assert C / laser.frequency(0.500) == pytest.approx(1549.76e-9, abs=2e-12)
    assert laser.frequency(0.020) - laser.frequency(0.500) == pytest.approx(205e9, rel=1e-9)
    assert laser.frequency(0.160) - laser.frequency(0.480) == pytest.approx(160e9, rel=1e-9)
    slope = np.abs(laser.tuning_slope(np.array([0.160, 0.480])))
    assert 2.0 < slope[1] / slope[0] < 2.6  # the local chirp rate varies by about 2x
    cur, freq = laser.tuning_table(np.random.default_rng(0))
    assert cur.size == 25 and cur[0] == 0.020 and cur[-1] == 0.500
    assert np.std(freq - laser.frequency(cur)) < 50e6


def test_scenarios_follow_the_paper():
    t = np.arange(0, 0.3, 1e-5)
    r, v, a = jump(0.3).at(t)
    assert v.max() == pytest.approx(7.15, abs=0.05) and abs(t[v.argmax()] - 0.078) < 0.002
    assert 340 < a.max() < 380 and 340 < -a.min() < 400
    assert 0.3 <= r.max() <= 0.4
    landing = (t > 0.18) & (t < 0.215)
    assert a[landing].max() == pytest.approx(300, rel=0.05)
    assert r[0] == pytest.approx(r[-1], abs=1e-6)  # back on the ground
    r, v, a = rail(0.4).at(t)
    assert v.max() == pytest.approx(2.7, abs=0.02) and a.max() == pytest.approx(22.5, abs=0.1)


def test_trajectory_derivatives_are_consistent():
    t = np.arange(0.05, 0.25, 1e-6)
    r, v, a = jump(0.3).at(t)
    np.testing.assert_allclose(np.gradient(r, t)[1:-1], v[1:-1], atol=2e-4)
    np.testing.assert_allclose(np.gradient(v, t)[1:-1], a[1:-1], atol=0.05)


def _linear_laser() -> DfbLaser:
    """A linearly tuned laser (-500 GHz/A) so that beats are pure tones in time."""
    return DfbLaser(C / 1549e-9, 0.32, 500e9, 0.0, linewidth_hz=0.0)


def _tone(x: np.ndarray, fs: float) -> float:
    """Frequency of the strongest tone (Hz), from a heavily zero-padded FFT."""
    spec = np.abs(np.fft.rfft((x - x.mean()) * np.hanning(x.size), 1 << 20))
    spec[:50] = 0
    return np.argmax(spec) * fs / (1 << 20)


@pytest.mark.parametrize("velocity", [0.0, 2.0, -3.0])
def test_beat_and_doppler_from_the_optical_phase(tmp_path, velocity):
    """Linear sweep: beat = |nu'| tau -+ 2 v / lambda in the two directions."""
    cfg = replace(SimulationConfig(), laser=_linear_laser(), noise_codes=1.0, lens_codes=0.0,
                  leak_codes=0.0, sync_delay_samples=0.0, start_phase=0.0)
    r0 = 0.2
    traj = Trajectory.from_velocity(0, 0.002, lambda t: np.full_like(t, velocity),
                                    np.zeros_like, r0)
    path = tmp_path / "tone.h5"
    simulate_capture(path, traj, 0.002, seed=1, config=cfg)
    with Capture(path) as cap:
        beat, _ = cap.read(0, 10_000)
    fs = cfg.sample_rate_hz
    # start_phase 0: current rises over samples 0..2500 and falls over 2500..5000
    rising, falling = beat[5200:7300].astype(float), beat[7700:9800].astype(float)
    f_r, f_f = _tone(rising, fs), _tone(falling, fs)
    lam = C / cfg.laser.frequency(0.32)
    chirp = 500e9 * 320e-3 * 2 * 20e3           # |nu'| in Hz/s
    r_mid = r0 + velocity * 7500 / fs
    assert 0.5 * (f_r + f_f) == pytest.approx(chirp * 2 * r_mid / C, rel=2e-3)
    assert 0.5 * (f_f - f_r) == pytest.approx(2 * velocity / lam, abs=0.01 * 2 * 3 / lam)


def test_capture_is_deterministic_and_valid(tmp_path):
    a, b = tmp_path / "a.h5", tmp_path / "b.h5"
    for p in (a, b):
        hidden = simulate_capture(p, jump(0.3), 0.001, seed=9, start_s=0.07)
    with Capture(a) as ca, Capture(b) as cb:
        np.testing.assert_array_equal(ca.read(0, 100_000)[0], cb.read(0, 100_000)[0])
        info = ca.info
        assert info.samples == 100_000 and info.has_truth
        beat, sync = ca.read(0, info.samples)
        assert beat.dtype == np.int16 and np.abs(beat).max() <= 8191
        assert -40 <= hidden["sync_delay_samples"] <= 40
        truth = ca.truth()
        assert truth.time_s[0] == 0 and truth.distance_m.size == truth.time_s.size
        # the excerpt starts at scenario time 0.07: fast take-off
        assert truth.velocity_mps[0] > 5


def test_captures_written_at_once_equal_each_written_alone(tmp_path):
    """`simulate_captures`: threads of their own write what `simulate_capture` writes,
    a capture already there is kept, and progress reaches the total; a script without a
    `__main__` guard may call it (no processes spawned that import the script again)."""
    def jobs(folder):
        return [{"path": folder / f"c{k}.h5", "trajectory": jump(0.3), "duration_s": 0.0005 * (k + 1),
                 "seed": k, "start_s": 0.07} for k in range(3)]
    (tmp_path / "many").mkdir()
    alone = jobs(tmp_path)
    for job in alone:
        simulate_capture(**job)
    many = jobs(tmp_path / "many")
    many[1]["path"].write_bytes(b"kept")
    seen = []
    paths = simulate_captures(many, progress=lambda done, total: seen.append((done, total)))
    assert paths == [job["path"] for job in many] and many[1]["path"].read_bytes() == b"kept"
    assert seen[-1] == (200_000, 200_000) and len(seen) == 2
    script = tmp_path / "unguarded.py"
    script.write_text("from pathlib import Path\nfrom fmcw_cl.simulator import jump, simulate_captures\n"
                      f"folder = Path({str(tmp_path)!r})\n"
                      "simulate_captures([{'path': folder / f'u{k}.h5', 'trajectory': jump(0.3), "
                      "'duration_s': 0.0002, 'seed': k} for k in range(2)])\nprint('written')\n")
    run = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0 and run.stdout == "written\n", run.stderr
    assert (tmp_path / "u0.h5").exists() and (tmp_path / "u1.h5").exists()
    for k in (0, 2):
        with Capture(alone[k]["path"]) as ca, Capture(many[k]["path"]) as cb:
            assert ca.info.samples == cb.info.samples == 50_000 * (k + 1)
            for x, y in zip(ca.read(0, ca.info.samples), cb.read(0, cb.info.samples), strict=True):
                np.testing.assert_array_equal(x, y)


def test_speckle_field_is_rayleigh_with_its_correlation_time():
    from fmcw_cl.simulator.writer import speckle_field

    corr = 3e-3
    g = speckle_field(3.0, corr, np.random.default_rng(4))
    t = np.arange(0, 3.0, corr / 10)
    z = g(t)
    power = np.abs(z) ** 2
    assert np.mean(power) == pytest.approx(1.0, rel=0.1)
    # Rayleigh amplitude: |g|^2 exponential, so P(|g|^2 < 0.1) = 1 - exp(-0.1)
    assert np.mean(power < 0.1) == pytest.approx(1 - np.exp(-0.1), abs=0.02)
    # field autocorrelation exp(-(dt/corr)^2): 1/e at one correlation time
    lag = 10
    rho = np.abs(np.mean(z[lag:] * np.conj(z[:-lag]))) / np.mean(power)
    assert rho == pytest.approx(np.exp(-1), abs=0.08)


def test_snr_db_sets_the_noise_and_reflectors_add_beats(tmp_path):
    cfg = SimulationConfig(snr_db=0.0, reflectors=((0.35, 300.0),), leak_codes=0.0, lens_codes=0.0)
    amp = cfg.echo_amplitude(0.3)
    assert cfg.beat_noise_codes == pytest.approx(amp / np.sqrt(2))        # A^2/2 = sigma^2
    quiet = SimulationConfig(noise_codes=0.0, reflectors=((0.35, 300.0),), echo_codes=0.0,
                             leak_codes=0.0, lens_codes=0.0, sync_delay_samples=0.0)
    path = tmp_path / "wall.h5"
    simulate_capture(path, static(0.001, 0.2), 0.001, seed=2, config=quiet)
    with Capture(path) as cap:
        beat, _ = cap.read(0, cap.info.samples)
    # the wall alone: its amplitude times the laser's relative power (about 1 mid-sweep)
    assert 200 < np.sqrt(2) * np.std(beat) < 400


def test_weak_echo_gain_keeps_the_noise_inside_the_adc(tmp_path):
    """Below about -11 dB the whole beat is scaled as a lab's gain would be: the noise's
    rms stays 6x below full scale (nothing clips), the SNR stays what was asked."""
    from fmcw_cl.simulator.writer import HEADROOM

    for snr_db, scaled in ((-8.0, False), (-20.0, True)):
        cfg = SimulationConfig(snr_db=snr_db, leak_codes=0.0, lens_codes=0.0)
        path = tmp_path / f"weak{snr_db:+g}.h5"
        simulate_capture(path, static(0.002, 0.3), 0.002, seed=4, config=cfg)
        with Capture(path) as cap:
            beat, _ = cap.read(0, cap.info.samples)
        rms = np.std(beat.astype(np.float64))
        full = 2 ** (cap.info.bits - 1)
        assert np.abs(beat).max() < full - 1                                 # no clipping
        sigma, amp = cfg.beat_noise_codes, cfg.echo_amplitude(0.3)
        gain = full / (HEADROOM * sigma) if scaled else 1.0
        assert (gain < 1) == scaled
        assert rms == pytest.approx(gain * np.sqrt(sigma**2 + amp**2 / 2), rel=0.05)   # noise + echo
