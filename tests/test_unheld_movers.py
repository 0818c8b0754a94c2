"""A mover that shares a candidate's band but that no tracker held
(fmcw_cl.unheld_movers): the velocity bank's bodies make it an object of its own."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from conftest import shifted_jump, two_movers

from fmcw_cl import unheld_movers
from fmcw_cl.evaluate import best_held
from fmcw_cl.objects import SceneObject
from fmcw_cl.simulator.scene import glide, jump
from fmcw_cl.stages import faults
from fmcw_cl.track import read_track


def test_a_bare_object_holds_no_pair(jump_track):
    track = read_track(jump_track)
    bare = unheld_movers.bare(track)
    assert track.valid.any() and not bare.valid.any()
    assert np.all(np.isnan(bare.distance_m)) and np.all(np.isnan(bare.velocity_mps))
    assert np.all(bare.reason == faults.NO_ECHO)
    assert bare.attrs["invalid_no_echo"] == bare.pairs
    assert track.valid.any() and np.isfinite(track.distance_m[track.valid]).all()    # left as it was


def test_a_bare_object_that_took_a_held_movers_echo_is_dropped(jump_track):
    """Converted along its course, a bare object whose pairs lie within 10 mm of another
    object's is that object's twin, and one that gained no pair is none: dropped, the
    others kept as they are; 20 mm off, it stays."""
    track = read_track(jump_track)
    other = SceneObject(0, True, track, "the jump")
    twin = SceneObject(0, True, replace(track, attrs=dict(track.attrs)), "a mover no tracker held")
    assert unheld_movers.without_twin([other, twin]) == [other]
    empty = SceneObject(0, True, unheld_movers.bare(track), "a mover no tracker held")
    assert unheld_movers.without_twin([other, empty]) == [other]
    apart = replace(track, attrs=dict(track.attrs), distance_m=track.distance_m + 0.02)
    scene = [other, SceneObject(0, True, apart, "a mover no tracker held")]
    assert unheld_movers.without_twin(scene) == scene


def test_a_body_told_apart_by_its_motion_is_clear_of_a_track(jump_track):
    """A velocity bank's body within objects.GATE_M (10 mm) of a held track's verified
    pairs lies on it, unless its velocities are given and the two are told apart as two
    movers are (crossings.movers_apart: a hand at 1-1.5 m/s across a foot, more than 5
    mm apart and so are their peaks in both directions); not where one direction's
    peaks meet, nor within 5 mm. So too for a candidate no tracker held (along._untracked)."""
    from fmcw_cl import along, course_bodies

    track = read_track(jump_track)
    ok = np.flatnonzero(track.valid)[:400]
    t, d, v = track.time_s[ok], track.distance_m[ok], track.velocity_mps[ok]
    k = (-0.029, 0.029)
    assert course_bodies.clear(t, d + 0.02, [track])
    assert not course_bodies.clear(t, d + 0.007, [track])
    assert course_bodies.clear(t, d + 0.007, [track], v + 1.5, k)
    assert not course_bodies.clear(t, d + 0.007, [track], v + 0.007 / 0.029, k)    # rising peaks meet
    assert not course_bodies.clear(t, d + 0.003, [track], v + 1.5, k)
    # ... and so a candidate no tracker held takes it for its course (along._untracked)
    body = (t, d + 0.007, v + 1.5)
    assert along._untracked([body], [track], (0.03, None)) is None
    course = along._untracked([body], [track], (0.03, None), k)
    assert course is not None and np.array_equal(np.unique(course[1]), np.unique(body[1]))


@pytest.mark.long
@pytest.mark.parametrize("hand, db, seed, start, span, held", [
    ((0.3912946541500179, 0.03079453646711917, 0.0929636424675265, 0.4423116408428659), -3.3, 630,
     0.20878124721276184, 0.16926850140933736, 0.3),
    ((0.04729550206929087, 0.3310377115877617, 0.2090456251110855, 0.3826703838188366), 5.0, 131,
     0.23237886607588146, 0.07353313207044986, 0.6),
    ((0.04819524271923787, 0.304085469873333, 0.17130089747496066, 0.4267919828842448), -5.761990254360757,
     198, 0.18615715086914136, 0.0890866624758966, 0.05)])
def test_a_hand_the_jumps_tracker_never_held_is_an_object(tmp_path, hand, db, seed, start, span, held):
    """The jump and a hand glided through its path at 1.5-3 m/s in one moving span, lab
    SNR (movers.py seed 1, capture 17, the hand 3.3 dB weaker coming down; seed 6,
    capture 22, 5.0 dB stronger going up from beside the foot at rest): one candidate,
    its tracker on the foot throughout, and the hand in none of the objects' periods.
    The velocity bank saw the hand: an object of its own, converted along its bodies'
    course (41 % and 75 % of its periods), the foot's pairs where the hand passes within
    10 mm now `ambiguous` (97 -> 90 %, 96 -> 89 %); no pair off its own object
    (`two_movers` asserts it). Seed 1, capture 22: the hand 5.8 dB weaker going up at
    0.8-1.4 m/s across the foot come to rest, half its body within 10 mm of it but told
    apart by its motion (course_bodies.clear): 0 -> 9 %."""
    amplitude = 500.0 * 10 ** (db / 20)
    track, scores = two_movers(tmp_path / "jump_hand.h5", jump(0.7), glide(0.7, *hand), amplitude, True, seed,
                               start, span)
    best = best_held(scores, 2)
    assert best[0] >= 0.85 and best[1] >= held, best
    assert any("no tracker held" in o.note for o in track.objects)


@pytest.mark.long
def test_a_weak_glide_whose_few_pairs_are_a_fixed_part_is_an_object(tmp_path):
    """Two glides one way at a lab's SNR (movers.py seed 2, capture 33): the other, 5.9
    dB weaker, rests at 0.083 m until the target has passed it, then glides after it at
    up to 1.4 m/s. One candidate; its tracker held the weaker glide for 2 ms (40 pairs,
    a fixed part: too short to move). The velocity bank's body of the glide goes on as
    that part, but a fixed part is converted along no course: the body is an object of
    its own (1 -> 22 % of the glide's periods), no pair off its own object."""
    target = glide(0.7, 0.06426805035336254, 0.2864645441449119, 0.0775095587342738, 0.4775095587342738)
    other = glide(0.7, 0.08258346981345052, 0.37919452866132275, 0.14828275983005668, 0.5482827598300567)
    track, scores = two_movers(tmp_path / "glides.h5", target, other, 254.4762553761667, True, 106,
                               0.10386334032799983, 0.23401722063618646)
    best = best_held(scores, 2)
    assert best[0] >= 0.9 and best[1] >= 0.15, best
    assert any("no tracker held" in o.note for o in track.objects)


def test_a_slow_body_of_the_echo_table_is_a_mover_no_tracker_held(tmp_path):
    """A glide (the target) leaving a sway 5.4 dB weaker, lab SNR (movers.py seed 1,
    capture 19): the sway at 0.1-0.5 m/s, 35-39 mm beyond the glide for 60 ms, is too
    slow to smear its plain peak, so the velocity bank has no body of it, and the glide's
    span holds its range: one candidate, whose tracker never held it. The echo table's
    body of it, travelling 15 mm, is an unheld mover's (unheld_movers.bodies_of); along
    its course its verified pairs join it one by one (along._run_pairs; 1 in 3 of them
    `unstable`): the sway in 7 -> 52 % of its periods, the glide as before, no pair off
    its own object."""
    from fmcw_cl.simulator.scene import sway

    target = glide(0.7, 0.09760146343630924, 0.36080475427831826, 0.03600071875481442, 0.26626863179132304)
    other = sway(0.7, 0.15576168258780607, 0.019339683967690424, 4.373446977173887, 3.584963098651965)
    track, scores = two_movers(tmp_path / "glide_sway.h5", target, other, 267.03138773007197, True, 611,
                               0.027111506469481364, 0.11907825352378819)
    best = best_held(scores, 2)
    assert best[0] >= 0.85 and best[1] >= 0.45, best


@pytest.mark.long
def test_a_landing_no_tracker_held_beside_several_candidates_is_an_object(tmp_path):
    """Two jumps 34 ms apart, the second leg 5.1 dB stronger, lab SNR (movers.py seed 3,
    capture 10): the first foot at rest bouncing by +-0.4 m/s, the second landing at
    up to 5 m/s from 0.21 m onto the same ground. Two candidates (the moving echo
    0.055-0.188 m and the fixed echo at 0.070 m, its rest); the moving one's tracker
    held the bouncing foot throughout, and the landing, which the velocity bank saw
    whole, was in no object's periods: an unheld mover is sought beside several
    candidates as beside one (1 -> 34 % of the landing leg's periods), no pair off its
    own object."""
    track, scores = two_movers(tmp_path / "legs.h5", jump(0.7), shifted_jump(-0.03436138147507793),
                               500.0 * 10 ** (5.057129544405381 / 20), True, 731, 0.2051311997109243,
                               0.07332302718785345)
    best = best_held(scores, 2)
    assert best[0] >= 0.5 and best[1] >= 0.25, best
    assert any("no tracker held" in o.note for o in track.objects)


def test_a_fixed_echos_peak_paired_with_a_movers_is_no_body():
    """The velocity bank pairs each rising echo with each falling one: a hand's rising
    peak with a foot's at rest (0.070 m) solves to a body half way between, moving as
    its distance does (movers.py seed 3, capture 12). Its falling peak (R + k_f v) stays
    at the foot's: no body (unheld_movers._image); the hand itself, the body with the
    fixed echo elsewhere or none, are bodies."""
    k = (-0.0287, 0.0287)
    t = np.arange(0.0, 0.014, 2.5e-4)
    v = -1.3 + 20.0 * t                                   # the hand, slowing
    r = 0.0883 - 1.3 * t + 10.0 * t * t
    rise, fall = r + k[0] * v, np.full(t.size, 0.070)     # its rising peak, the foot's falling one
    ghost = (t, (k[1] * rise - k[0] * fall) / (k[1] - k[0]), (fall - rise) / (k[1] - k[0]))
    hand = (t, r, v)
    assert np.ptp(ghost[1]) > 0.01 and np.all(ghost[2] < -0.5)          # it travels, fast
    assert unheld_movers._image(ghost[1], ghost[2], np.array([0.0695]), k)
    assert not unheld_movers._image(hand[1], hand[2], np.array([0.0695]), k)
    assert not unheld_movers._image(ghost[1], ghost[2], np.array([0.080]), k)
    assert not unheld_movers._image(ghost[1], ghost[2], (), k)
    kept = unheld_movers.bodies_of([ghost, hand], [], [], np.array([0.0695, 0.3]), k)
    assert len(kept) == 1 and kept[0] is hand


@pytest.mark.long
def test_an_unheld_movers_course_goes_on_across_its_bodys_fade(tmp_path):
    """The jump at rest and a hand 2.5 dB weaker glided up from 0.031 m past it at up to
    2.3 m/s, lab SNR (movers.py seed 2, capture 12): the velocity bank's body of the
    hand ends at 0.069 s, 0.108 m; then no pick for 18 ms, then three in 3 ms on its
    motion, too few for a body. They carry its course on (fast_echoes.carried): 37 -> 51
    % of the hand's periods, the foot as before, no pair off its own object."""
    hand = glide(0.7, 0.03131963076169191, 0.40592311834112405, 0.1784097577396993, 0.48323554949090813)
    amplitude = 500.0 * 10 ** (-2.5286649105369694 / 20)
    _, scores = two_movers(tmp_path / "hand.h5", jump(0.7), hand, amplitude, True, 605, 0.21293079794739125,
                           0.09814874384475501)
    best = best_held(scores, 2)
    assert best[0] >= 0.85 and best[1] >= 0.45, best


def test_the_echo_tables_bodies_that_travel_and_lie_on_no_harmonic_may_be_movers(jump_track):
    """unheld_movers.bodies_of: the velocity bank's bodies, and the echo table's that
    travel SLOW_TRAVEL_M (10 mm) or more, not those that stay (a fixed echo's) nor those
    on twice or three times a held track's distance (its harmonics)."""
    held = read_track(jump_track)
    t = np.linspace(0.01, 0.05, 161)
    d_held = np.interp(t, held.time_s[held.valid], held.distance_m[held.valid])
    fast = [(t, 0.30 - 2.0 * (t - 0.01), np.full(t.size, -2.0))]
    slow = (t, 0.32 + 0.3 * (t - 0.01), np.full(t.size, 0.3))              # 12 mm in 40 ms
    still = (t, np.full(t.size, 0.25), np.zeros(t.size))
    harmonic = (t, 2 * d_held + 0.3 * (t - 0.01), np.full(t.size, 0.3))
    got = unheld_movers.bodies_of(fast, [slow, still, harmonic], [held])
    assert [b[1][0] for b in got] == [fast[0][1][0], slow[1][0]]
