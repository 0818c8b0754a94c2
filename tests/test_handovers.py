"""A tracker that passes from one echo to another at once (fmcw_cl.handovers): two
bodies, whatever one body's motion could join, and a fade's noise or a return to its
own echo is not such a pass."""

from __future__ import annotations

import numpy as np
import pytest

from fmcw_cl import handovers, identities, objects
from fmcw_cl.stages import faults
from fmcw_cl.track import Track

PERIOD = 50e-6
N = 1200
T = PERIOD * (np.arange(N) + 0.5)


def _track(path: np.ndarray, velocity: np.ndarray, valid: np.ndarray, seed: int) -> Track:
    """A conversion's track whose tracker held `path` (m; its de-chirped half-sweep peaks
    that, with 30 um of noise), verified at `valid`."""
    rng = np.random.default_rng(seed)
    sweeps = np.repeat(path, 2) + 3e-5 * rng.standard_normal(2 * N)
    reason = np.where(valid, faults.OK, faults.AMBIGUOUS).astype(np.uint8)
    return Track(np.repeat(T, 2) + np.tile([-PERIOD / 4, PERIOD / 4], N), np.tile([True, False], N),
                 sweeps, np.full(2 * N, 25.0), T, np.where(valid, path, np.nan),
                 np.where(valid, velocity, np.nan), np.zeros(N), valid, {},
                 sweep_distance_dechirped_m=sweeps, sweep_snr_dechirped_db=np.full(2 * N, 25.0),
                 reason=reason, period_s=PERIOD)


def _rail_then_glide(flip: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A rail at +1.8 m/s slowing at 45 m/s^2 (pairs 0-559), its tracker then on a glide
    at rest 20 mm beyond it that sets off towards it at -60 m/s^2 (verified from pair
    1160 on, `flip` pairs before that on another echo 20 mm beyond it): the glide's pairs
    lie where the rail slowing at 90 m/s^2 would be."""
    t0 = T[560]
    rail = 0.30 + 1.8 * T - 22.5 * T ** 2
    start = rail[559] + 0.020
    go = np.maximum(T - T[600], 0.0)
    glide = start - 30.0 * go ** 2
    path = np.where(T < t0, rail, glide)
    velocity = np.where(T < t0, 1.8 - 45.0 * T, -60.0 * go)
    path[1160 - flip:1160] += 0.02
    valid = (np.arange(N) < 560) | (np.arange(N) >= 1160)
    return path, velocity, valid


@pytest.mark.parametrize("seed", [1, 2, 3])
@pytest.mark.parametrize("flip", [0, 34])
def test_a_tracker_passed_to_another_echo_at_once_holds_two_bodies(seed, flip):
    """The verified pairs either side of the gap make one body's course (`seen_again`), so
    the motion alone joins them; the tracker's pass from the rail straight onto the glide
    parts them, the glide's 34 pairs on the rail at its end notwithstanding, and no join
    mends it."""
    path, velocity, valid = _rail_then_glide(flip)
    track = _track(path, velocity, valid, seed)
    a, b = 559, 1160
    assert objects.seen_again(T[a], path[a], velocity[a], T[b], path[b], velocity[b])
    before, after = handovers.handovers(track)
    assert before.tolist() == [T[a]] and after.tolist() == [T[b]]
    scene = identities.rejoined(identities.parted([objects.SceneObject(1, True, track, "")]), True)
    held = sorted(int(o.track.valid.sum()) for o in scene)
    assert held == sorted([560, N - 1160])
    for o in scene:                              # each part one body's, not both
        k = np.flatnonzero(o.track.valid)
        assert k.max() < 560 or k.min() >= 1160


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_pass_through_pairs_whose_peaks_part_holds_two_bodies(seed):
    """A glide at -2.4 m/s passing a glide at rest 8 mm nearer (movers.py seed 19, capture
    23): its last 6 pairs' rising peaks stay as the falling ones follow it (up to 2.4 mm
    apart: on no chain, the last verified one too), then the tracker is on the rest, the
    rest verified from 7 ms on. A body landing there could join them; the step from
    the glide's chain onto the rest's, across the parting pairs, parts them."""
    glide = 0.3300 - 2.4 * (T - T[400])
    rest = np.full(N, 0.3133)
    path = np.where(np.arange(N) < 560, glide, rest)
    velocity = np.where(np.arange(N) < 560, -2.4, 0.0)
    valid = (np.arange(N) < 560) | (np.arange(N) >= 700)
    track = _track(path, velocity, valid, seed)
    lag = 4.8e-4 * np.arange(1, 7)                  # the rising peaks held where they were
    track.sweep_distance_dechirped_m[2 * 554:2 * 560:2] += lag
    before, after = handovers.handovers(track)
    assert before.tolist() == [T[559]] and after.tolist() == [T[700]]
    scene = identities.rejoined(identities.parted([objects.SceneObject(1, True, track, "")]), True)
    assert sorted(int(o.track.valid.sum()) for o in scene) == [N - 700, 560]


@pytest.mark.parametrize("seed", [1, 2, 3])
@pytest.mark.parametrize("agree", [False, True])
def test_noise_pairs_at_a_stretchs_end_are_no_pass(seed, agree):
    """A rail's two pairs in a fade, one half-sweep's peak 2.5 and 4.7 mm off (or both
    peaks 1.2 and 2.4 mm off, so the path drifts by a step), then on its own echo
    again: the stretch's end is its pairs' before them, not the drift's -6.6 m/s."""
    path = 0.28 + 0.3 * T
    valid = np.ones(N, bool)
    valid[400:402] = False
    track = _track(path, np.full(N, 0.3), valid, seed)
    off = np.array([1.2e-3, 2.4e-3])
    rise = track.sweep_distance_dechirped_m[800:804:2]
    fall = track.sweep_distance_dechirped_m[801:804:2]
    if agree:
        rise -= off
        fall -= off
    else:
        rise -= 2 * off
    track.sweep_distance_dechirped_m[800:804:2], track.sweep_distance_dechirped_m[801:804:2] = rise, fall
    assert handovers.handovers(track)[0].size == 0


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_fade_or_a_return_to_its_own_echo_is_no_pass(seed):
    """Lost in a fade (noise peaks over the band) and back on its own body, or passed to
    a wall 40 mm off for 10 ms and back: no pass between the verified pairs' echoes (the
    later's chain starts after the wall's), and the track stays one object."""
    rng = np.random.default_rng(seed)
    body = 0.30 + 1.0 * T
    valid = (np.arange(N) < 400) | (np.arange(N) >= 800)
    faded = body.copy()
    faded[400:800] = rng.uniform(0.02, 0.45, 400)
    walled = body.copy()
    walled[400:600] = body[399] + 0.04
    walled[600:800] = rng.uniform(0.02, 0.45, 200)        # then a fade back to it
    for path in (faded, walled):
        track = _track(path, np.ones(N), valid, seed)
        assert handovers.handovers(track)[0].size == 0
        assert len(identities.rejoined(identities.parted([objects.SceneObject(1, True, track, "")]))) == 1


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_tracker_back_from_an_echo_it_crossed_onto_is_no_pass(seed):
    """A sway at +1.9 m/s unverified as it crosses a glide at +0.4 m/s: its tracker
    goes on along the glide (no step, a kink), then steps back onto the sway 2.5 ms
    on: the step is from the glide's chain, not the sway's, and the sway stays whole."""
    sway = 0.15 + 1.9 * T
    cross = 560
    glide = sway[cross] + 0.4 * (T - T[cross])
    path = sway.copy()
    path[cross:cross + 50] = glide[cross:cross + 50]
    valid = (np.arange(N) < 520) | (np.arange(N) >= 640)
    track = _track(path, np.full(N, 1.9), valid, seed)
    lab = handovers.chains(T, path)
    assert lab[cross - 30] != lab[cross + 30]                 # the kink parts the chains
    assert handovers.handovers(track)[0].size == 0
    assert len(identities.rejoined(identities.parted([objects.SceneObject(1, True, track, "")]))) == 1


def test_chains_join_a_stretch_that_goes_on_as_an_echo_and_skip_noise():
    """An echo's stretches either side of a 34-pair flip onto another are one chain;
    a stretch of noise peaks is none, and an echo's stretch after it a chain of its
    own when it starts beyond LINK_S after."""
    rng = np.random.default_rng(4)
    path = 0.30 - 0.5 * T
    path[300:334] += 0.02                        # a flip onto another echo
    path[600:700] = rng.uniform(0.02, 0.45, 100)   # noise
    path[700:] += 0.01                             # on again 10 mm off, 5 ms later
    lab = handovers.chains(T, path)
    assert lab[0] == lab[299] == lab[334] == lab[599] >= 0
    assert lab[300] not in (-1, lab[0])
    assert (lab[600:700] == -1).all()
    assert lab[700] not in (-1, lab[0], lab[300])


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_noisy_paths_slopes_make_no_kinks_a_turn_does(seed):
    """A glide decelerating at 83 m/s^2 whose path reads 0.1 mm of noise (a peak at
    about 20 dB): its 8-pair slopes scatter by 0.3 m/s, and at KINK_MPS alone it broke
    into stretches of a few pairs (movers.py seed 20, capture 21); it is one chain. A
    turn by 6 m/s in that noise still starts a stretch, and in a quiet path one by
    1 m/s does."""
    rng = np.random.default_rng(seed)
    k = np.arange(N)
    glide = 0.27 - 1.15 * T - 41.5 * T ** 2
    noisy = glide + 1e-4 * rng.standard_normal(N)
    lab = handovers.chains(T, noisy)
    assert lab[0] >= 0 and np.mean(lab == lab[0]) > 0.95
    turned = noisy + np.where(k >= 600, 6.0 * (T - T[600]), 0.0)
    starts = np.flatnonzero(handovers.stretches(T, turned))
    assert np.any(np.abs(starts - 600) <= handovers.TREND_PAIRS)
    quiet = glide + 2e-5 * rng.standard_normal(N) + np.where(k >= 600, 1.0 * (T - T[600]), 0.0)
    assert np.any(np.abs(np.flatnonzero(handovers.stretches(T, quiet)) - 600) <= handovers.TREND_PAIRS)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_pass_from_the_body_come_to_rest_onto_another_holds_two_bodies(seed):
    """movers.py seed 20, capture 21: a rail slowing at 83 m/s^2 (verified to pair 399),
    its tracker then on a glide at rest 8 mm beyond (100 pairs), then on the rail come
    to rest (140 pairs), then straight onto the glide setting off (verified from pair
    700): the step onto the later's chain is from the rail's body (seen again at rest
    where it slowed to), not from its own chain, and still parts the two. Where the
    tracker left the rail's chain for that echo at once (a step off it), the echo is
    not the rail's and the step onto the glide parts nothing."""
    t0 = T[400]
    rail = 0.2717 + 0.99 * (T - t0) - 41.5 * (T - t0) ** 2
    stop = 0.2717 + 0.99 ** 2 / 166.0
    glide = 0.2806 - 0.5 * 60.0 * np.maximum(T - T[690], 0.0) ** 2
    k = np.arange(N)
    path = np.where(k < 420, rail, glide)
    path[560:700] = stop
    velocity = np.where(k < 400, 0.99 - 83.0 * (T - t0), -60.0 * np.maximum(T - T[690], 0.0))
    valid = (k < 400) | (k >= 700)
    track = _track(path, velocity, valid, seed)
    before, after = handovers.handovers(track)
    assert before.tolist() == [T[399]] and after.tolist() == [T[700]]
    path[420:700] = stop + 0.01               # off the rail's chain at once onto a still echo
    assert handovers.handovers(_track(path, velocity, valid, seed))[0].size == 0


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_lone_tracks_brief_pass_onto_another_echo_is_ambiguous(seed):
    """movers.py seed 20, capture 30: two legs landing 5 mm apart, one object; its
    tracker left the one for the other for 39 pairs and came back. Those pairs are
    another echo's (`ambiguous`), the body's stay; held for BODY_PAIRS or more, the
    track holds two bodies, every pair ambiguous (lone_bodies.one_body)."""
    from fmcw_cl import lone_bodies

    k = np.arange(N)
    body = 0.0765 - 0.14 * T
    for flip, left in ((39, N - 41), (45, 0)):
        other = (k >= 600) & (k < 600 + flip)
        path = np.where(other, body - 0.0045 - 0.16 * (T - T[600]), body)
        velocity = np.where(other, -0.3, -0.14)
        valid = (k != 599) & (k != 600 + flip)           # the pairs at the steps unverified
        track = _track(path, velocity, valid, seed)
        out = lone_bodies.one_body(track, True)
        assert int(out.valid.sum()) == left
        assert not out.valid[other].any() and np.all(out.reason[other & valid] == faults.AMBIGUOUS)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_chain_after_a_gap_is_the_verified_pairs_own(seed):
    """A glide at +3.8 m/s whose tracker held a sway near its turn 20 mm short of it for
    5 ms, came back onto the glide for 5 verified pairs, their peaks apart (on no chain),
    then onto the sway again (movers.py seed 20, capture 24): the chain after the gap is
    not the sway's, which lies nowhere near the verified pairs' course; no pass."""
    k = np.arange(N)
    glide = 0.2769 + 3.8 * (T - T[400])
    sway = np.full(N, 0.2553)
    path = np.where((k >= 400) & (k < 500) | (k >= 505) & (k < 700), sway, glide)
    valid = (k < 400) | (k >= 500) & (k < 505) | (k >= 700)
    track = _track(path, np.full(N, 3.8), valid, seed)
    track.sweep_distance_dechirped_m[2 * 500:2 * 505:2] += 1.5e-3        # peaks apart: on no chain
    before, after = handovers.handovers(track)
    assert T[399] not in before.tolist()


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_turn_onto_a_crossing_echo_holds_two_bodies(seed):
    """Two legs crossing 0.5 mm apart at +0.41 and -0.80 m/s, unverified (movers.py seed
    15, capture 20): the tracker goes on along the other leg, a kink between chains and
    no step, verified on it 4 ms on, where one body's motion could join the pairs either
    side. No body turns by 1.2 m/s in the 1.1 ms between the chains' slopes: a pass."""
    k = np.arange(N)
    leg = 0.20 + 0.41 * (T - T[560])
    other = 0.2005 - 0.80 * (T - T[560])
    path = np.where(k < 560, leg, other)
    valid = (k < 520) | (k >= 640)
    track = _track(path, np.where(k < 560, 0.41, -0.80), valid, seed)
    assert objects.seen_again(T[519], path[519], 0.41, T[640], path[640], -0.80)
    before, after = handovers.handovers(track)
    assert before.tolist() == [T[519]] and after.tolist() == [T[640]]


def test_a_landing_in_noise_is_no_turn():
    """A foot landing at -4.8 m/s and slowing at 450 m/s^2 through a fade of 10 pairs,
    its path 0.1 mm noisy (its 16-pair slopes 0.1 m/s, its ends' medians 0.2): where the
    noise keeps its chains apart, their slopes still agree within what the noise and
    the slowing allow. No pass on any of ten seeds (the ends' medians against
    KINK_MPS + ACCEL_MAX dt made one on seed 7)."""
    k = np.arange(N)
    slow = np.maximum(T - T[300], 0.0)
    foot = 0.30 - 4.8 * (T - T[300]) + 225.0 * slow ** 2
    foot = np.where(k < 700, foot, foot[700])
    velocity = np.where(k < 700, -4.8 + 450.0 * slow, 0.0)
    valid = (k < 540) | (k >= 600)
    for seed in range(1, 11):
        path = foot + 1e-4 * np.random.default_rng(seed).standard_normal(N)
        path[560:570] = np.nan
        assert handovers.handovers(_track(path, velocity, valid, seed))[0].size == 0, seed
