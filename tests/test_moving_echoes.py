"""Moving echoes that no tracker held, found as lines of the echo table
(fmcw_cl.moving_echoes): a glide's two directions' Doppler-shifted detections agree as
one echo; noise, one direction alone, the target's own peak and its harmonic do not."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from fmcw_cl import fixed_echoes, moving_echoes
from fmcw_cl.echoes import Echoes
from fmcw_cl.stages.verification import ACCEL_MAX
from fmcw_cl.track import Track

PERIOD = 50e-6
N = 2000                       # 100 ms
T = PERIOD * (np.arange(N) + 0.5)
K = 0.029                      # the Doppler model's k (s): -K rising, +K falling


def _table(rng, lines: list[tuple[np.ndarray, float | np.ndarray, bool]], share: float = 0.3,
           noise: int = 200) -> Echoes:
    """An echo table of `lines` ((distance, velocity per period m, m/s; tracked)), each
    heard in `share` of its half-sweeps (10 um of noise), plus `noise` detections
    anywhere in 0.03-0.45 m."""
    t, d, rising, tracked = [], [], [], []
    for dist, v, held in lines:
        for way, k in ((True, -K), (False, K)):
            seen = (rng.random(N) < share) & np.isfinite(dist)
            at = T[seen] + (-0.25 if way else 0.25) * PERIOD
            t.append(at)
            d.append(dist[seen] + k * np.broadcast_to(v, N)[seen] + 1e-5 * rng.standard_normal(seen.sum()))
            rising.append(np.full(seen.sum(), way))
            tracked.append(np.full(seen.sum(), held))
    way = rng.random(noise) < 0.5
    t.append(np.round(rng.uniform(0, N, noise)) * PERIOD + PERIOD / 2 + np.where(way, -0.25, 0.25) * PERIOD)
    d.append(rng.uniform(0.03, 0.45, noise))
    rising.append(way)
    tracked.append(np.zeros(noise, bool))
    t, d, rising, tracked = map(np.concatenate, (t, d, rising, tracked))
    order = np.argsort(t, kind="stable")
    return Echoes(t[order], d[order], np.full(t.size, 15.0), rising[order], tracked[order],
                  _smear(np.zeros(0), np.zeros(0)))


def _target(dist: np.ndarray) -> Track:
    """A track whose verified pairs lie at `dist` (m)."""
    ok = np.ones(N, bool)
    return Track(np.zeros(0), np.zeros(0, bool), np.zeros(0), np.zeros(0), T, dist, np.zeros(N), np.zeros(N),
                 ok, {}, period_s=PERIOD)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_glide_no_tracker_held_is_a_moving_echo(seed):
    """A glide from 0.35 m at -0.6 m/s speeding up at 8 m/s^2 (heard in 30 % of its
    half-sweeps, each direction's detections 35-81 mm apart by their Doppler terms; each
    line's slope off its velocity by k a, 0.23 m/s) beside a sway the tracker held and
    200 noise detections: lines a direction that hold 90 % of its detections
    (a fade of 2 ms or more parts them), and one moving echo whose span is the glide's
    own (within 1 mm), not its Doppler-shifted peaks'."""
    rng = np.random.default_rng(seed)
    glide = 0.35 - 0.6 * T - 4.0 * T ** 2
    sway = 0.25 + 0.02 * np.sin(2 * np.pi * 4 * T)
    e = _table(rng, [(glide, -0.6 - 8.0 * T, False), (sway, 0.0, True)])
    for way in (True, False):
        free = np.flatnonzero(~e.tracked & (e.rising == way))
        got = moving_echoes.lines(e.time_s[free], e.distance_m[free])
        assert 1 <= len(got) <= 3 and sum(x.size for x in got) >= 0.9 * 0.3 * N
    spans = moving_echoes.unheld(e, -K, K, _target(sway), (0.03, None), [])
    assert len(spans) == 1
    lo, hi = spans[0]
    assert abs(lo - np.percentile(glide, 1)) < 1e-3 and abs(hi - np.percentile(glide, 99)) < 1e-3


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_noise_one_direction_the_target_and_its_harmonic_are_no_moving_echo(seed):
    """No span from: noise alone (2000 detections); a table of the tracked peaks alone
    (a static target's: no detection free); a glide heard in one direction only;
    the tracked target's own peak split beside it (its untracked detections 0.5 mm
    off); its second harmonic; a glide whose span centres inside a known one; a glide
    where the tracker held no verified pair (the target's own echo, lost, may be it),
    or where it held another body after the glide (a rail's end, movers.py seed 9,
    capture 26, cut its band and lost 85 -> 44 %)."""
    rng = np.random.default_rng(seed)
    target = 0.15 - 0.8 * T
    assert moving_echoes.unheld(_table(rng, [], noise=2000), -K, K, _target(target), (0.03, None), []) == []
    held = _table(rng, [(target, -0.8, True)], noise=0)        # every detection the target's: none free
    assert moving_echoes.unheld(held, -K, K, _target(target), (0.03, None), []) == []
    glide = 0.35 - 1.2 * T
    e = _table(rng, [(glide, -1.2, False)])
    on = np.abs(e.distance_m - glide[np.minimum((e.time_s / PERIOD).astype(int), N - 1)]) <= 0.05
    one = ~e.rising | ~on
    lone = Echoes(e.time_s[one], e.distance_m[one], e.snr_db[one], e.rising[one], e.tracked[one],
                  e.persistent)
    assert moving_echoes.unheld(lone, -K, K, _target(target), (0.03, None), []) == []
    for beside in (target + 5e-4, 2 * target):
        e = _table(rng, [(beside, -0.8 * (beside[1] - beside[0]) / (target[1] - target[0]), False)])
        assert moving_echoes.unheld(e, -K, K, _target(target), (0.03, None), []) == []
    e = _table(rng, [(glide, -1.2, False)])
    assert moving_echoes.unheld(e, -K, K, _target(target), (0.03, None), [(0.2, 0.4)]) == []
    assert len(moving_echoes.unheld(e, -K, K, _target(target), (0.03, None), [])) == 1
    lost = _target(target)                     # verified for its first 10 ms only: the glide may be it
    lost.valid[200:] = False
    assert moving_echoes.unheld(e, -K, K, lost, (0.03, None), []) == []
    # the tracker on the glide for 30 ms, then on another body 0.2 m away: the glide's
    # line after is the body of that first run, seen again
    swapped = _target(np.where(np.arange(N) < 600, glide, 0.12 + 0.1 * T))
    swapped.velocity_mps[:] = np.where(np.arange(N) < 600, -1.2, 0.1)
    swapped.valid[600:610] = False                       # the swap unverified
    late = _table(rng, [(np.where(np.arange(N) < 800, np.nan, glide), -1.2, False)])
    assert moving_echoes.unheld(late, -K, K, swapped, (0.03, None), []) == []


def _smear(t: np.ndarray, d: np.ndarray) -> dict:
    """An echo table's persistent echoes: diffuse slices at `t` (s) and `d` (m)."""
    n = t.size
    return {"time_s": t, "distance_m": d, "snr_db": np.full(n, 10.0), "share": np.full(n, 0.3),
            "relative_db": np.full(n, -5.0), "diffuse": np.ones(n, bool)}


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_slow_start_before_a_smeared_span_is_that_spans_body(seed):
    """Movers seed 9, capture 37: a hand known by its smeared energy alone (slices from
    75 ms on) while the tracker held a foot at rest, whose slow start (0.32 m, -0.3 m/s,
    speeding up at 20 m/s^2) leaves lines until 45 ms. The line's echo, 9.5 mm from the
    first slice where its velocity carries it, is the smeared span's body: one span
    from the smear's nearest to the start's farthest (found apart, it cut the hand's
    band: 83 -> 58 %). A smear of a body elsewhere, or none, leaves the line its own."""
    rng = np.random.default_rng(seed)
    hand = 0.32 - 0.3 * T - 10.0 * T ** 2
    e = _table(rng, [(np.where(T < 0.045, hand, np.nan), -0.3 - 20.0 * T, False)])
    foot = _target(np.full(N, 0.07))
    ts = np.arange(0.075, 0.1, 0.01)
    on = np.interp(ts, T, hand)
    known = fixed_echoes.moving_spans(foot.time_s, foot.distance_m, foot.velocity_mps, foot.valid, on)
    smeared = replace(e, persistent=_smear(ts, on))
    found = moving_echoes.unheld(smeared, -K, K, foot, (0.03, None), known)
    assert len(found) == 1 and found[0][0] == known[0][0], (found, known)
    assert abs(found[0][1] - np.percentile(hand[T < 0.045], 99)) < 1e-3
    assert moving_echoes.joined(known, found) == found
    alone = moving_echoes.unheld(replace(e, persistent=_smear(ts[:0], on[:0])), -K, K, foot, (0.03, None), [])
    assert len(alone) == 1 and abs(alone[0][0] - np.percentile(hand[T < 0.045], 1)) < 1e-3
    away = 0.10 - 0.5 * (ts - 0.05)                           # another body's smear, 0.10 -> 0.077 m
    far = fixed_echoes.moving_spans(foot.time_s, foot.distance_m, foot.velocity_mps, foot.valid, away)
    got = moving_echoes.unheld(replace(e, persistent=_smear(ts, away)), -K, K, foot, (0.03, None), far)
    assert got == alone and moving_echoes.joined(far, got) == sorted(far + alone)
    # a span found apart that holds a known one keeps it (neither end is the known one's)
    assert moving_echoes.joined([(0.11, 0.13)], [(0.10, 0.40)]) == [(0.10, 0.40), (0.11, 0.13)]


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_slow_end_after_a_smeared_span_is_that_spans_body(seed):
    """The other way in time: a body leaving at 1.5 m/s, known by its smeared energy
    (slices at 5-25 ms), slowing to 0.5 m/s as lines from 55 ms on: the line comes from
    the last slice at its start's velocity (found apart on e6b4966), one span."""
    rng = np.random.default_rng(seed)
    body = 0.12 + 1.5 * T - 5.0 * T ** 2
    e = _table(rng, [(np.where(T >= 0.055, body, np.nan), 1.5 - 10.0 * T, False)])
    foot = _target(np.full(N, 0.05))            # its harmonics clear of the line
    ts = np.arange(0.005, 0.03, 0.01)
    on = np.interp(ts, T, body)
    known = fixed_echoes.moving_spans(foot.time_s, foot.distance_m, foot.velocity_mps, foot.valid, on)
    found = moving_echoes.unheld(replace(e, persistent=_smear(ts, on)), -K, K, foot, (0.03, None), known)
    assert len(found) == 1 and found[0][0] == known[0][0], (found, known)
    assert abs(found[0][1] - np.percentile(body[T >= 0.055], 99)) < 1e-3


def _ahead(x: list[int], t: list[float], d: list[float], now: float) -> tuple[float, float]:
    """Where the line of detections `x` is at `now`, and its reach, as first written: from
    its detections at each half-sweep (moving_echoes._Line keeps them as it goes)."""
    me = moving_echoes
    last, back = x[-1], x[-me.TREND] if len(x) >= me.TREND else x[0]
    dt, span = now - t[last], t[last] - t[back]
    if span <= 0:
        return d[last], me.LINK_M + me.START_MPS * dt if dt <= me.START_S else -1.0
    return d[last] + (d[last] - d[back]) / span * dt, me.LINK_M + 0.5 * ACCEL_MAX * dt * dt


def _lines_by_matching(time_s: np.ndarray, distance_m: np.ndarray) -> list[np.ndarray]:
    """moving_echoes.lines as first written: every half-sweep's detections matched to the
    open lines by numeric.matched, a lone one too (the reference of its shortcut)."""
    from fmcw_cl.numeric import matched

    t, d = time_s.tolist(), distance_m.tolist()
    starts = np.r_[0, np.flatnonzero(np.diff(time_s) > 0) + 1, time_s.size].tolist()
    open_: list[list[int]] = []
    out: list[list[int]] = []
    for a, b in zip(starts[:-1], starts[1:], strict=True):
        going = [t[a] - t[x[-1]] <= (moving_echoes.GAP_S if len(x) > 1 else moving_echoes.START_S)
                 for x in open_]
        out += [x for x, g in zip(open_, going, strict=True) if not g and len(x) > 1]
        open_ = [x for x, g in zip(open_, going, strict=True) if g]
        if not open_:
            open_ = [[i] for i in range(a, b)]
            continue
        near = []
        for n, x in enumerate(open_):
            at, reach = _ahead(x, t, d, t[a])
            near += [(m, i, n) for i in range(b - a) if (m := abs(d[a + i] - at)) <= reach]
        taken = [False] * (b - a)
        for i, n in matched(near):
            open_[n].append(a + i)
            taken[i] = True
        open_ += [[a + i] for i in range(b - a) if not taken[i]]
    out += open_
    return [np.asarray(x) for x in out if len(x) >= moving_echoes.MIN_DETECTIONS
            and t[x[-1]] - t[x[0]] >= moving_echoes.MIN_SPAN_S]


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_lines_link_a_lone_detection_as_the_matching_does(seed):
    """A half-sweep's lone detection goes to the nearest line within reach (on a tie the
    first opened) without the matching's sort, and a line's velocity is kept as
    detections join it: the lines of tables of two crossing glides, a rest, fades and
    noise (one to four detections a half-sweep) are those of matching every half-sweep's
    detections with each line's reach made from its detections."""
    rng = np.random.default_rng(seed)
    glide = 0.10 + 1.5 * T
    cross = 0.30 - 1.2 * T
    e = _table(rng, [(glide, 1.5, False), (cross, -1.2, False), (np.full(N, 0.2), 0.0, True)], share=0.6,
               noise=600)
    for way in (True, False):
        t, d = e.time_s[e.rising == way], e.distance_m[e.rising == way]
        got, want = moving_echoes.lines(t, d), _lines_by_matching(t, d)
        assert len(got) == len(want) >= 3
        for a, b in zip(got, want, strict=True):
            np.testing.assert_array_equal(a, b)
