"""The windows a conversion fits its pairs over (fmcw_cl.motion): a vibration's where its
velocity reverses within a leg's windows, a leg's for everything else (noise at any
level, wrong echoes, a take-off, a landing's stop)."""

from __future__ import annotations

import numpy as np
import pytest

from fmcw_cl import motion

PAIRS = 240                      # a trial stretch (refine.STRETCH_PERIODS), three of them
T = 50e-6 * np.arange(PAIRS)


def _stretches(v_of_t, rng, noise: float) -> list[np.ndarray]:
    return [v_of_t(T + 0.013 * k) + rng.normal(0, noise, PAIRS) for k in range(3)]


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_vibration_calls_for_short_windows(seed):
    """50 um and 10 um at 1 kHz, 100 um at 700 Hz (0.06-0.44 m/s), under 2 mm/s of
    velocity noise, and 50 um at 1 kHz under 10 mm/s."""
    rng = np.random.default_rng(seed)
    for amplitude, hz, noise in ((50e-6, 1000.0, 2e-3), (10e-6, 1000.0, 2e-3), (100e-6, 700.0, 2e-3),
                                 (50e-6, 1000.0, 0.01)):
        w = 2 * np.pi * hz
        got = motion.choose(_stretches(lambda t, a=amplitude, w=w: a * w * np.cos(w * t), rng, noise))
        assert got is motion.FAST, (amplitude, hz)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_leg_and_noise_keep_a_legs_windows(seed):
    """Noise from 1 mm/s to 0.3 m/s, 5 % of pairs on another echo 1 m/s off, a take-off
    at 360 m/s^2, a landing stopping 7 m/s in 1 ms, slow vibrations (1 um at 1 kHz,
    2 mm at 50 Hz)."""
    rng = np.random.default_rng(seed)
    for noise in (1e-3, 0.01, 0.1, 0.3):
        assert motion.choose(_stretches(lambda t: 0.0 * t, rng, noise)) is motion.SMOOTH
    wrong = _stretches(lambda t: 2.0 + 0.0 * t, rng, 3e-3)
    for v in wrong:
        v[rng.random(PAIRS) < 0.05] += rng.choice([-1.0, 1.0])
    assert motion.choose(wrong) is motion.SMOOTH
    legs = [lambda t: 360.0 * t, lambda t: -7.0 * np.clip(1 - (t - 0.02) / 1e-3, 0, 1),
            lambda t: 1e-6 * 2 * np.pi * 1e3 * np.cos(2 * np.pi * 1e3 * t),
            lambda t: 2e-3 * 2 * np.pi * 50 * np.cos(2 * np.pi * 50 * t)]
    for leg in legs:
        assert motion.choose(_stretches(leg, rng, 2e-3)) is motion.SMOOTH
    assert motion.choose([]) is motion.SMOOTH and motion.choose([np.zeros(5)]) is motion.SMOOTH


def test_a_swings_acceleration_is_not_held_at_its_run_ends():
    """Held over 2 pairs, a 1 kHz swing's acceleration moves by 60 %: a vibration's
    windows take the fit's own at a run's ends, within 10 % (the quadratic over 5 pairs
    reads the swing 5.5 % low); a leg's hold the nearest centred value."""
    from fmcw_cl.stages import kinematics

    w = 2 * np.pi * 1000.0
    v = 50e-6 * w * np.cos(w * T)
    truth = -50e-6 * w * w * np.sin(w * T)
    ok = np.ones(PAIRS, bool)
    fast = kinematics.held_acceleration(v, ok, 50e-6, motion.FAST.window, motion.FAST.hold)
    held = kinematics.held_acceleration(v, ok, 50e-6, motion.FAST.window, True)
    ends = np.r_[0, 1, PAIRS - 2, PAIRS - 1]
    assert np.max(np.abs(fast - truth)) <= 0.1 * np.max(np.abs(truth))
    assert np.max(np.abs(held[ends] - truth[ends])) >= 0.4 * np.max(np.abs(truth))
    assert motion.SMOOTH.hold and not motion.FAST.hold
