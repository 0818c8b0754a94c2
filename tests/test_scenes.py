"""Real scenes at a lab's SNR (0 dB per sample): a stronger wall behind the target,
speckle fading, a landing at close range, and the echoes a track lists."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from conftest import process, realistic, scene_of

from fmcw_cl import fixed_echoes, objects, swing
from fmcw_cl.capture import Capture
from fmcw_cl.evaluate import accuracy, truth_at, valid_errors
from fmcw_cl.options import Options
from fmcw_cl.simulator import SimulationConfig, simulate_capture, static
from fmcw_cl.stages import faults
from fmcw_cl.track import read_track, track_path


def scored(path, **opts):
    track = process(path, Options(**opts))
    with Capture(path) as cap:
        return accuracy(track, cap.truth()), track


def wrong(track, truth, limit=2e-3) -> int:
    """Valid pairs more than `limit` m from the truth."""
    return int(np.sum(valid_errors(track, truth) > limit))


def test_the_moving_target_is_tracked_past_a_stronger_wall(wall_capture, tmp_path, fmcw):
    # as a user runs it first: the wall is a fixed echo, the moving target is tracked
    proc = fmcw("process", wall_capture, "-o", tmp_path, "--backend", "numpy")
    note = [w for w in proc.stderr.splitlines() if "leaving out the fixed echo at 0.420 m" in w]
    assert len(note) == 1 and "the target (moving, 0.0" in note[0] and "--target-near" in note[0], proc.stderr
    track = read_track(track_path(tmp_path, wall_capture))
    with Capture(wall_capture) as cap:
        truth = cap.truth()
    assert wrong(track, truth) == 0
    assert track.valid.mean() >= 0.95
    assert track.attrs["target_moving"] and track.attrs["target_rule"] == "auto"
    assert np.any(np.abs(track.attrs["target_fixed_echoes_m"] - 0.42) < 2e-3)
    assert track.attrs["target_band_m"][1] < 0.42 - 0.01
    # the wall is still listed, never hidden, but out of the band
    pers = track.echoes.persistent
    assert np.any((np.abs(pers["distance_m"] - 0.42) < 2e-3) & ~pers["in_band"])
    # the strongest echo pair by pair (the user's explicit choice) follows the wall in flight
    _, strongest = scored(wall_capture, target="strongest")
    assert np.sum(np.abs(strongest.distance_m[strongest.valid] - 0.42) < 2e-3) > 1000
    # with the band closed by hand: the pipeline's figures
    acc, track = scored(wall_capture, max_range=0.40)
    assert acc["valid_share"] >= 0.98
    assert acc["distance_p95_m"] <= 0.5e-3
    assert acc["velocity_p95_mps"] <= 0.02
    assert wrong(track, truth) == 0


def test_the_shipped_wall_sample_is_never_wrong(fmcw, tmp_path):
    from pathlib import Path

    sample = Path(__file__).parent.parent / "data_samples" / "jump_wall_fading.h5"
    track = process(sample)
    with Capture(sample) as cap:
        assert wrong(track, cap.truth()) == 0
    assert track.valid.mean() >= 0.9 and track.attrs["target_moving"]


@pytest.mark.parametrize("seed", [41, 42])
def test_a_wall_inside_the_targets_span_is_never_wrong(tmp_path, seed):
    """The jump crosses a wall's distance: the wall is an object; the target's pairs there
    are `ambiguous`, or its own where the target's rows are without still echoes (the
    wall not among them: fmcw_cl.scene); none wrong."""
    path = realistic(tmp_path / "crossing.h5", seed=seed, reflectors=((0.20, 800.0),), speckle_s=3e-3)
    track = process(path)
    with Capture(path) as cap:
        assert wrong(track, cap.truth()) == 0
    assert track.attrs["invalid_ambiguous"] > 0 or track.attrs["still_echoes_removed_s"] > 0
    walls = [o for o in track.objects if o.kind == "fixed"]
    assert any(abs(np.mean(o.attrs()["distance_span_m"]) - 0.20) < 2e-3 for o in walls)
    near = track.valid & (np.abs(track.distance_m - 0.20) <= objects.GATE_M)
    assert track.attrs["still_echoes_removed_s"] > 0 or not near.any()


@pytest.mark.parametrize("seed", [1, 2])
def test_an_accelerating_targets_doppler_image_is_no_fixed_echo(tmp_path, seed):
    """Lab conditions (a weak intensity triangle, a 20 MHz table), the rail's start: under
    steady acceleration the rising half-sweeps' plain peak d - k v stays put for tens of
    ms, in one direction only; it must not pass for a wall the target is confused with."""
    from fmcw_cl.simulator import rail

    path = tmp_path / "rail.h5"
    cfg = SimulationConfig(leak_codes=150.0, noise_codes=600.0, table_noise_hz=20e6)
    simulate_capture(path, rail(0.4), 0.05, seed=seed, config=cfg, start_s=0.05)
    track = process(path)
    with Capture(path) as cap:
        assert wrong(track, cap.truth()) == 0
    assert track.attrs["invalid_ambiguous"] == 0 and track.valid.mean() >= 0.99


def test_two_static_reflectors_are_two_objects_until_the_user_chooses(tmp_path, fmcw):
    path = tmp_path / "two.h5"
    cfg = SimulationConfig(snr_db=0.0, reflectors=((0.37, 400.0),))
    simulate_capture(path, static(0.02, 0.21), 0.02, seed=41, config=cfg)
    track = process(path)
    # no echo moves: each is an object, valid on its own; nothing tells which is the
    # target, so /track's pairs are ambiguous and both objects are named
    scores = scene_of(track, path)
    assert sorted(s["truth"] for s in scores) == [0, 1] and min(s["tracked"] for s in scores) >= 0.95
    assert not track.valid.any() and (track.reason == faults.AMBIGUOUS).all()
    assert track.attrs["target_object"] == 0
    proc = fmcw("process", path, "-o", tmp_path / "out", "--backend", "numpy")
    assert "no object moves: the fixed objects at 0.210, 0.370 m cannot be told apart" in proc.stderr
    assert "--target-near 0.210 chooses it" in proc.stderr and "--target-near 0.370 chooses it" in proc.stderr
    strongest = process(path, Options(target="strongest"))     # the tracker alone, in the whole band
    e = strongest.echoes
    near = lambda d: np.abs(e.distance_m - d) < 1e-3  # noqa: E731
    sweeps = strongest.sweep_time_s.size
    assert near(0.21).sum() >= 0.98 * sweeps and e.tracked[near(0.21)].all()
    assert near(0.37).sum() >= 0.98 * sweeps and not e.tracked[near(0.37)].any()
    assert np.sum(~near(0.21) & ~near(0.37)) <= 0.02 * sweeps        # false echoes are rare
    # 400 codes at 0.37 m against 1500 * 0.1/0.21 = 714 at 0.21 m: about 5 dB weaker
    assert strongest.attrs["rival_echo_m"] == pytest.approx(0.37, abs=1e-3)
    assert -8 < strongest.attrs["rival_echo_db"] < -2
    # each rule that names one: that one
    for opts, want in (({"target": "nearest"}, 0.21), ({"target": "strongest"}, 0.21),
                       ({"target_near": 0.36}, 0.37)):
        got = process(path, Options(**opts))
        assert got.valid.mean() >= 0.98, opts
        assert np.all(np.abs(got.distance_m[got.valid] - want) < 0.5e-3), opts


@pytest.mark.parametrize("seed", [1, 2])
def test_a_stronger_wall_under_full_scale_noise_is_told_from_the_target(tmp_path, seed):
    """A lab's target at 0.3 m (500 codes) under noise at full scale, a stronger wall at
    0.45 m (800 codes): the CFAR sees neither echo in enough single half-sweeps, their
    mean spectra see both, so the rule cannot tell which is the target and no pair is
    valid (tracking the wall as "one echo: the target" put 94 % of the pairs 150 mm from
    the target). Each is an object: no pair of either on the other. The sync delay is
    refined on the wall across the isolated pairs noise leaves invalid (without
    bridging them, seed 2 kept an intensity estimate 51 samples off and every velocity
    0.24 m/s off)."""
    import fmcw_cl

    path = tmp_path / "fs.h5"
    drawn = fmcw_cl.simulate(path, "static", duration=0.05, seed=seed, noise=3000.0, lab=True,
                             no_headroom=True, reflectors=((0.45, 800.0),))["sync_delay_samples"]
    track = process(path)
    scene_of(track, path)
    fixed = np.sort(track.attrs["target_fixed_echoes_m"])
    assert fixed.size == 2 and np.all(np.abs(fixed - [0.30, 0.45]) < 2e-3)
    m = process(path, Options(target="strongest")).echoes.means     # the whole band's mean spectra
    for rising in (True, False):           # both echoes in every full mean spectrum of both directions
        blocks = np.unique(m["mean_time_s"][m["mean_rising"] == rising])
        for d in (0.30, 0.45):
            seen = m["peak_time_s"][(m["peak_rising"] == rising) & (np.abs(m["peak_distance_m"] - d) < 2e-3)]
            assert np.unique(seen).size >= blocks.size - 1
    assert track.attrs["sync_delay_refined"]
    assert abs(track.attrs["sync_delay_samples"] - drawn) < 1.0


def test_two_moving_echoes_are_two_objects(tmp_path):
    """The jump and, beyond it, a second limb swinging 0.38-0.42 m at 8 Hz (1 m/s) and
    stronger than the target in flight: the strongest echo hops between the two; each is
    an object, the leg (it travels furthest) the target."""
    from fmcw_cl.simulator.scene import Trajectory

    w = 2 * np.pi * 8
    sway = Trajectory.from_velocity(0.0, 0.31, lambda t: 0.02 * w * np.cos(w * t),
                                    lambda t: -0.02 * w * w * np.sin(w * t), 0.40)
    path = realistic(tmp_path / "limbs.h5", seed=1, movers=((sway, 800.0),), speckle_s=3e-3)
    with Capture(path) as cap:
        truth = cap.truth()
    _, strongest = scored(path, target="strongest")
    on_sway = np.abs(strongest.distance_m - sway.at(strongest.time_s)[0]) < 2e-3
    assert np.sum(strongest.valid & on_sway) > 1000        # the scene is what it claims
    track = process(path)
    scores = scene_of(track, path)            # each its own object, neither's pair on the other
    assert {s["truth"] for s in scores if s["tracked"] >= 0.8} == {0, 1}, scores
    assert next(s["truth"] for s in scores if s["id"] == track.attrs["target_object"]) == 0   # the leg
    others = track.attrs["target_others"]            # what `process` names, with the option for it
    assert "(moving, 0.3" in others and "--target-near 0.4" in others, others
    got = process(path, Options(target_near=0.2))
    assert wrong(got, truth) == 0 and got.valid.mean() >= 0.90
    assert 0.31 < got.attrs["target_band_m"][1] < 0.37


@pytest.mark.parametrize("seed, noise", [(1, None), (2, None), (2, 3000.0)])
def test_a_target_at_rest_behind_a_far_stronger_wall_is_never_the_wall(tmp_path, seed, noise):
    """A lab's target at rest at 0.40 m (375 codes) and a wall at 0.25 m 12 dB
    stronger: tracking the wall as "one echo: the target" put every pair 150 mm off.
    Both are fixed echoes at any level: each is an object, and neither holds a pair of
    the other. Under noise at full scale (seed 2) the target's mean-spectrum peaks are
    in 3 and 4 of 6 blocks of each direction, in both of one block in fewer than 3."""
    from fmcw_cl.simulator import LAB

    path = tmp_path / "behind.h5"
    lab = LAB if noise is None else replace(LAB, noise_codes=noise, headroom=None)
    simulate_capture(path, static(0.05, 0.40), 0.05, seed=seed,
                     config=replace(lab, reflectors=((0.25, 1500.0),)))
    track = process(path)
    scene_of(track, path)
    assert np.allclose(np.sort(track.attrs["target_fixed_echoes_m"]), [0.25, 0.40], atol=2e-3)
    got = process(path, Options(target_near=0.40))
    assert got.valid.mean() >= 0.95                       # 97.9 % under noise at full scale
    assert np.all(np.abs(got.distance_m[got.valid] - 0.40) < 0.5e-3)


@pytest.mark.parametrize("seed, noise", [(1, None), (2, 3000.0)])
def test_a_target_at_rest_five_cells_beside_a_stronger_wall_is_never_the_wall(tmp_path, seed, noise):
    """A lab's target at rest 4.7 mm (five resolution cells) beyond a wall of 1500 codes,
    5 dB under it: the wall's main lobe and power hide it from the CFAR and the mean
    spectra's test, and "one echo: the target" put every pair on the wall, 4.7 mm off.
    The capture's mean spectra show it (echoes.masked_peaks): the wall is ambiguous."""
    from fmcw_cl.simulator import LAB

    path = tmp_path / "beside.h5"
    lab = LAB if noise is None else replace(LAB, noise_codes=noise, headroom=None)
    simulate_capture(path, static(0.05, 0.1827), 0.05, seed=seed,
                     config=replace(lab, reflectors=((0.178, 1500.0),)))
    track = process(path)
    with Capture(path) as cap:
        assert wrong(track, cap.truth()) == 0
    assert (track.reason == faults.AMBIGUOUS).mean() > 0.9
    assert "another echo at 0.183 m besides the fixed echo at 0.178 m" in track.attrs["target_choice"]


@pytest.mark.parametrize("seed", [1, 2])
def test_a_take_off_through_a_far_stronger_wall_has_no_wrong_pair(tmp_path, seed):
    """The jump's take-off (0.09 -> 0.28 m at up to 7 m/s) through a wall at 0.20 m
    (3000 codes, 12 dB over the target there): one direction's Doppler image beside the
    wall made runs of pairs 110 mm off that every 0.4 ms neighbourhood vouched for (71
    of them), their velocities 4 m/s from their distances' course."""
    from fmcw_cl.simulator import LAB, jump

    path = tmp_path / "through.h5"
    simulate_capture(path, jump(0.3), 0.05, seed=seed, config=replace(LAB, reflectors=((0.20, 3000.0),)),
                     start_s=0.06)
    track = process(path)
    with Capture(path) as cap:
        assert wrong(track, cap.truth()) == 0
    assert track.valid.mean() > 0.05                 # the target at rest beyond the wall


def test_one_fixed_echo_among_many_others_is_not_one_echo(tmp_path):
    """A rail's start (0.06 m, then away) beside a wall at 0.259 m of 1500 codes, speckle,
    noise at full scale: the moving target is neither a fixed echo nor found moving, and
    "one echo: the target" put 621 valid pairs on the wall, 199 mm off. Other echoes fill
    a fifth of the half-sweeps (false alarms: under 1 %): the wall is not the target, and
    a second look beside it, on rows without still echoes, finds the rail (its pairs
    were all `ambiguous` before: "hold other echoes than the fixed echo"), 60 % valid."""
    from fmcw_cl.simulator import LAB, rail

    path = tmp_path / "others.h5"
    simulate_capture(path, rail(0.4), 0.05, seed=7, start_s=0.05,
                     config=replace(LAB, noise_codes=3000.0, headroom=None, reflectors=((0.259, 1500.0),),
                                    speckle_s=3e-3))
    track = process(path)
    with Capture(path) as cap:
        assert wrong(track, cap.truth()) == 0
    assert track.attrs["target_choice"].startswith("the moving echo at 0.0")
    assert "fixed echoes at 0.259 m left out" in track.attrs["target_choice"]
    assert track.valid.mean() >= 0.5


def test_a_take_off_too_weak_to_be_tracked_beside_a_wall_is_seen_by_a_second_look(tmp_path):
    """The jump's take-off beside a wall at 0.277 m of 1500 codes under noise at full
    scale: smeared by its Doppler term, the target is weaker than the wall in its plain
    spectra, the tracker follows the wall, and "one echo: the target" put 931 valid pairs
    on it, up to 193 mm off. Converted beside the wall, the trial stretches show the
    moving echo: the wall is left out and the target tracked."""
    from fmcw_cl.simulator import LAB, jump

    path = tmp_path / "unseen.h5"
    simulate_capture(path, jump(0.3), 0.05, seed=313, start_s=0.06,
                     config=replace(LAB, noise_codes=3000.0, headroom=None, reflectors=((0.277, 1500.0),)))
    track = process(path)
    with Capture(path) as cap:
        assert wrong(track, cap.truth()) == 0
    assert track.attrs["target_moving"] and "fixed echoes at 0.277 m left out" in track.attrs["target_choice"]
    assert track.valid.mean() > 0.2


def test_the_second_look_converts_the_band_on_each_side_of_the_echo():
    from fmcw_cl.second_look import sides

    assert np.allclose(sides(0.30, (0.03, 0.45), 0.468), [(0.03, 0.27), (0.33, 0.45)])
    assert sides(0.05, (0.03, None), 0.468) == [(0.08, None)]                # below: too narrow
    assert sides(0.40, (0.03, None), 0.468) == [(0.03, 0.37)]                # above: starts too far


def test_harmonics_of_a_far_stronger_echo_are_no_objects():

    # 0.201 and 0.299: 2 and 3 x 0.10, 25 and 28 dB under it; 0.43 is none
    d = np.array([0.10, 0.201, 0.299, 0.43])
    level = np.array([40.0, 15.0, 12.0, 1.0])
    assert fixed_echoes.harmonic(d, level, 0.47).tolist() == [False, True, True, False]
    # folded: 3 x 0.20 = 0.60 lies at 0.94 - 0.60 = 0.34
    folded = fixed_echoes.harmonic(np.array([0.20, 0.341]), np.array([30.0, 5.0]), 0.47)
    assert folded.tolist() == [False, True]
    # 8.6 mm from twice a wall's distance, or only 10 dB under it: an object
    assert not fixed_echoes.harmonic(np.array([0.1756, 0.3599]), np.array([20.0, 0.0]), 0.47).any()
    assert not fixed_echoes.harmonic(np.array([0.10, 0.20]), np.array([20.0, 10.0]), 0.47).any()


def test_an_ambiguous_fixed_echo_covers_the_echoes_it_stands_for():
    """Hunt seed 5, capture 10: walls of 3000 codes at 0.1972 and 0.2098 m are one fixed
    echo (nearer than APART_M: the stronger stands), and another echo in most half-sweeps
    makes it ambiguous; the tracker held the weaker wall, 12.6 mm from the one listed.
    The ambiguity covers both walls."""
    from fmcw_cl import echoes, target

    sweeps = np.repeat(np.arange(1000) * 25e-6 + 12.5e-6, 3)      # 50 ms, three echoes each
    rising = np.repeat(np.arange(1000) % 2 == 0, 3)
    d = np.tile([0.0605, 0.1972, 0.2098], 1000)                    # a rail's start, the walls
    d[::3] += 2.0 * sweeps[::3]
    snr = np.tile([15.0, 33.0, 35.7], 1000)
    tracked = np.tile([False, True, False], 1000)                  # the tracker holds the weaker wall
    t_sweep = np.unique(sweeps)
    e = echoes.Echoes(sweeps, d, snr, rising, tracked,
                      echoes.persistent(t_sweep, np.full(t_sweep.size, 30.0), sweeps, d, snr, tracked))
    t = np.arange(500) * 50e-6 + 25e-6
    at = np.full(t.size, 0.1972)
    choice = target.choose("auto", None, t, at, np.zeros(t.size), np.ones(t.size, bool), e, 0.468,
                           (0.03, None))
    assert np.allclose(choice.fixed_m, [0.2098]) and "cannot be told apart" in choice.note
    assert np.isclose(choice.ambiguous_m, 0.1972).any()
    code = target.ambiguous(np.zeros(t.size, np.int8), t, at, np.zeros(t.size), choice)
    assert np.all(code == faults.AMBIGUOUS)


def wall_table(wall_m: float, diffuse_m: list[float], weaker_m: float | None = None):
    """An echo table of 50 ms: a wall the tracker held in every half-sweep (and a weaker
    one), and a moving echo found by its smeared energy alone at `diffuse_m` (one slice
    each)."""
    from fmcw_cl import echoes

    sweeps = np.arange(2000) * 25e-6 + 12.5e-6
    d = np.full(sweeps.size, wall_m)
    snr = np.full(sweeps.size, 26.0)
    rising, tracked = np.arange(sweeps.size) % 2 == 0, np.ones(sweeps.size, bool)
    if weaker_m is not None:
        d = np.c_[d, np.full(d.size, weaker_m)].ravel()
        sweeps, snr = np.repeat(sweeps, 2), np.repeat(snr, 2) - 6
        rising, tracked = np.repeat(rising, 2), np.c_[tracked, ~tracked].ravel()
    p = echoes.persistent(sweeps, snr, sweeps, d, snr, tracked)
    n = len(diffuse_m)
    p = {k: np.r_[v, np.zeros(n, v.dtype)] for k, v in p.items()}
    p["distance_m"][-n:], p["diffuse"][-n:] = diffuse_m, True
    return echoes.Echoes(sweeps, d, snr, rising, tracked, p)


def test_a_wall_that_held_the_first_conversion_is_left_out_of_a_smeared_span():
    """Hunt seeds 1 and 3: a take-off found by its smeared energy alone while the first
    conversion held a wall of 800 codes. Kept in the band, the wall would hold the
    tracker again (every pair on it): the span's longest part beside it is tracked, the
    wall left out, where it lies inside the span and where it lies 20 mm before it; not
    where as many slices of it lie on either side. Where the first conversion followed
    the target (verified pairs in motion), a wall it passes is ambiguous there."""
    from fmcw_cl import target

    t = np.arange(1000) * 50e-6 + 25e-6
    on_wall = lambda m: (t, np.full(t.size, m), np.zeros(t.size), np.ones(t.size, bool))  # noqa: E731
    start = target.choose("auto", None, *on_wall(0.0923), wall_table(0.0923, [0.110, 0.184, 0.217, 0.266]),
                          0.468, (0.03, None))
    assert start.band_m[0] >= 0.0923 + fixed_echoes.GATE_M - 1e-9 and start.ambiguous_m.size == 0, start.note
    through = target.choose("auto", None, *on_wall(0.187), wall_table(0.187, [0.0915, 0.192, 0.225, 0.308]),
                            0.468, (0.03, None))
    assert 0.187 + 0.009 < through.band_m[0] < 0.25 and through.ambiguous_m.size == 0, through.note
    assert "one side" in through.note
    # a span of one slice 15 mm beyond the wall: the band's edge 10 mm from it; one slice
    # on each side: no side is tracked alone
    near = target.choose("auto", None, *on_wall(0.2), wall_table(0.2, [0.2153]), 0.468, (0.03, None))
    assert near.band_m[0] >= 0.2 + fixed_echoes.GATE_M - 1e-9, near.note
    both = target.choose("auto", None, *on_wall(0.2), wall_table(0.2, [0.185, 0.2153]), 0.468, (0.03, None))
    assert both.band_m[0] < 0.185 and np.isclose(both.ambiguous_m, 0.2).any(), both.note
    # walls 17.7 mm apart are one fixed echo, at the stronger; the weaker, inside the span,
    # held the tracker where the band was cut at the stronger (hunt seed 2, 762 pairs wrong)
    table = wall_table(0.0985, [0.0979, 0.182, 0.217, 0.273, 0.276], 0.1162)
    pair = target.choose("auto", None, *on_wall(0.0985), table, 0.468, (0.03, None))
    assert np.allclose(pair.fixed_m, [0.0985]) and pair.band_m[0] > 0.1162 + 0.009, pair.note
    # the first conversion followed the target past the wall: ambiguous where it passes
    d = np.where(t < 0.025, 0.187, 0.095 + 8.0 * (t - 0.025))
    v = np.where(t < 0.025, 0.0, 8.0)
    followed = target.choose("auto", None, t, d, v, np.ones(t.size, bool),
                             wall_table(0.187, [0.0915, 0.192, 0.225, 0.308]), 0.468, (0.03, None))
    assert followed.band_m[0] < 0.1 and np.isclose(followed.ambiguous_m, 0.187).any(), followed.note


def test_a_span_holding_the_targets_own_does_not_cut_its_band():
    """Movers seed 9, capture 37: a hand found by its smeared energy alone (0.043-0.234 m)
    and its slow start as a line of the echo table (0.287-0.304 m), one span
    (moving_echoes.unheld: 0.043-0.304 m). The span the smear alone gives, nested in it,
    is the hand's body seen narrower: it bounds no band, and the hand's band holds its
    start (the band cut at 0.274 m left 18 % of its periods outside, 83 -> 61 %)."""
    from fmcw_cl import target

    t = np.arange(1000) * 50e-6 + 25e-6
    foot = (t, np.full(t.size, 0.07), np.zeros(t.size), np.ones(t.size, bool))
    table = wall_table(0.07, [0.10, 0.15, 0.20, 0.234])
    (lo, hi), = fixed_echoes.moving_spans(*foot, fixed_echoes.smeared(table, (0.03, None)))
    for wide in [(lo, 0.304), (0.08, hi)]:
        choice = target.choose("auto", 0.5 * sum(wide), *foot, table, 0.468, (0.03, None), [wide],
                               moving=True, sides=True)
        assert choice.band_m[1] is None or choice.band_m[1] >= wide[1], (wide, choice.band_m)
    # another mover beyond the span still bounds it
    choice = target.choose("auto", 0.17, *foot, table, 0.468, (0.03, None), [(0.10, 0.234), (0.30, 0.36)],
                           moving=True, sides=True)
    assert 0.234 < choice.band_m[1] < 0.30, choice.band_m


def test_a_target_at_rest_near_twice_a_walls_distance_is_no_harmonic(tmp_path):
    """Speckle, a target at rest at 0.36 m, a wall at 0.176 m about as strong: the target
    lies 8.6 mm from twice the wall's distance. Taken for the wall's harmonic, the wall
    was "one echo: the target" and 538 valid pairs were 184 mm off."""
    from fmcw_cl.simulator import LAB

    path = tmp_path / "twice.h5"
    simulate_capture(path, static(0.05, 0.35986565), 0.05, seed=138,
                     config=replace(LAB, reflectors=((0.17564, 400.0),), speckle_s=3e-3))
    track = process(path)
    scores = scene_of(track, path)
    assert {s["truth"] for s in scores} <= {0, 1}


def with_a_wrong_run(size, d0, noise_m, run, seed, d_run, v_run):
    """A track of `size` pairs 50 us apart at 0.5 m/s from `d0` (m, noise `noise_m` rms)
    whose pairs `run` follow another echo (d_run(t), v_run(t), the same noise), 20
    invalid pairs either side of it: (t, d, v, ok, run)."""
    rng = np.random.default_rng(seed)
    t = np.arange(size) * 50e-6
    v = np.full(t.size, 0.5)
    d = d0 + 0.5 * t + rng.normal(0, noise_m, t.size)
    v[run] = v_run(t[run])
    d[run] = d_run(t[run]) + rng.normal(0, noise_m, run.size)
    ok = np.ones(t.size, bool)
    ok[run[0] - 20:run[0]] = ok[run[-1] + 1:run[-1] + 21] = False
    return t, d, v, ok, run


def test_verification_drops_runs_whose_velocity_is_not_their_motion():
    """A run of 100 pairs (5 ms) on another echo's Doppler image: each 0.4 ms
    neighbourhood agrees within the noise, but the velocities (+2.2 m/s) are not the
    distances' course (-2.2 m/s): over 2 ms they part by 9 mm."""
    from fmcw_cl.stages import verification

    t, d, v, ok, w = with_a_wrong_run(1000, 0.25, 0.2e-3, np.arange(600, 700), 3,
                                      lambda t: 0.2608 - 2.2 * (t - t[0]), lambda t: np.full(t.size, 2.2))
    got, _ = verification.verify(t, d, v, ok)
    assert not got[w].any()
    right = ok.copy()
    right[w] = False
    assert got[right].mean() >= 0.98


def test_verification_drops_isolated_pairs_and_short_wrong_runs():
    from fmcw_cl.stages import verification

    rng = np.random.default_rng(1)
    t = np.arange(600) * 50e-6
    v = 2.0 + 100 * t
    d = 0.1 + 2.0 * t + 50 * t**2 + rng.normal(0, 20e-6, t.size)
    ok = np.ones(t.size, bool)
    ok[100:140] = False
    ok[120] = True                       # alone in a fade: right, but nothing vouches for it
    ok[300:340] = False
    ok[310:316] = True                   # six pairs on another echo, consistent with each other
    d[310:316] += 0.044
    ok[400:540] = False
    ok[470:476] = True                   # six more, over 3 ms from any other pair
    d[470:476] += 0.044
    got, unsupported = verification.verify(t, d, v, ok)
    assert not got[120] and unsupported[120]
    # the pairs within 2 ms disagree with the first six; no anchor within 5 ms predicts the others
    assert not got[310:316].any() and not unsupported[310:316].any()
    assert not got[470:476].any() and unsupported[470:476].all()
    assert got[ok & ~np.isin(np.arange(t.size), [120, *range(310, 316), *range(470, 476)])].all()
    # a short run that continues its anchors' motion across a gap stays
    d[310:316] -= 0.044
    d[470:476] -= 0.044
    ok[310:316] = False
    ok[318:324] = True
    got2, _ = verification.verify(t, d, v, ok)
    assert got2[318:324].all() and got2[470:476].all()


def test_an_integrated_run_stands_alone_only_past_one_integration():
    """A run of 18 self-consistent pairs far from any other stands on its own (over
    ANCHOR_PAIRS) where each pair is one look; where each sums K = 32 half-sweeps of a
    direction, one half-sweep's noise lifts K of them (a noise peak integrated along
    the track): it needs K + 1 pairs, or an anchor that predicts it. A run that long,
    or the short one beside its anchor, stays."""
    from fmcw_cl.stages import verification

    t = np.arange(2000) * 50e-6
    v = np.full(t.size, -1.4)
    d = 0.42 - 1.4 * t
    ok = np.zeros(t.size, bool)
    ok[900:918] = True
    looks = np.full(t.size, 32)
    assert verification.verify(t, d, v, ok)[0][900:918].all()
    got, unsupported = verification.verify(t, d, v, ok, looks=looks)
    assert not got.any() and unsupported[900:918].all()
    ok[918:933] = True                      # 33 pairs: two looks apart
    assert verification.verify(t, d, v, ok, looks=looks)[0][900:933].all()
    ok[:] = False
    ok[300:700] = True                      # an anchor, 1 ms before the short run
    ok[720:738] = True
    got, _ = verification.verify(t, d, v, ok, looks=looks)
    assert got[300:700].all() and got[720:738].all()


def test_verification_drops_runs_whose_distance_leaves_their_velocity(monkeypatch):
    """A rail's start beside a strong wall: a wrong echo held at one distance for 25 ms
    with a velocity of 0.94 m/s. Within 2 ms most pairs agree (0.94 m/s moves the
    prediction by less than the tolerance up to 1.1 ms); over the run it drifts 23 mm."""
    from fmcw_cl.stages import verification

    rng = np.random.default_rng(6)
    t, d, v, ok, w = with_a_wrong_run(1200, 0.06, 50e-6, np.arange(400, 900), 5,
                                      lambda t: np.full(t.size, 0.0786),
                                      lambda t: 0.94 + rng.normal(0, 0.005, t.size))
    right = ok.copy()
    right[w] = False
    got, _ = verification.verify(t, d, v, ok)
    assert not got[w].any() and got[right].mean() >= 0.98
    monkeypatch.setattr(verification, "_drifting", lambda *a: False)
    assert verification.verify(t, d, v, ok)[0][w].mean() > 0.5       # the 2 ms test alone keeps most


def test_verification_drops_a_short_run_that_drifts(monkeypatch):
    """Hunt seed 3, capture 46: the rail's start beside a wall; a wrong echo held at
    0.0797 m with a velocity of 0.90 m/s, which the target passes. The run of 4.95 ms
    where the target meets it, cut from the rest, is right for its first 1.5 ms and then
    stays on the wrong echo while the target moves on by 3.5 mm: shorter than DRIFT_S,
    but its drift is 20 standard errors. A run of 28 pairs that drifts is dropped too.
    Right short runs under noise, their velocity 0.1 m/s off (a sync delay's error), stay."""
    from fmcw_cl.stages import verification

    rng = np.random.default_rng(46)
    t = np.arange(1000) * 50e-6
    meet = np.arange(400, 500)                     # 4.95 ms; the target passes 0.0797 m in its first ms
    tm = t - t[meet[10]]
    true_v = 0.91 + 22.5 * tm
    true_d = 0.0797 + 0.91 * tm + 11.25 * tm**2
    d = true_d + rng.normal(0, 40e-6, t.size)
    v = true_v + rng.normal(0, 0.005, t.size)
    ok = np.ones(t.size, bool)
    ok[380:400] = ok[500:520] = False
    ok[meet[12:17]] = False                        # the handover: a few pairs heard neither
    ghost = meet[17:]
    d[ghost] = 0.0797 + rng.normal(0, 40e-6, ghost.size)
    v[ghost] = 0.90 + rng.normal(0, 0.005, ghost.size)
    assert true_d[ghost[-1]] - 0.0797 > 3e-3
    got, _ = verification.verify(t, d, v, ok)
    assert not got[ghost].any()
    right = ok.copy()
    right[meet] = False
    assert got[right].mean() >= 0.98
    monkeypatch.setattr(verification, "DRIFT_PAIRS", 10**9)
    assert verification.verify(t, d, v, ok)[0][ghost].mean() > 0.5        # runs of DRIFT_S alone keep it

    # a run of 28 pairs (1.35 ms) held 49 mm short of a take-off under noise at full scale
    # (hunt seed 24, capture 50): its distance leaves its velocity at 0.44 m/s
    monkeypatch.undo()
    short = np.arange(28) * 50e-6
    v = 1.57 + rng.normal(0, 0.02, short.size)
    d = 0.2101 + (1.57 + 0.44) * short + rng.normal(0, 40e-6, short.size)
    ok = np.ones(short.size, bool)
    assert verification._drifting(short, d, v, ok) and not ok.any()

    # right runs of 0.85-5 ms, 0.2 mm of noise, velocities 0.1 m/s off: none dropped for a drift
    for seed in range(5):
        rng = np.random.default_rng(seed)
        d = true_d + rng.normal(0, 0.2e-3, t.size)
        v = true_v + 0.1 + rng.normal(0, 0.02, t.size)
        for run in (60, verification.DRIFT_PAIRS, 30):
            ok = np.ones(t.size, bool)
            for gap in range(0, t.size, run + 20):
                ok[gap:gap + 20] = False
            dropped = ok.copy()
            verification._drifting(t, d, v, dropped)
            assert dropped.sum() == ok.sum()


def test_verification_drops_a_run_at_rest_that_the_motion_passes_by(monkeypatch):
    """Hunt seed 9, capture 15: a rail's target at 0.6-0.9 m/s passes 4 mm from a wall
    of 400 codes that no table finds, and the tracker holds the wall for 5 ms at a time:
    runs at rest, self-consistent, between runs in motion that join across them. A
    target that stops where it is and goes on is kept."""
    from fmcw_cl.stages import verification

    rng = np.random.default_rng(15)
    t = np.arange(1000) * 50e-6
    true_d = 0.060 + 0.7 * t
    d = true_d + rng.normal(0, 40e-6, t.size)
    v = 0.7 + rng.normal(0, 0.005, t.size)
    ok = np.ones(t.size, bool)
    wall = np.arange(520, 620)                     # 5 ms on the wall, the target 2-6 mm away
    d[wall] = true_d[520] - 3e-3 + rng.normal(0, 40e-6, wall.size)
    v[wall] = rng.normal(0, 0.005, wall.size)
    ok[500:520] = ok[620:630] = False               # the handovers
    got, _ = verification.verify(t, d, v, ok)
    assert not got[wall].any()
    right = ok.copy()
    right[wall] = False
    assert got[right].mean() >= 0.98
    monkeypatch.setattr(verification, "REST_MPS", 0.0)   # the test off: the wall's runs stand
    assert verification.verify(t, d, v, ok)[0][wall].mean() > 0.9
    monkeypatch.undo()

    # hunt seed 18, capture 8: the run after the wall comes to rest (a landing): its median
    # speed is low, its start moves
    true_v = np.clip(0.7 - 60 * np.maximum(t - 0.0315, 0.0), 0.0, 0.7)
    true_d = 0.060 + np.r_[0.0, np.cumsum(0.5 * (true_v[1:] + true_v[:-1]) * np.diff(t))]
    d = true_d + rng.normal(0, 40e-6, t.size)
    v = true_v + rng.normal(0, 0.005, t.size)
    d[wall] = true_d[520] - 3e-3 + rng.normal(0, 40e-6, wall.size)
    v[wall] = rng.normal(0, 0.005, wall.size)
    assert np.median(np.abs(v[630:])) < verification.REST_MPS
    got, _ = verification.verify(t, d, v, ok)
    assert not got[wall].any() and got[right].mean() >= 0.98

    # three walls passed, a run too short to have ends beside one: each run at rest is
    # judged by the nearest runs on either side whose facing ends move
    t = np.arange(3000) * 50e-6
    true_d = 0.060 + 0.7 * t
    d = true_d + rng.normal(0, 40e-6, t.size)
    v = 0.7 + rng.normal(0, 0.005, t.size)
    ok = np.ones(t.size, bool)
    walls = [np.arange(a, a + n) for a, n in ((400, 60), (1300, 100), (2300, 80))]
    for w in walls:
        d[w] = true_d[w[0]] - 3e-3 + rng.normal(0, 40e-6, w.size)
        v[w] = rng.normal(0, 0.005, w.size)
        ok[w[0] - 20:w[0]] = ok[w[-1] + 1:w[-1] + 11] = False
    ok[1285:1290] = True                                # 5 pairs in the second handover
    got, _ = verification.verify(t, d, v, ok)
    right = ok.copy()
    for w in walls:
        right[w] = False
        assert not got[w].any()
    assert got[right].mean() >= 0.98
    monkeypatch.setattr(verification, "REST_MPS", 0.0)
    got, _ = verification.verify(t, d, v, ok)
    assert all(got[w].mean() > 0.9 for w in walls)

    # a target that stops for 5 ms and goes on (braking and starting at 400 m/s^2) is kept
    true_v = np.clip(np.maximum(0.7 - 400 * (t - 0.023), 400 * (t - 0.030)), 0.0, 0.7)
    true_d = 0.060 + np.r_[0.0, np.cumsum(0.5 * (true_v[1:] + true_v[:-1]) * np.diff(t))]
    d = true_d + rng.normal(0, 40e-6, t.size)
    v = true_v + rng.normal(0, 0.005, t.size)
    ok = np.ones(t.size, bool)
    ok[490:500] = ok[600:610] = False
    assert verification.verify(t, d, v, ok)[0][ok].mean() >= 0.98


@pytest.mark.parametrize("kind, walls, speckle, seed, unlike", [
    # hunt seed 9, capture 0: the take-off's falling half-sweeps on the image of a wall of
    # 1500 codes left out (wall_images), 1.7-0.2 dB under the peaks there: 22 valid pairs
    # 30 mm off
    ("jump_up", ((0.16472688363502214, 150.0), (0.3610136331680715, 1500.0)), 0.0, 926, "image"),
    # hunt seed 9, capture 15: the rail's target passes a wall of 400 codes no table finds
    # (the bridged runs above): 163 valid pairs on the wall, up to 18 mm off
    ("rail", ((0.06577842260695742, 400.0), (0.4086749894340692, 1500.0)), 3e-3, 38, "bridged"),
    # hunt seed 10, capture 51: a wall of 150 codes at 0.309 m found by the mean spectra
    # alone, inside the moving span taken from the take-off's smeared energy, was taken for
    # the target at rest: the CFAR did not see it while the target was away. 374 valid
    # pairs on it, up to 225 mm off (the span, placed without the Doppler shift, now ends
    # short of the wall, and no pair is valid)
    ("jump_up", ((0.3093033884448571, 150.0), (0.2254166657286965, 800.0)), 3e-3, 676, "object"),
    # hunt seed 18, capture 8: a landing passes a wall of 150 codes no table finds; the run
    # after it comes to rest, so its median speed is low and only its end moves: 77 valid
    # pairs on the wall, up to 89 mm off
    ("jump_land", ((0.056812271834929366, 150.0),), 3e-3, 373, "bridged"),
    # hunt seed 20, capture 5, noise at full scale: a landing through a wall of 800 codes
    # that rests 32 mm before it for 18 ms, seen by neither the tables nor the second look:
    # "one echo: the target" put 507 valid pairs on the wall, up to 64 mm off
    ("jump_land", ((0.10362474899129559, 800.0), (0.3309771346340382, 150.0)), 3e-3, 613, "elsewhere"),
    # hunt seed 19, capture 45: a target at rest at 0.327 m between walls at 0.283 m (150
    # codes) and 0.345 m (400, found by no table): the fixed echoes ambiguous, 392 valid
    # pairs on the wall no table found, 18 mm off
    ("static 0.3271024475064748", ((0.2827899003366614, 150.0), (0.3452754789774954, 400.0)), 3e-3, 609,
     "elsewhere"),
    # hunt seed 30, capture 17: a landing at -5 m/s past a wall of 800 codes, found by its
    # smeared energy alone, whose rising centres lie 0.13 m beyond it: placed there, the
    # band left the target out, and 25 pairs at 14 m/s were valid, 371 mm off
    ("jump_land", ((0.13866466780589373, 800.0),), 3e-3, 518, "centres")])
def test_a_lab_capture_beside_walls_has_no_wrong_pair(tmp_path, kind, walls, speckle, seed, unlike):
    """Seven of benchmarks/hunt.py's captures (seeds 9-30) that had wrong valid pairs,
    each mended by one rule; none is wrong, on both processors."""
    from fmcw_cl.backend import make_processor
    from fmcw_cl.simulator import LAB, jump, rail

    path = tmp_path / f"{unlike}.h5"
    traj, start = {"jump_up": (jump(0.3), 0.06), "jump_land": (jump(0.3), 0.18),
                   "rail": (rail(0.4), 0.05)}.get(kind, (None, 0.0))
    if kind.startswith("static"):
        traj = static(0.05, float(kind.split()[1]))
    lab = replace(LAB, reflectors=walls, speckle_s=speckle)
    if seed == 613:                                  # noise at full scale
        lab = replace(lab, noise_codes=3000.0, headroom=None)
    simulate_capture(path, traj, 0.05, seed=seed, config=lab, start_s=start)
    for backend in ("numpy", "opencl"):
        track = process(path, processor=make_processor(backend))
        scene_of(track, path)
        if unlike == "elsewhere":       # the echoes each an object: none on another's distance
            assert len(track.objects) >= 2, backend
        elif unlike == "object":    # the weak wall is named; the take-off beyond it goes unseen
            assert "0.309" in track.attrs["target_choice"], backend
        else:
            assert track.valid.mean() > 0.1, backend


def test_a_target_on_no_object_is_not_taken_for_a_wall(tmp_path):
    """hunt seed 1, capture 59: a landing from 0.168 m to rest at 0.077 m between walls
    of 800 codes at 0.220 and 0.280 m, the lab's SNR. The first conversion's choice
    made both walls ambiguous and left the foot's rest verified; no object holds the
    foot, and the fallback that picks the object the choice told took the one verified
    at the most of the same instants: the wall at 0.280 m was /track, 999 valid pairs
    150-210 mm off the foot. The object must verify the same echo (scene._same_echo):
    none does, so /track is ambiguous, and each wall keeps its own pairs."""
    from fmcw_cl.simulator import LAB, jump

    path = tmp_path / "landing.h5"
    walls = ((0.21978543385283106, 800.0), (0.28028206413563944, 800.0))
    lab = replace(LAB, reflectors=walls, speckle_s=3e-3)
    simulate_capture(path, jump(0.3), 0.05, seed=966, config=lab, start_s=0.18)
    track = process(path)
    with Capture(path) as cap:
        assert wrong(track, cap.truth()) == 0, track.attrs["target_choice"]
    scores = scene_of(track, path)
    assert sum(s["tracked"] > 0.5 for s in scores) >= 2, scores


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
    from fmcw_cl.stages import verification

    rng = np.random.default_rng(0)
    t = np.arange(400) * 50e-6
    v = 3.0 + 200 * t                                        # accelerating
    d = 0.1 + 3.0 * t + 100 * t**2 + rng.normal(0, 30e-6, t.size)
    d[[50, 51, 300]] += 1.7e-3                                # both sweeps on a wrong peak
    ok = verification.continuity(t, d, v, np.ones(t.size, bool))
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


def test_a_wall_left_out_does_not_pass_for_a_chirp_off_its_table(tmp_path):
    """Lab conditions, the take-off behind which a wall (1500 codes) outshines the foot,
    speckle: the tuning check measures the target's peaks in its band, not the wall's
    (once read 1.5x wide, so that every pair was marked uncalibrated)."""
    from fmcw_cl.simulator import LAB, jump

    path = tmp_path / "takeoff_wall.h5"
    cfg = replace(LAB, reflectors=((0.42, 1500.0),), speckle_s=3e-3)
    simulate_capture(path, jump(0.3), 0.05, seed=2, config=cfg, start_s=0.06)
    track = process(path)
    with Capture(path) as cap:
        assert wrong(track, cap.truth()) == 0
    assert track.attrs["invalid_uncalibrated"] == 0 and track.valid.mean() >= 0.5


# each case on the processor it was found on, and the numpy case on OpenCL too (a numpy
# conversion of these 50 ms costs 25-50 s of the suite's time)
@pytest.mark.parametrize("target_m, walls, seed, backend", [
    # a wall seen in 28 half-sweeps, the target in 7, as many as the false alarms; the
    # OpenCL delay 55 samples off split the wall to 0.2325 / 0.2401 m and hid the target
    (0.4276, ((0.2362, 400.0),), 119, "opencl"),
    # the target between two walls: the numpy delay 56 samples off, no echo at a slice's
    # or a block's level, and the capture's mean spectra at 0.428 and 0.442 m
    (0.4160, ((0.4350, 400.0), (0.4037, 150.0)), 382, "numpy"),
    (0.4160, ((0.4350, 400.0), (0.4037, 150.0)), 382, "opencl"),
    # hunt seed 6, capture 52: the target's CFAR echoes outnumber the wall's 16 mm behind
    # it, the mean spectra show both; the OpenCL tracker followed the wall: 261 valid pairs
    # 16 mm off where only the fixed echo's pairs were ambiguous
    (0.37948896749657884, ((0.3957724197220784, 400.0),), 700, "opencl")])
def test_a_weak_target_at_rest_under_noise_at_full_scale_is_never_a_wall(tmp_path, backend, target_m, walls,
                                                                           seed, request):
    """Noise at full scale (3000 codes): the target and the walls are too weak for most
    half-sweeps' CFAR, the other echoes' share is the false alarms', and "one echo: the
    target" put 655 and 389 valid pairs on a wall, 19-192 mm off (benchmarks/hunt.py,
    seeds 2 and 4). The capture's mean spectra tell: another echo, or a wall that is not
    at one distance in both directions; the pairs on either echo are ambiguous."""
    from fmcw_cl.backend import make_processor
    from fmcw_cl.simulator import LAB

    if backend == "numpy" and seed == 382:
        # open (#68): on 2026-12-03's install (numpy 2.4.6, scipy 1.17.1; 2.3.5 and 1.16.3
        # alike) the first conversion still finds the two echoes it cannot tell apart,
        # but the object converted in the band of the one at 0.428 m holds the wall at
        # 0.435 m (430 pairs, right on the wall, read at +0.26 m/s: the delay refined 21
        # samples from the triangle's, +-32) and is /track: a wall taken for a target
        # never detected, the hunt's "off the target". Run, and reported, not hidden.
        request.applymarker(pytest.mark.xfail(reason="#68: a wall taken for a target never detected",
                                              strict=False))

    path = tmp_path / "weak.h5"
    simulate_capture(path, static(0.05, target_m), 0.05, seed=seed,
                     config=replace(LAB, noise_codes=3000.0, headroom=None, reflectors=walls))
    track = process(path, processor=make_processor(backend))
    with Capture(path) as cap:
        assert wrong(track, cap.truth()) == 0
    assert track.attrs["target_choice"] != "one echo: the target"


@pytest.mark.parametrize("wall", [False, True])
def test_a_fixed_echo_the_target_never_leaves_by_a_slice_is_judged_by_half_sweeps(wall):
    """15 ms of a target slowing from 0.268 m onto 0.282 m: its slow end clusters into a
    fixed echo at 0.282 m, and no 10 ms slice's median lies GATE_M from it. Where every
    detection near it is the tracked peak's, it is the target's own rest (no object);
    where a third of the half-sweeps whose tracked peak lies away hold another
    detection there, a wall stands beside the target (an object)."""
    from fmcw_cl import echoes

    sweeps = np.arange(600) * 25e-6 + 12.5e-6
    rising = np.arange(600) % 2 == 0
    v = np.clip(2.6 * (1 - sweeps / 0.012), 0, None)                    # slowing to rest at 12 ms
    d = 0.282 - 0.5 * 2.6 / 0.012 * np.clip(0.012 - sweeps, 0, None) ** 2
    plain = d + np.where(rising, -1, 1) * 0.0091 * v                    # each direction's Doppler image
    snr, tracked = np.full(600, 20.0), np.ones(600, bool)
    if wall:
        sweeps, rising = np.repeat(sweeps, 2), np.repeat(rising, 2)
        plain = np.c_[plain, np.where(np.arange(600) % 3 == 0, 0.2825, np.nan)].ravel()
        snr, tracked = np.repeat(snr, 2), np.c_[tracked, ~tracked].ravel()
        keep = np.isfinite(plain)
        sweeps, rising, plain = sweeps[keep], rising[keep], plain[keep]
        snr, tracked = snr[keep], tracked[keep]
    e = echoes.Echoes(sweeps, plain, snr, rising, tracked, {})
    t = np.arange(300) * 50e-6 + 25e-6
    pair = 0.282 - 0.5 * 2.6 / 0.012 * np.clip(0.012 - t, 0, None) ** 2
    speed = np.gradient(pair, t)
    got = fixed_echoes.are_objects(np.array([0.282]), t, pair, speed, np.ones(300, bool), e)
    assert got.tolist() == [wall]


@pytest.mark.parametrize("wall", [False, True])
def test_a_targets_own_doppler_image_is_not_an_echo_seen_while_it_is_away(wall):
    """A landing turning at 0.072 m at +-0.4 m/s: one direction's tracked plain peak lies
    11 mm beside its pairs, at 0.062 m, in the slice where they lie 11.5 mm from it.
    Those detections are the target's own image: the fixed echo they make is no object
    unless something untracked is seen there too (a wall in half the half-sweeps)."""
    from fmcw_cl import echoes

    sweeps = np.arange(1200) * 25e-6 + 12.5e-6                       # 30 ms
    rising = np.arange(1200) % 2 == 0
    pair_d = np.where(sweeps < 0.01, 0.085, np.where(sweeps < 0.02, 0.071, 0.0735))
    plain = pair_d + np.where(rising, -0.011, 0.011) * (sweeps >= 0.01)
    snr, tracked = np.full(1200, 20.0), np.ones(1200, bool)
    if wall:
        extra = np.flatnonzero(np.arange(1200) % 2 == 1)
        sweeps = np.r_[sweeps, sweeps[extra]]
        rising = np.r_[rising, rising[extra]]
        plain = np.r_[plain, np.full(extra.size, 0.062)]
        snr, tracked = np.r_[snr, snr[extra]], np.r_[tracked, np.zeros(extra.size, bool)]
        order = np.argsort(sweeps, kind="stable")
        sweeps, rising, plain, snr, tracked = (x[order] for x in (sweeps, rising, plain, snr, tracked))
    e = echoes.Echoes(sweeps, plain, snr, rising, tracked, {})
    t = np.arange(600) * 50e-6 + 25e-6
    d = np.where(t < 0.01, 0.085, np.where(t < 0.02, 0.071, 0.0735))
    v = np.where(t < 0.01, 0.0, 0.4)                    # its images: 0.0275 m per m/s, opposite ways
    assert fixed_echoes.are_objects(np.array([0.062]), t, d, v, np.ones(600, bool), e).tolist() == [wall]


@pytest.mark.parametrize("still", [False, True])
def test_pairs_swinging_with_their_velocity_are_one_echo_unless_they_stand_still(still):
    """No echo stays or travels: a foot bouncing +-4 mm at 20 Hz is one echo, its
    tracked plain peaks offset with its velocities (27 mm per m/s, opposite in the two
    directions) and its distances following them. A wall at rest read at a constant
    0.35 m/s (a delay 77 samples off) offsets its peaks as alike, but its distances stand
    still: not that."""
    from fmcw_cl import echoes

    t = np.arange(800) * 50e-6 + 25e-6                                   # 40 ms of pairs
    if still:
        d, v = np.full(t.size, 0.30), np.full(t.size, 0.35)
    else:
        d = 0.074 + 0.004 * np.sin(2 * np.pi * 20 * t)
        v = 0.004 * 2 * np.pi * 20 * np.cos(2 * np.pi * 20 * t)
    sweeps = np.repeat(t, 2) + np.tile([-12.5e-6, 12.5e-6], t.size)
    rising = np.tile([True, False], t.size)
    plain = np.repeat(d, 2) + np.where(rising, -0.027, 0.027) * np.repeat(v, 2)
    e = echoes.Echoes(sweeps, plain, np.full(sweeps.size, 20.0), rising, np.ones(sweeps.size, bool), {})
    assert swing.swinging(e, t, d, v, np.ones(t.size, bool)) is (not still)


def test_a_foot_resting_on_a_panes_front_surface_puts_no_pair_on_the_back(tmp_path):
    """A pane's two surfaces 6 mm apart (0.050 m, 1200 codes; 0.056 m, 800) and a foot
    resting on the front one, jumping: the tables list one fixed echo, the back surface
    is hidden beside it in the mean spectra, and the tracker held it at rest for 7 ms.
    That rest lies inside the span of the target's own pairs, and was taken for its
    swing: "one echo", 338 valid pairs more than 2 mm from the window (the back surface,
    the foot's small bounces). A run of pairs at rest is no swing's image: the hidden
    echo where they rest is another echo, and nothing is valid that cannot be told."""
    from dataclasses import replace

    from fmcw_cl.simulator import jump
    from fmcw_cl.simulator.several import LAB_SCENE

    path = tmp_path / "pane.h5"
    pane = replace(LAB_SCENE, reflectors=((0.05, 1200.0), (0.056, 800.0)))
    simulate_capture(path, jump(0.3, ground_m=0.05), 0.3, seed=1, config=pane)
    track = process(path)
    scene_of(track, path)
    assert "cannot be told apart" in track.attrs["target_choice"]


def test_runs_at_rest_are_found_and_nothing_else():
    """swing.rests: runs of 40 verified pairs under 0.02 m/s, at their median; a
    shorter run, a faster one or one cut by an invalid pair is none."""
    from fmcw_cl import swing

    t = np.arange(300) * 50e-6
    d = np.r_[np.full(100, 0.05), np.linspace(0.05, 0.056, 100), np.full(100, 0.056)]
    v = np.r_[np.zeros(100), np.full(100, 1.2), np.full(100, 0.01)]
    ok = np.ones(300, bool)
    np.testing.assert_allclose(swing.rests(t, d, v, ok), [0.05, 0.056])
    ok[[30, 230]] = False            # each rest cut into runs of 30 and 69: one of 40 each
    np.testing.assert_allclose(swing.rests(t, d, v, ok), [0.05, 0.056])
    ok[:] = True
    ok[20::25] = False               # no run of 40
    assert swing.rests(t, d, v, ok).size == 0


def test_a_peak_at_a_bands_edge_is_no_peak():
    """assemble.at_band_edge: a half-sweep's de-chirped peak within a bin of either edge
    of the band (not the spectrum's end) flags its pair; NaN (no peak) does not. Along
    a course (fmcw_cl.course), each pair's own band's edges in each direction."""
    from types import SimpleNamespace

    from fmcw_cl.assemble import at_band_edge
    from fmcw_cl.course import Course, searched
    from fmcw_cl.stages.spectrum import Search

    def plan_of(search, course=None):
        return SimpleNamespace(model=model, search=search, searched=lambda times: searched(
            search, course, times.rise, times.fall, model.metres_per_bin))

    model = SimpleNamespace(metres_per_bin=0.5e-3, nfft=2048)
    plan = plan_of(Search(130, 212))        # 0.065-0.106 m
    rise = np.array([0.0652, 0.0656, 0.080, 0.1048, 0.1052, np.nan])
    fall = np.array([0.080, 0.080, 0.0651, 0.080, 0.080, 0.080])
    t = np.arange(6) * 50e-6
    flagged = at_band_edge((rise, fall), plan, (t, t + 25e-6))
    assert flagged.tolist() == [True, False, True, False, True, False]
    open_top = plan_of(Search(130, 1024))
    assert not at_band_edge((np.array([0.511]), np.array([0.511])), open_top, (t[:1], t[:1])).any()
    # along a course: the rising band 0.0700-0.0900 m (bins 140-181), the falling one the search's
    course = Course(np.array([0.0, 1.0]), np.array([[0.07, 0.07], [0.0, 0.0]]), np.array([[0.0899, 0.0899],
                                                                                        [1.0, 1.0]]))
    along = plan_of(Search(130, 212), course)
    rise = np.array([0.0702, 0.0706, 0.0898, 0.0893, 0.0652])
    fall = np.full(5, 0.080)
    assert at_band_edge((rise, fall), along, (t[:5], t[:5] + 25e-6)).tolist() == [True, False, True, False,
                                                                                  True]


def test_a_brief_still_part_of_a_moving_track_is_no_body():
    """Movers seed 22, capture 7: where the jump's falling peak and a hand's rising one
    coincide, four sparse pairs read still, 47 mm from either, and cut from the moving
    echo's track they were a fixed object of their own. A still part of a moving track
    with fewer verified pairs than the phases' window (16) is `ambiguous` (scene's
    `_brief_rest`); not one of 16 or more, not a moving part, not a part of a still track,
    and not pairs another check took already."""
    from fmcw_cl import scene
    from fmcw_cl.objects import SceneObject
    from fmcw_cl.track import Track

    n = 2000
    t = 50e-6 * (np.arange(n) + 0.5)

    def _target(d):
        return Track(np.zeros(0), np.zeros(0, bool), np.zeros(0), np.zeros(0), t, d, np.zeros(n), np.zeros(n),
                     np.ones(n, bool), {}, period_s=50e-6)

    whole = _target(0.30 - 1.8 * t)
    whole.velocity_mps[:] = -1.8
    part = _target(np.full(n, 0.245))
    part.valid[:] = False
    part.valid[[1000, 1006, 1008, 1015]] = True
    none = np.zeros(n, bool)
    assert scene._brief_rest(SceneObject(3, False, part, "", whole), none).sum() == 4
    assert scene._brief_rest(SceneObject(3, False, part, "", whole), part.valid).sum() == 0
    assert scene._brief_rest(SceneObject(3, True, part, "", whole), none).sum() == 0
    assert scene._brief_rest(SceneObject(3, False, part, "", None), none).sum() == 0
    assert scene._brief_rest(SceneObject(3, False, part, "", _target(np.full(n, 0.245))), none).sum() == 0
    part.valid[1000:1016] = True
    assert scene._brief_rest(SceneObject(3, False, part, "", whole), none).sum() == 0
