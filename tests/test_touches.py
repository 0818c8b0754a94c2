"""Where another mover's path touches a tracked mover's (fmcw_cl.touches): the tracker
may have passed from one body to the other there, so no part that starts or ends at a
touch is joined across it; and a body of the echo tables that went on from one mover
to the other is a piece of each."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import shifted_jump, two_movers

from fmcw_cl import identities, touches
from fmcw_cl.evaluate import best_held
from fmcw_cl.objects import SceneObject
from fmcw_cl.simulator.scene import jump
from fmcw_cl.stages import faults
from fmcw_cl.track import Track

PERIOD = 50e-6
T = PERIOD * (np.arange(2400) + 0.5)        # 0.12 s


def _track(d, v, valid) -> Track:
    n = d.size
    reason = np.where(valid, faults.OK, faults.NO_ECHO).astype(np.uint8)
    return Track(np.zeros(0), np.zeros(0, bool), np.zeros(0), np.zeros(0), T, np.where(valid, d, np.nan),
                 np.where(valid, v, np.nan), np.zeros(n), valid, {}, reason=reason, period_s=PERIOD)


def _legs():
    """Two legs by their plateaus (movers.py seed 33, capture 35): one at rest at 0.282 m
    until 64 ms, then setting off at 40 m/s^2 (+0.6 m/s 15 ms on); the other arriving at
    +1.6 m/s, braking at 40 m/s^2 to rest at 0.282 m at 40 ms... 64 ms; at 64 ms both at
    0.282 m within 0.2 mm, at velocities alike. Distances, velocities at T."""
    u = np.maximum(T - 0.064, 0.0)
    first = 0.282 + 20.0 * u ** 2, 40.0 * u
    w = np.maximum(0.064 - T, 0.0)
    second = 0.282 - 20.0 * w ** 2, 40.0 * w
    return first, second


def _path(d, v, lo: float, hi: float, step: float = 2.5e-4):
    grid = np.arange(lo, hi, step)
    return grid, np.interp(grid, T, d), np.interp(grid, T, v)


def test_a_path_that_parts_from_a_tracks_first_pairs_touches_its_start():
    """The tracker on the first leg at rest until 60 ms (part A), then, after 8 ms
    unverified as the two made one echo, on the second at rest (part C); the echo
    table's body of the second leg's arrival, then of the first leg's set-off. At C's
    first pairs it lies within 2 mm at a velocity alike and parts from C beyond 5 mm
    within 20 ms, both one body's motion: C's start is touched; at A's last pairs it
    came from beyond 5 mm: A's end is touched. Not by a path that lies on the track
    (its own body), stays 10 mm off, passes at a velocity 2 m/s apart, comes 50 %
    faster than its distances do, or does not move (a fixed echo's line: not one of
    `Touched`'s paths)."""
    (d1, v1), (d2, v2) = _legs()
    at = T < 0.064
    path = _path(np.where(at, d2, d1), np.where(at, v2, v1), 0.02, 0.11)
    a, c = _track(d1, v1, T < 0.06), _track(d2, v2, T >= 0.068)
    assert touches.ends(c, [path]) == (True, False)
    assert touches.ends(a, [path]) == (False, True)
    for other in (_path(d2, v2, 0.07, 0.11), _path(d2 + 0.01, v2, 0.02, 0.11),
                  _path(np.where(at, d2, d1), np.where(at, v2, v1) + 2.0, 0.02, 0.11)):
        assert touches.ends(c, [other]) == (False, False)
    # a body of the echo tables whose distances do not follow its velocities (a blend
    # sliding from one echo onto the other): 3 mm for 4.5 mm
    slid = _path(np.where(at, d2, d1), np.where(at, 1.5 * v2, v1), 0.02, 0.11)
    assert touches.ends(a, [slid]) == (False, False)
    still = _path(np.full(T.size, 0.282), np.zeros(T.size), 0.02, 0.11)
    assert not touches.moves(still) and touches.Touched([still])(c) == (False, False)
    assert touches.Touched([still, path])(c) == (True, False)


def test_parts_either_side_of_a_touch_are_not_joined_again():
    """identities.rejoined: the two legs' parts above, seen again across 8 ms at rest
    (one body's motion could join them), are one object without the path; with it,
    two, each one leg's."""
    (d1, v1), (d2, v2) = _legs()
    at = T < 0.064
    path = _path(np.where(at, d2, d1), np.where(at, v2, v1), 0.02, 0.11)
    parts = [SceneObject(0, True, _track(d1, v1, T < 0.06), "A"),
             SceneObject(0, True, _track(d2, v2, T >= 0.068), "C")]
    assert len(identities.rejoined(parts, True)) == 1
    apart = identities.rejoined(parts, True, touched=touches.Touched([path]))
    assert [o.note for o in apart] == ["A", "C"]


def test_a_body_that_went_on_from_one_mover_to_the_other_is_a_piece_of_each():
    """The bank's body of the second leg's arrival and the first leg's set-off, beside
    the verified pairs of the first leg at rest (a fixed part) until the touch: cut
    within the touch into one piece per leg; not cut where it crosses an object from
    one side to the other at 0.9 m/s (it keeps its own echo), beside the first leg's
    pairs alone that it lies on (the same echo), nor beside a path that never comes
    near."""
    (d1, v1), (d2, v2) = _legs()
    at = T < 0.064
    body = _path(np.where(at, d2, d1), np.where(at, v2, v1), 0.02, 0.11)
    rest = T[at & (T > 0.03)]
    first = rest, np.full(rest.size, 0.282), np.zeros(rest.size)
    got = touches.pieces(body, [first])
    near = rest[np.abs(np.interp(rest, T, d2) - 0.282) <= 2e-3]          # the touching times
    assert len(got) == 2 and near[0] <= got[0][0][-1] < got[1][0][0] <= near[-1] + 2.5e-4
    for (g, d, _), truth in zip(got, (d2, d1), strict=True):
        assert np.max(np.abs(d - np.interp(g, T, truth))) < 1e-3 or g.size < 8
    # a body crossing the first leg at rest at 0.9 m/s, apart on either side: no cut
    across = np.arange(0.03, 0.1, 2.5e-4)
    across = across, 0.282 + 0.9 * (across - 0.064), np.full(across.size, 0.9)
    still = T[(T > 0.02) & (T < 0.11)]
    assert len(touches.pieces(across, [(still, np.full(still.size, 0.282), np.zeros(still.size))])) == 1
    on = _path(d1, v1, 0.064, 0.11)
    assert len(touches.pieces(on, [_path(d1, v1, 0.07, 0.1)])) == 1
    assert len(touches.pieces(body, [_path(d1 + 0.02, v1, 0.02, 0.11)])) == 1


@pytest.mark.long
@pytest.mark.parametrize("off, db, seed, start, span, held", [
    (-0.02345415962467607, -5.834791960081212, 564, 0.0830433338279471, 0.28023639390490457, 0.65),
    (-0.013621996193602683, -3.829564768614228, 321, 0.05355259133827035, 0.23677084212551475, 0.5)])
def test_two_legs_that_touch_near_their_apexes_keep_their_own_pairs(tmp_path, off, db, seed, start, span,
                                                                     held):
    """Two jumps 23 and 14 ms apart, the second leg 5.8 and 3.8 dB weaker, lab SNR
    (movers.py seed 32, capture 20; seed 33, capture 35): one candidate, its tracker
    passing between the legs. Seed 33: the first leg at rest on its plateau, the other
    arriving beside it as it set off again; the tracker stepped onto their one peak and
    held the second at rest, its parts either side were joined as one body seen again,
    and the velocity bank's body went on from the arrival onto the set-off, carrying
    the later part's course back onto the other leg (1147 valid pairs of one leg on the
    other's objects): no join across the touch, the bank's body a piece either side.
    Seed 32: a leg's descent, its part before the apex another object, had its course
    carried back across the gap onto the other leg's take-off (644): not where another
    object goes on as its end. No pair off its own object (`two_movers` asserts it);
    the target leg's best object 77 and 61 % of its periods."""
    _, scores = two_movers(tmp_path / "legs.h5", jump(0.7), shifted_jump(off), 500.0 * 10 ** (db / 20), True,
                           seed, start, span)
    assert best_held(scores, 2)[0] >= held
