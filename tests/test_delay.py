"""The sync delay measured from the capture's own target (refine): a lab's weak
intensity triangle leaves the first estimate samples off; kinematic consistency moves
it to where a static target reads no velocity, with its uncertainty stated."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from conftest import process

from fmcw_cl import refine
from fmcw_cl.motion import SMOOTH, Motion
from fmcw_cl.options import Options
from fmcw_cl.second_look import LOOK_K

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


def test_a_run_of_the_delays_refinement_bridges_isolated_invalid_pairs():
    """A run of `refine` goes on across a few invalid pairs where the distance moves as
    the velocity says, not across a longer gap or a step to another echo."""
    from fmcw_cl.refine import BRIDGE_M, BRIDGE_PAIRS, bridged_runs

    t = np.arange(60) * 5e-5
    v = np.full(60, 0.5)
    d = 0.2 + v * t
    ok = np.ones(60, bool)
    ok[[5, 9, 10]] = False                             # isolated pairs: one run
    ok[20: 21 + BRIDGE_PAIRS] = False                  # a longer gap: two
    d[45:] += 2 * BRIDGE_M                             # another echo after a short gap: three
    ok[44] = False
    got = bridged_runs(t, d, v, ok)
    want = [np.flatnonzero(ok[:20]), np.arange(21 + BRIDGE_PAIRS, 44), np.arange(45, 60)]
    assert [r.tolist() for r in got] == [w.tolist() for w in want]
    assert bridged_runs(t[:4], d[:4], v[:4], np.zeros(4, bool)) == []


def _line_slope(t: np.ndarray, r: np.ndarray) -> tuple[float, float]:
    """Least-squares slope of r over t and its standard error for white residuals, of
    one run alone: what numeric.drifts' group sums must give for it."""
    from fmcw_cl.numeric import centred_slope

    slope, tt, tc, rc = centred_slope(t, r)
    resid = rc - slope * tc
    return slope, float(np.sqrt(np.sum(resid * resid) / max(1, t.size - 2) / tt))


@pytest.mark.parametrize("phi", [0.0, 0.85])
def test_the_drifts_error_holds_for_distances_correlated_over_pairs(phi):
    """refine.drift over runs of 220 valid pairs (bridged gaps) whose distance noise is
    white or correlated over several pairs (AR(1), as the tracker's under noise at full
    scale): the slopes are unbiased and the stated error matches their spread over 300
    runs; with the correlation the white residuals' error alone is far too small."""
    from fmcw_cl.refine import drift

    rng = np.random.default_rng(3)
    t = np.arange(240) * 5e-5
    t = t[np.sort(rng.choice(t.size, 220, replace=False))]
    slopes, errors, white = [], [], []
    for _ in range(300):
        e = rng.normal(0, 40e-6, t.size)
        for i in range(1, t.size):
            e[i] += phi * e[i - 1]
        d = 0.3 + 0.004 * t + e
        v = np.full(t.size, 0.004)                     # consistent: the drift is zero
        slope, se = drift(t, d, v)
        slopes.append(slope)
        errors.append(se)
        white.append(_line_slope(t, d)[1])
    spread = np.std(slopes)
    assert abs(np.mean(slopes)) < 3 * spread / np.sqrt(len(slopes))
    assert 0.8 < np.sqrt(np.mean(np.square(errors))) / spread < 1.3
    if phi:
        assert np.median(white) < 0.6 * spread


@pytest.mark.parametrize("pairs", [17, 61, 240])
def test_the_drifts_jackknife_is_each_block_left_out_and_fitted_again(pairs):
    """numeric.drift's jackknife from block sums equals fitting the run again without
    each block (np.array_split's blocks: uneven where the blocks do not divide it); runs
    laid end to end (numeric.drifts) each as alone."""
    from fmcw_cl.numeric import drift, drifts, travelled

    rng = np.random.default_rng(pairs)
    t = 2.0 + np.sort(rng.choice(pairs + 20, pairs, replace=False)) * 5e-5
    d = 0.3 + 1.5 * (t - 2.0) + np.cumsum(rng.normal(0, 40e-6, pairs))
    v = 1.5 + rng.normal(0, 1e-3, pairs)
    r = d - travelled(t, v)
    loo = [_line_slope(np.delete(t, b), np.delete(r, b))[0] for b in np.array_split(np.arange(pairs), 6)]
    jack = np.sqrt(5 / 6 * np.sum(np.square(np.subtract(loo, np.mean(loo)))))
    slope, se = drift(t, d, v, 6)
    assert slope == pytest.approx(_line_slope(t, r)[0], rel=1e-12)
    assert se == pytest.approx(max(jack, _line_slope(t, r)[1]), rel=1e-9)
    assert jack > _line_slope(t, r)[1]                     # the jackknife's error is the one stated
    # this run between two others, one shorter than the blocks, at other times and speeds
    cut = [2, pairs, 9]
    ts, ds, vs = (np.concatenate(x) for x in zip((t[:2] - 1.0, d[:2], v[:2] + 3.0), (t, d, v),
                                                 (t[:9] + 1.0, d[:9] - 0.1, -v[:9]), strict=True))
    slopes, errors = drifts(ts, ds, vs, np.array(cut), 6)
    np.testing.assert_allclose(slopes[1:2], slope, rtol=1e-12)
    np.testing.assert_allclose(errors[1:2], se, rtol=1e-9)
    for k, (a, b) in enumerate(((0, 2), (2 + pairs, 11 + pairs))):
        one = drift(ts[a:b], ds[a:b], vs[a:b], 6)
        np.testing.assert_allclose([slopes[k * 2], errors[k * 2]], one, rtol=1e-9)


def test_a_line_through_unsettled_trials_gives_the_root_and_its_error():
    from fmcw_cl.refine import line_root

    rng = np.random.default_rng(5)
    x = np.array([-2.8, -0.8, 0.9, 3.3, 2.3])
    sigma = np.full(x.size, 0.002)
    roots, errors = [], []
    for _ in range(400):
        got = line_root(x, -0.004 * (x - 1.0) + rng.normal(0, 0.002, x.size), sigma)
        assert got is not None and abs(got[2] + 0.004) < 0.004
        roots.append(got[0])
        errors.append(got[1])
    assert abs(np.mean(roots) - 1.0) < 0.05
    assert 0.8 < np.median(errors) / np.std(roots) < 1.3
    assert line_root(x, 0.01 + 0.001 * x, sigma) is None          # its root outside the trials


def test_a_refinement_that_ends_off_its_root_states_the_miss_as_uncertainty(monkeypatch):
    """A noisy capture's secant steps: 0.171, 0.141, then 0.117 m/s (7.6 of its sigmas)
    at -18.4 samples, and a trial without runs ends the search. The delay is not at a
    root, so the uncertainty holds the miss: about 8 samples, not the 1.0 of its sigma
    alone (the capture's numpy refinement lands 54 samples away)."""
    from dataclasses import dataclass

    trials = {-29.88: (0.1708, 0.0100), -27.88: (0.1409, 0.0164)}

    def mismatches(held, plan, lags, processor):
        return [refine.Mismatch(*trials.get(round(lag, 2), (0.1168, 0.0154) if lag < 0 else (np.nan, np.nan)),
                                0.236) for lag in lags]

    @dataclass(frozen=True)
    class Plan:
        lag: float = -29.88
        lag_refined: bool = False
        lag_mismatch_mps: float = np.nan
        lag_sigma_samples: float = np.nan
        lag_sigma_mps: float = np.nan
        lag_sigma_m: float = np.nan
        lag_at_m: float = np.nan
        motion: Motion = SMOOTH

    monkeypatch.setattr(refine, "stretches", lambda cap, plan, processor: [])
    monkeypatch.setattr(refine, "mismatches", mismatches)
    got = refine.refine_lag(None, Plan(), None)
    assert got.lag_refined and abs(got.lag - -18.43) < 0.05
    slope = (0.1409 - 0.1708) / 2
    assert got.lag_sigma_samples == pytest.approx(np.hypot(0.0154, 0.1168) / abs(slope), rel=1e-6)
    assert got.lag_sigma_samples > 7.5 and got.lag_sigma_mps > 0.1


def test_a_trial_without_runs_does_not_end_the_delay_search(monkeypatch):
    """Under noise at full scale a trial near the root may hold no run of valid pairs
    (its mismatch NaN): the search goes half way back to the last trial with runs and
    on, where it ended there (a lab capture's delay 55 samples off on OpenCL)."""
    from dataclasses import dataclass

    from fmcw_cl import refine

    @dataclass
    class Plan:
        lag: float
        lag_refined: bool = False
        lag_mismatch_mps: float = float("nan")
        lag_sigma_samples: float = float("nan")
        lag_sigma_mps: float = float("nan")
        lag_sigma_m: float = float("nan")
        lag_at_m: float = float("nan")
        motion: Motion = SMOOTH

    root, tried = 36.5, []

    def mismatch(lag):       # linear, and no runs 5-12 samples below the root
        tried.append(lag)
        if root - 12 < lag < root - 5:
            return refine.Mismatch(float("nan"), float("nan"), float("nan"))
        noise = 7e-4 if lag == -29.8 else 0.0       # the first secant step lands in the gap
        return refine.Mismatch(-0.0023 * (lag - root) + noise, 0.001, 0.2363)

    monkeypatch.setattr(refine, "stretches", lambda cap, plan, processor: [])
    monkeypatch.setattr(refine, "mismatches", lambda held, plan, lags, processor: list(map(mismatch, lags)))
    got = refine.refine_lag(None, Plan(lag=-29.8), None)
    assert any(root - 12 < x < root - 5 for x in tried)             # the search met the gap
    assert got.lag_refined and abs(got.lag - root) < 0.1
    assert len(tried) <= refine.MAX_EVALUATIONS


def test_trial_stretches_converted_together_equal_each_converted_apart(tmp_path, monkeypatch):
    """ChunkProcessor.process_apart (the delay's trial conversions: one pass, one trip
    each way on a device) gives each chunk of the trial stretches the measurements of
    its own conversion: chunks of 27 periods (several a stretch, odd counts of pairs,
    one chunk's pairs tracked beside another's), at the true delay and 3 samples off in
    one pass (`Held.at`: each chunk twice, at each delay), on a weak lab's landing under
    noise at full scale. With the integration left to the
    chunk, a chunk whose single pairs are too weak for it (here some are, some are not)
    is converted on its own; with K given (the second look's), none is, and each chunk's
    windows end at its ends. Equal but for float rounding (the resampling's positions
    are offset into the codes of all the chunks). Each delay's chunks are converted as in
    a pass of their own, to the bit on a device too: the float32 resampling and the
    plain transforms (two rows each) pair no chunk's rows with another's, though the
    second delay's rows start at an odd row of the pass. On the OpenCL processor: the
    grouping is the base class's, and numpy's twin of each pass is held to the device's
    by tests/test_opencl.py (a numpy run here cost 43 s of the suite's 21 min)."""
    from fmcw_cl.backend import make_processor
    from fmcw_cl.capture import Capture
    from fmcw_cl.plan import make_plan

    path = tmp_path / "landing.h5"
    cfg = replace(LAB, headroom=None, snr_db=-15.0)
    true = simulate_capture(path, jump(0.3), 0.05, start_s=0.18, seed=4, config=cfg)["sync_delay_samples"]
    be = make_processor("opencl")
    tol = 2e-5
    with Capture(path) as cap:
        plan = make_plan(cap, Options(chunk_periods=27), lag=true, processor=be)
        held = refine.stretches(cap, plan, be)
        assert len(held.chunks) >= 9 and len(set(held.stretch)) == 3
        be.open(plan)
        pairs = [got[3].rise.size for c, p in zip(held.chunks, held.prepared, strict=True)
                 if (got := be._pairs(c, p, plan.lag)) is not None]
        assert sum(pairs) % 2 == 1          # a second delay's rows start at an odd row
        for lags, k in (([plan.lag, plan.lag + 3.0], None), ([plan.lag], LOOK_K)):
            apart = []
            for lag in lags:
                trial = refine.trial_plan(plan, lag)
                be.open(replace(trial, options=replace(trial.options, integrate=k)))
                apart += [be.process(c, p) for c, p in zip(held.chunks, held.prepared, strict=True)]
            be.open(replace(be.plan, lag=lags[0]))
            alone, real = [], be.process           # the chunks process_apart converts on their own
            monkeypatch.setattr(be, "process", lambda c, p, a=alone, real=real: a.append(c) or real(c, p))
            together = be.process_apart(held.at(lags))
            assert 0 < len(alone) < len(apart) if k is None else not alone
            if k is not None:
                assert max(m.result.integrated.max() for got in together for m in got) == k
            _assert_same(together, apart, tol,
                         ("valid", "integrated", "distance", "velocity", "dechirped_rise", "dechirped_fall"))
            monkeypatch.undo()
            assert any(m.result.valid.any() for got in together for m in got)
            if len(lags) > 1:
                n = len(held.chunks)
                for j, lag in enumerate(lags):
                    _assert_same(together[j * n:(j + 1) * n], be.process_apart(held.at([lag])))


def _assert_same(one: list, other: list, atol: float = 0.0, keys: tuple | None = None) -> None:
    """Lists of chunks' measurements: the same pairs and reasons, and the arrays `keys`
    of their results (None: all, echoes aside) within `atol` (0: to the bit)."""
    assert len(one) == len(other)
    for x, y in zip(one, other, strict=True):
        assert len(x) == len(y)
        for a, b in zip(x, y, strict=True):
            np.testing.assert_array_equal(a.t_rise, b.t_rise)
            np.testing.assert_array_equal(a.reason, b.reason)
            for key in keys or [k for k in a.result.__dataclass_fields__
                                if isinstance(getattr(a.result, k), np.ndarray)]:
                np.testing.assert_allclose(getattr(a.result, key), getattr(b.result, key), rtol=0, atol=atol,
                                           err_msg=key)


@pytest.mark.parametrize("name", ["numpy", "opencl"])
def test_the_second_look_converts_the_stretches_the_refinement_read(static_capture, monkeypatch, name):
    """A lone fixed echo's second look converts the delay's trial stretches again, as
    the refinement read and prepared them (`Capture.held`): one read a capture, and the
    track is the one that reading them twice gave."""
    from fmcw_cl import engine
    from fmcw_cl.backend import make_processor
    from fmcw_cl.capture import Capture

    be = make_processor(name)
    reads, looks = [], []
    real_read, real_look = refine.held_end_to_end, engine.moving_beside
    monkeypatch.setattr(refine, "held_end_to_end", lambda *a: reads.append(1) or real_read(*a))
    monkeypatch.setattr(engine, "moving_beside", lambda *a: looks.append(1) or real_look(*a))
    with monkeypatch.context() as m:            # nothing kept: the stretches read twice
        m.setattr(Capture, "held", property(lambda self: None, lambda self, value: None), raising=False)
        want = process(static_capture, Options(), be)
    assert looks == [1] and reads == [1, 1]
    got = process(static_capture, Options(), be)
    assert looks == [1, 1] and reads == [1, 1, 1]
    for key in ("distance_m", "velocity_mps", "valid", "reason"):
        np.testing.assert_array_equal(getattr(got, key), getattr(want, key))


@pytest.mark.parametrize(("seed", "start_s", "duration_s"), [(95, 0.064, 0.032), (692, 0.060, 0.033)])
def test_where_the_refined_delay_and_the_triangles_disagree_the_rule_is_said(tmp_path, fmcw, seed, start_s,
                                                                            duration_s):
    """Short take-offs at a lab's SNR: the moving beat leaks into the intensity
    triangle's fit (76-113 samples, stated +-11-14), the refinement on the target's own
    motion is right. They disagree by more than 3 sigmas: `process` says so and which
    one it uses (refine.disagreement's rule), and the refined one covers the truth."""
    path = tmp_path / "takeoff.h5"
    true = simulate_capture(path, jump(0.3), duration_s, seed=seed, config=LAB,
                            start_s=start_s)["sync_delay_samples"]
    a = process(path).attrs
    assert a["sync_delay_disagreement_sigmas"] > a["sync_delay_disagreement_limit"] == refine.DISAGREE_SIGMAS
    assert abs(a["sync_delay_samples"] - true) <= 3 * a["sync_delay_uncertainty_samples"] + 0.3
    assert abs(a["sync_delay_intensity_samples"] - true) > 10
    err = fmcw("process", path, "-o", tmp_path / "o").stderr
    assert "sigmas apart: the refined one is used" in err


def test_the_intensity_estimates_error_is_the_medians():
    from fmcw_cl.stages import delay

    rng = np.random.default_rng(4)
    sigmas = [delay.combine_delays(rng.normal(5.0, 2.0, 400), np.full(400, 0.1))[3] for _ in range(3)]
    assert all(0.1 < s < 0.15 for s in sigmas)         # 1.25 x 2 / sqrt(400) = 0.125
    assert np.isnan(delay.combine_delays(np.array([1.0, 2.0]), np.array([0.1, 0.1]))[3])


def test_trial_stretches_without_still_echoes_are_each_converted_alone(tmp_path):
    """A plan whose rows lose their still echoes (Plan.still_half: a running mean along
    each chunk's rows) converts held chunks each alone: a mean must not reach across
    chunks, which process_apart would put side by side."""
    from fmcw_cl.backend import make_processor
    from fmcw_cl.capture import Capture
    from fmcw_cl.plan import make_plan

    path = tmp_path / "landing.h5"
    simulate_capture(path, jump(0.3), 0.03, start_s=0.18, seed=4, config=replace(LAB, headroom=None))
    be = make_processor("numpy")
    with Capture(path) as cap:
        plan = make_plan(cap, Options(chunk_periods=27), processor=be)
        held = refine.stretches(cap, plan, be)
        still = replace(plan, check=None, survey=False, still_half=5)
        be.open(still)
        apart = [be.process(c, p) for c, p in zip(held.chunks, held.prepared, strict=True)]
        be.open(still)
        together = be.process_apart(held)
    _assert_same(together, apart)
