"""Property-based fuzzing (hypothesis, fixed example budgets): the reader, the
segmentation and the pairing raise nothing but the project's own clear errors."""

from __future__ import annotations

import os

import h5py
import numpy as np
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from fmcw_cl.capture import Capture
from fmcw_cl.engine import process
from fmcw_cl.errors import FmcwError
from fmcw_cl.options import Options
from fmcw_cl.simulator.laser import paper_dfb
from fmcw_cl.stages import doppler, faults, pairing, resample, spectrum, sync
from fmcw_cl.stages.lut import build_lut
from fmcw_cl.stages.spectrum import Search

FUZZ = settings(max_examples=int(os.environ.get("FMCW_FUZZ_EXAMPLES", 40)), deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
FS, FMOD = 100e6, 20e3
HP = FS / FMOD / 2
LASER = paper_dfb()
TABLE_I = np.linspace(0.15, 0.49, 25)
TABLE_F = LASER.frequency(TABLE_I)


def triangle(n, half_period, phase, amplitude, offset, rng, noise=4.0):
    p = (np.arange(n) / (2 * half_period) + phase) % 1.0
    tri = np.where(p < 0.5, 4 * p - 1, 3 - 4 * p)
    return offset + amplitude * tri + noise * rng.standard_normal(n)


def codes(x):
    return np.clip(np.rint(x), -8192, 8191).astype(np.int16)


DAMAGE = {
    "fs": [0.0, -1.0, float("nan"), 1e15], "fmod": [0.0, float("inf"), 1e9, 19e3],
    "imin": [0.6, -0.1], "bits": [0, 40], "table": ["nan", "reversed", "short", "narrow"],
    "sync_len": [1, 100],
}


@st.composite
def captures(draw):
    """A small capture (a few periods) with random content and at most one damage."""
    n = draw(st.integers(0, 14)) * 2500 + draw(st.integers(0, 2499))
    rng = np.random.default_rng(draw(st.integers(0, 2**31)))
    hp = HP * draw(st.floats(0.99, 1.01))
    amplitude = draw(st.sampled_from([3000, 3000, 3000, 0, 50, 20000]))
    sync_codes = codes(triangle(n, hp, draw(st.floats(0, 1)), amplitude, draw(st.floats(-1000, 1000)), rng))
    beat = codes(rng.normal(0, draw(st.sampled_from([0.0, 30.0, 3000.0])), n)
                 + 800 * triangle(n, hp, 0.0, 1.0, 0.0, rng, 0.0))
    case = {"fs": FS, "fmod": FMOD, "imin": 0.16, "bits": 14, "table": "good", "sync_len": 0}
    damage = draw(st.sampled_from(["none"] * 6 + sorted(DAMAGE)))
    if damage != "none":
        case[damage] = draw(st.sampled_from(DAMAGE[damage]))
    return n, beat, sync_codes, case


def write_raw(path, n, beat, sync_codes, attrs):
    """Write with h5py directly: CaptureWriter would refuse some of this damage."""
    cur, freq, table = TABLE_I.copy(), TABLE_F.copy(), attrs["table"]
    if table == "nan":
        freq[4] = np.nan
    elif table == "reversed":
        cur = cur[::-1].copy()
    elif table == "short":
        cur, freq = cur[:3], freq[:3]
    elif table == "narrow":
        cur = np.linspace(0.3, 0.4, 25)
    with h5py.File(path, "w") as f:
        f.attrs["fmcw_format"] = "capture"
        f.attrs["format_version"] = 1
        adc = f.create_group("adc")
        adc.attrs["sample_rate_hz"] = attrs["fs"]
        adc.attrs["bits"] = attrs["bits"]
        adc["beat"] = beat
        adc["sync"] = sync_codes[:max(0, n - attrs["sync_len"])]
        mod = f.create_group("modulation")
        mod.attrs["waveform"] = "triangle"
        mod.attrs["frequency_hz"] = attrs["fmod"]
        mod.attrs["current_min_a"] = attrs["imin"]
        mod.attrs["current_max_a"] = 0.48
        f["laser/tuning_current_a"] = cur
        f["laser/tuning_frequency_hz"] = freq


@FUZZ
@given(captures())
def test_reader_and_engine_raise_only_clear_errors(tmp_path_factory, case):
    path = tmp_path_factory.mktemp("fuzz") / "c.h5"
    write_raw(path, *case)
    try:
        with Capture(path) as cap:
            assert cap.info.samples == case[0]
        track = process(path, Options(context_periods=2))
    except FmcwError as exc:
        event(str(exc).split(": ", 1)[-1][:30])
        assert str(exc).startswith(str(path)) or "--min-range" in str(exc)
        assert "\n" not in str(exc)
        return
    event("processed")
    assert track.time_s.size == track.valid.size == track.reason.size
    assert np.all(np.isfinite(track.distance_m[track.valid]))


@FUZZ
@given(n_periods=st.integers(0, 30), phase=st.floats(0, 1), stretch=st.floats(0.995, 1.005),
       amplitude=st.floats(200, 8000), noise=st.floats(0, 200),
       cuts=st.lists(st.integers(0, 150_000), max_size=3), spikes=st.integers(0, 20),
       seed=st.integers(0, 2**31))
def test_segmentation(n_periods, phase, stretch, amplitude, noise, cuts, spikes, seed):
    rng = np.random.default_rng(seed)
    n = int(n_periods * 2 * HP) + int(rng.integers(0, 5000))
    x = triangle(n, HP * stretch, phase, amplitude, 0.0, rng, noise)
    for c in sorted(cuts, reverse=True):          # dropped samples
        if c < x.size:
            x = np.delete(x, np.s_[c:c + int(rng.integers(1, 3000))])
    if x.size and spikes:
        x[rng.integers(0, x.size, spikes)] = rng.choice([-8192, 8191], spikes)
    tp = sync.sync_turning_points(codes(x), HP)
    assert np.all(np.diff(tp.time)[np.diff(tp.segment) == 0] > 0)
    hs = sync.half_sweeps(tp, float(rng.uniform(-40, 40)))
    if hs.length.size:
        assert np.all(np.abs(hs.length / HP - 1) < 0.04)       # the stretch within 0.5 %
        same = hs.segment[1:] == hs.segment[:-1]
        assert np.all(hs.rising[1:][same] != hs.rising[:-1][same])     # directions alternate


LUT = build_lut(TABLE_I, TABLE_F, 0.16, 0.48, 64)
WIN = resample.window(64)
MODEL = doppler.doppler_model(LUT, 25e-6, spectrum.fft_length(64), WIN)


@FUZZ
@given(pairs=st.integers(1, 40), kind=st.sampled_from(["zeros", "noise", "tone", "square"]),
       bin_=st.floats(2, 30), seed=st.integers(0, 2**31), dechirp=st.booleans())
def test_pairing(pairs, kind, bin_, seed, dechirp):
    rng = np.random.default_rng(seed)
    j = np.arange(64)
    if kind == "zeros":
        x = np.zeros((2, pairs, 64))
    elif kind == "noise":
        x = rng.standard_normal((2, pairs, 64))
    elif kind == "tone":
        x = (np.cos(2 * np.pi * bin_ / 64 * j + rng.uniform(0, 6, (2, pairs, 1)))
             + 0.1 * rng.standard_normal((2, pairs, 64)))
    else:                                            # a clipped, square-ish beat
        x = 8191.0 * np.sign(np.cos(2 * np.pi * bin_ / 64 * j) + rng.standard_normal((2, pairs, 1)))
    x = x * WIN
    t = np.arange(pairs) * 50e-6
    res = pairing.track_pairs(x[0], x[1], pairing.Times(t, t + 25e-6), MODEL, Search(2, MODEL.nfft // 2), 3,
                              dechirp)
    assert res.distance.shape == res.velocity.shape == res.valid.shape == (pairs,)
    assert res.valid.dtype == bool
    assert np.all(np.isfinite(res.distance[res.valid]))


@FUZZ
@given(n=st.integers(0, 3000), block=st.sampled_from([1, 3, 16, 64, 256]),
       clips=st.lists(st.tuples(st.integers(0, 2999), st.sampled_from([-8192, -8191, 8190, 8191])),
                      max_size=6),
       spans=st.lists(st.tuples(st.floats(-100, 3100), st.floats(0, 900)), min_size=1, max_size=30))
def test_clipped_share_from_block_counts(n, block, clips, spans):
    """The clipped share through block counts (what a device computes) is the plain
    definition, clipped codes in [floor(start), ceil(start + length)] over its length, to
    within the two partial blocks at the span's ends (taken pro rata)."""
    codes = np.zeros(n, np.int16)
    for at, value in clips:
        if at < n:
            codes[at] = value
    starts, lengths = np.array(spans).T
    hit = np.flatnonzero((codes <= -8192) | (codes >= 8191))      # 8190, -8191: near misses
    a = np.clip(np.floor(starts).astype(np.int64), 0, n)
    b = np.clip(np.ceil(starts + lengths).astype(np.int64) + 1, 0, n)
    exact = np.searchsorted(hit, b) - np.searchsorted(hit, a)
    got = faults.clipped_share(starts, lengths, faults.clip_counts(codes, block, 8192), n, block)
    counts = got * np.maximum(b - a, 1)
    assert np.all(np.abs(counts - exact) <= 2 * min(block, len(clips)) + 1e-9)
    if block == 1:                                                # no partial blocks: exact
        np.testing.assert_allclose(counts, exact, atol=1e-9)
