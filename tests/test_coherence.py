"""coherence: a pair's two half-sweeps hold one body where their phases move together."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from fmcw_cl import coherence

PERIOD = 5e-5
K = 4 * np.pi / 1.55e-6          # rad/m at 1550 nm
N = 2000


def _pairs(first, second, velocity, snr_db, rng, n=N):
    """Pairs at 20 kHz whose first half-sweep sees body `first` (R(t), m) and second
    `second`, with phase noise 1 / sqrt(2 SNR) and the given pair velocities."""
    t = PERIOD * (np.arange(n) + 0.5)
    sweep = np.stack([t - PERIOD / 4, t + PERIOD / 4])
    sigma = 1 / np.sqrt(2 * 10 ** (snr_db / 10))
    phase = np.stack([K * first(sweep[0]) + 0.7, K * second(sweep[1]) - 2.1])
    phase = np.angle(np.exp(1j * (phase + rng.normal(0, sigma, phase.shape))))
    snr = np.full((2, n), float(snr_db))
    return t, sweep, phase, snr, velocity(t)


def _take_off(t):
    """A foot at rest, then pushed off: its acceleration ramps 0 -> 350 m/s^2 over 2 ms
    (a jerk of 1.75e5 m/s^3), then holds; 0.3 m at rest."""
    u = np.clip(t - 0.04, 0, None)
    return 0.3 + np.where(u < 2e-3, 1.75e5 * u ** 3 / 6, 1.75e5 * 8e-9 / 6 + 350 * (u - 2e-3) ** 2 / 2
                          + 0.35 * (u - 2e-3))


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_one_body_moves_alike_in_both_directions(seed):
    """A take-off (jerk and all), a rail braking, a body at rest: not a pair flagged at
    a lab's 15-35 dB, the velocities scattered by 3 mm/s."""
    rng = np.random.default_rng(seed)
    bodies = [_take_off, lambda t: 0.1 + 2.2 * t - 16 * t * t, lambda t: 0.2 + 0 * t]
    dt = 1e-7
    for body in bodies:

        def speed(t, body=body):
            return (body(t + dt) - body(t - dt)) / (2 * dt) + rng.normal(0, 0.003, t.size)

        for snr in (15, 35):
            t, sweep, phase, level, v = _pairs(body, body, speed, snr, rng)
            used = np.ones(t.size, bool)
            assert not coherence.apart(t, sweep, phase, level, v, used, K, PERIOD).any()


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_two_bodies_peaks_in_one_pair_are_apart(seed):
    """A rail braking (+2.2 m/s) in the first half-sweeps, a glide speeding up (-1.0
    m/s) in the second: the directions' difference turns by k T (v_A - v_B) a step and
    drifts by k T^2 (a_A - a_B); every pair flagged. So are two bodies at steady speeds
    whose difference turns by a fixed angle a step away from zero."""
    rng = np.random.default_rng(seed)
    rail = lambda t: 0.2 + 2.2 * t - 16 * t * t          # noqa: E731
    glide = lambda t: 0.32 - 1.0 * t - 10 * t * t        # noqa: E731
    t, sweep, phase, snr, v = _pairs(rail, glide, lambda t: 0.6 + 0 * t, 25, rng, 200)
    used = np.ones(t.size, bool)
    assert coherence.apart(t, sweep, phase, snr, v, used, K, PERIOD).all()
    # steady: the step's turn k T (v_A - v_B), 1.3 rad off a whole number of turns
    dv = (2 * np.pi * 411 + 1.3) / (K * PERIOD)
    t, sweep, phase, snr, v = _pairs(lambda t: 0.2 + dv * t, lambda t: 0.2 + 0 * t,
                                     lambda t: 0.5 * dv + 0 * t, 25, rng, 200)
    assert coherence.apart(t, sweep, phase, snr, v, used, K, PERIOD).all()


def test_weak_pairs_are_not_judged_and_lone_pairs_follow_their_window():
    """Where the SNRs promise too little coherence (5 dB: a resultant length of 0.6) the
    phases judge nothing; a verified pair between a bad window's steps, whose own
    neighbours are too far for a step, goes with them."""
    rng = np.random.default_rng(4)
    rail = lambda t: 0.2 + 2.2 * t - 16 * t * t          # noqa: E731
    glide = lambda t: 0.32 - 1.0 * t - 10 * t * t        # noqa: E731
    t, sweep, phase, snr, v = _pairs(rail, glide, lambda t: 0.6 + 0 * t, 5, rng, 200)
    used = np.ones(t.size, bool)
    assert not coherence.apart(t, sweep, phase, snr, v, used, K, PERIOD).any()
    t, sweep, phase, snr, v = _pairs(rail, glide, lambda t: 0.6 + 0 * t, 25, rng, 200)
    used[96:100] = used[101:105] = False        # pair 100 alone: 5 periods to either neighbour
    out = coherence.apart(t, sweep, phase, snr, v, used, K, PERIOD)
    assert out[100] and np.array_equal(out, used)


def test_slope_is_the_local_least_squares_slope():
    rng = np.random.default_rng(5)
    t = np.sort(rng.uniform(0, 1, 300))
    y = 3.0 * t + rng.normal(0, 0.01, t.size)
    at = np.array([0.2, 0.5, 0.8])
    got = coherence.slope(t, y, at, 0.1)
    for g, a in zip(got, at, strict=True):
        near = np.abs(t - a) <= 0.1
        assert g == pytest.approx(np.polyfit(t[near], y[near], 1)[0], rel=1e-9)
    assert coherence.slope(t[:2], y[:2], at, 0.1).tolist() == [0.0, 0.0, 0.0]


def _track_of(first, second, velocity, snr_db, rng, n=400):
    """A Track whose pairs hold `first` in their first half-sweeps and `second` in
    their second (distances: their mean; velocities as given), all verified."""
    from fmcw_cl.stages import faults
    from fmcw_cl.track import Track

    t, sweep, phase, snr, v = _pairs(first, second, velocity, snr_db, rng, n)
    d = 0.5 * (first(t) + second(t))
    sweeps = np.stack([sweep[0], sweep[1]], axis=1).ravel()
    rising = np.tile([True, False], n)
    return Track(sweeps, rising, np.repeat(d, 2), snr.T.ravel(), t, d, v, np.zeros(n), np.ones(n, bool), {},
                 sweep_distance_dechirped_m=np.repeat(d, 2), sweep_snr_dechirped_db=snr.T.ravel(),
                 reason=np.zeros(n, np.uint8) + faults.OK, period_s=PERIOD,
                 sweep_phase_rad=phase.T.ravel())


def test_a_tracks_two_bodies_are_ambiguous_its_sums_are_not_judged():
    """On a Track: the pairs of two bodies' peaks flagged, one body's not; a track whose
    pairs each sum K half-sweeps (weak-echo integration) is not judged (its phase is a
    sum's: an occluder integrated over 1.6 ms read its place before it was seen)."""
    from fmcw_cl import objects
    from fmcw_cl.stages import faults

    rng = np.random.default_rng(6)
    rail = lambda t: 0.2 + 2.2 * t - 16 * t * t          # noqa: E731
    glide = lambda t: 0.32 - 1.0 * t - 10 * t * t        # noqa: E731
    ghost = _track_of(rail, glide, lambda t: 0.6 + 0 * t, 25, rng)
    assert coherence.two_bodies(ghost, K).all()
    one = _track_of(rail, rail, lambda t: 2.2 - 32 * t, 25, rng)
    assert not coherence.two_bodies(one, K).any()
    ghost.attrs["integrated_sweeps_max"] = 32
    assert not coherence.two_bodies(ghost, K).any()
    # the pairs left between two bodies' are verified again: one alone is vouched for by none
    lone = objects.invalidated(one, np.arange(one.pairs) != 105)
    assert lone.valid.sum() == 1
    again = coherence.verified_again(lone)
    assert not again.valid.any() and again.reason[105] == faults.UNVERIFIED


def test_an_object_is_cut_where_its_tracker_held_two_bodies():
    """Two legs' plateaus within the resolution at once, parting at +0.18 and +0.19 m/s:
    the tracker came out on one of them and nothing tells which (movers.py seed 7, 10:
    365 valid pairs of one leg on the object of the other). Where a run of two bodies'
    pairs has verified pairs on both sides, one of them slow, and another mover can have
    been there, the object is cut in its middle: two objects, neither holding a pair of
    the other side. A run at an end cuts nothing, nor one a body runs through on both
    sides (its velocity tells), nor one no other mover can have reached."""
    from fmcw_cl import objects, scene

    rng = np.random.default_rng(7)
    creep = lambda t: 0.28 + 0.1 * t - 20 * t * t      # noqa: E731
    one = _track_of(creep, creep, lambda t: 0.1 - 40 * t, 25, rng)     # 0.1 m/s, at rest at 2.5 ms
    rise = lambda t: 0.27 + 1.0 * t                    # noqa: E731   the other leg, rising at 1 m/s
    other = _track_of(rise, rise, lambda t: 1.0 + 0 * t, 25, rng)
    other = objects.invalidated(other, other.time_s > 0.004)               # lost at 4 ms, 5 mm below
    far = replace(other, distance_m=other.distance_m - 0.3)                # 0.3 m away: no body gets there
    two = np.zeros(one.pairs, bool)
    two[180:220] = True                                                    # 9-11 ms
    assert coherence.cuts(one, two, [other]).tolist() == pytest.approx([0.5 * (one.time_s[180]
                                                                                + one.time_s[219])])
    assert coherence.cuts(one, two, []).size == 0 and coherence.cuts(one, two, [far]).size == 0
    for end in (slice(0, 40), slice(360, 400)):
        edge = np.zeros(one.pairs, bool)
        edge[end] = True
        assert coherence.cuts(one, edge, [other]).size == 0
    o = objects.SceneObject(0, False, one, "a leg at rest")
    cut = coherence.cuts(one, two, [other])
    parts = scene._taken(o, np.zeros(one.pairs, bool), two, cut)
    assert len(parts) == 2
    before, after = (np.flatnonzero(p.track.valid) for p in parts)
    assert before.max() < 180 and after.min() >= 220 and before.size + after.size >= 340
    assert all(p.whole is one for p in parts)
    clash = scene._taken(o, two, np.zeros(one.pairs, bool), np.zeros(0))    # another's echo beside: no cut
    assert len(clash) == 1 and clash[0].track.valid.sum() == 360
    rail = lambda t: 0.2 + 2.2 * t - 16 * t * t          # noqa: E731
    fast = _track_of(rail, rail, lambda t: 2.2 - 32 * t, 25, rng)
    assert coherence.cuts(fast, two, [other]).size == 0


def test_a_run_the_velocity_turns_across_is_cut():
    """Two legs crossing at -0.50 and +0.43 m/s: the tracker held the first before its
    run of two bodies' pairs and the second after (42 valid pairs of the second on the
    first's object, movers.py seed 10, 15). Both sides move, but the velocity turned by
    0.9 m/s in 1.6 ms beyond what the accelerations either side carry it: cut."""
    rng = np.random.default_rng(15)
    t0 = 0.010
    down = lambda t: 0.0743 - 0.5 * (t - t0)             # noqa: E731
    up = lambda t: 0.0743 + 0.43 * (t - t0)              # noqa: E731
    leg = lambda t: np.where(t < t0, down(t), up(t))     # noqa: E731
    track = _track_of(leg, leg, lambda t: np.where(t < t0, -0.5, 0.43), 25, rng)
    two = (track.time_s > t0 - 0.0008) & (track.time_s < t0 + 0.0008)
    other = _track_of(up, up, lambda t: 0.43 + 0 * t, 25, rng)
    other = objects_invalidated(other, other.time_s > t0 - 0.002)     # the rising leg, lost 2 ms before
    assert coherence.cuts(track, two, [other]).size == 1
    steady = _track_of(down, down, lambda t: -0.5 + 0 * t, 25, rng)
    assert coherence.cuts(steady, two, [other]).size == 0 and coherence.cuts(track, two, []).size == 0


def objects_invalidated(track, where):
    from fmcw_cl import objects

    return objects.invalidated(track, where)
