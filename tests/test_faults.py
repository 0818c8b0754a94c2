"""Faults inside good captures are flagged with a reason, and the rest stays accurate;
bad captures are refused in one clear line; Ctrl-C leaves nothing torn."""

from __future__ import annotations

import re
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import replace

import h5py
import numpy as np
import pytest

from fmcw_cl.capture import Capture
from fmcw_cl.engine import process
from fmcw_cl.errors import CaptureError
from fmcw_cl.options import Options
from fmcw_cl.simulator import SimulationConfig, simulate_capture, static
from fmcw_cl.stages import faults

R = 0.25            # the static_capture fixture's distance
STRETCH = (0.008, 0.010)


def mutated(src, dst, beat=None, sync=None):
    """A copy of `src` with beat/sync edited in place by the given functions."""
    shutil.copy(src, dst)
    with h5py.File(dst, "a") as f:
        for name, fn in (("adc/beat", beat), ("adc/sync", sync)):
            if fn is not None:
                x = f[name][()]
                fn(x)
                f[name][...] = x
    return dst


def inside(track, margin=60e-6):
    t0, t1 = STRETCH
    return (track.time_s > t0 - margin) & (track.time_s < t1 + margin)


def assert_rest_accurate(track, hit):
    rest = ~hit
    assert np.all(track.valid[rest]) and np.all(track.reason[rest] == faults.OK)
    np.testing.assert_allclose(track.distance_m[rest], R, atol=5e-5)
    assert np.percentile(np.abs(track.velocity_mps[rest]), 95) < 1e-3


def test_clipped_stretch(tmp_path, static_capture):
    a, b = (int(t * 100e6) for t in STRETCH)

    def clip(x):
        x[a:b] = np.clip(x[a:b].astype(np.int32) * 8, -8192, 8191)

    track = process(mutated(static_capture, tmp_path / "clip.h5", beat=clip))
    core = (track.time_s > STRETCH[0] + 60e-6) & (track.time_s < STRETCH[1] - 60e-6)
    assert np.all(track.reason[core] == faults.CLIPPED) and not track.valid[core].any()
    hit = track.reason != faults.OK
    assert np.all(hit <= inside(track))
    assert_rest_accurate(track, hit)
    assert track.attrs["invalid_clipped"] == hit.sum()


@pytest.mark.parametrize("seed", [1, 2])
def test_noise_peaks_at_full_scale_are_no_clipping(tmp_path, seed):
    """A lab's gain: 3000 codes rms of noise on a 14-bit ADC, no headroom kept, so noise
    peaks reach full scale in 0.7 % of the codes, in runs of 1-3; the target at -16 dB
    per sample. They do not distort the spectrum: the pairs stay valid, and the clipped
    codes are counted."""
    from fmcw_cl.capture import Capture
    from fmcw_cl.evaluate import accuracy

    path = tmp_path / "noisy.h5"
    cfg = SimulationConfig(echo_codes=2016.0, snr_db=-16.0, headroom=None)   # 3000 codes rms at 0.3 m
    simulate_capture(path, static(0.02, 0.3), 0.02, seed=seed, config=cfg)
    with Capture(path) as cap:
        beat, _ = cap.read(0, cap.info.samples)
        truth = cap.truth()
    at_full_scale = int(np.sum(faults.is_clipped(beat, 8192)))
    assert 0.005 < at_full_scale / beat.size < 0.01
    track = process(path)
    acc = accuracy(track, truth)
    assert acc["valid_share"] >= 0.95 and acc["distance_std_m"] <= 0.1e-3
    assert track.attrs["invalid_clipped"] == 0
    assert abs(track.attrs["clipped_codes"] - at_full_scale) <= 0.02 * at_full_scale


def test_a_saturated_echo_is_clipping(tmp_path):
    """An echo above full scale is cut at its crests: every pair is flagged."""
    path = tmp_path / "saturated.h5"
    simulate_capture(path, static(0.01, 0.1), 0.01, seed=4, config=SimulationConfig(echo_codes=9000.0))
    track = process(path)
    assert (track.reason == faults.CLIPPED).all() and track.attrs["clipped_codes"] > 0.1 * 1e6


def test_beam_blocked(tmp_path, static_capture):
    dark = tmp_path / "dark.h5"
    cfg = replace(SimulationConfig(), echo_codes=0.0)
    simulate_capture(dark, static(0.02, R), 0.02, seed=11, config=cfg)
    with Capture(dark) as cap:
        blocked, _ = cap.read(0, cap.info.samples)
    a, b = (int(t * 100e6) for t in STRETCH)

    def block(x):
        x[a:b] = blocked[a:b]

    track = process(mutated(static_capture, tmp_path / "blocked.h5", beat=block))
    core = (track.time_s > STRETCH[0] + 60e-6) & (track.time_s < STRETCH[1] - 60e-6)
    assert np.all(track.reason[core] == faults.NO_ECHO)
    hit = track.reason != faults.OK
    assert np.all(hit <= inside(track))
    assert_rest_accurate(track, hit)


def test_sync_spikes_are_harmless(tmp_path, static_capture):
    rng = np.random.default_rng(5)

    def spikes(x):
        at = rng.choice(x.size, 40, replace=False)
        x[at] = np.where(rng.random(40) < 0.5, 8191, -8192)

    clean = process(static_capture)
    track = process(mutated(static_capture, tmp_path / "spiky.h5", sync=spikes))
    assert track.pairs == clean.pairs
    assert_rest_accurate(track, np.zeros(track.pairs, bool))


@pytest.mark.parametrize("distance,flagged", [(0.44, False), (0.60, True)])
def test_target_beyond_the_unambiguous_range(tmp_path, distance, flagged):
    path = tmp_path / "far.h5"
    simulate_capture(path, static(0.01, distance), 0.01, seed=17)
    track = process(path, Options(points=1000))
    assert track.attrs["unambiguous_range_m"] < 0.47
    if flagged:      # its alias would read 2 x 0.468 - 0.60 = 0.34 m, with a good SNR
        assert np.all(track.reason == faults.BEYOND_RANGE) and not track.valid.any()
    else:
        assert track.valid.all()
        np.testing.assert_allclose(track.distance_m, distance, atol=1e-4)


def bad_sync(value=None, frequency=None):
    def m(f):
        if value is not None:
            f["adc/sync"][...] = value
        if frequency is not None:
            f["modulation"].attrs["frequency_hz"] = frequency
    return m


@pytest.mark.parametrize("mutate,message", [
    (bad_sync(value=0), "no turning points in the sync channel"),
    (bad_sync(value=8191), "no turning points in the sync channel"),
    (bad_sync(frequency=20.8e3), r"the sync repeats every 50\.0\d us but /modulation frequency_hz "
                                 r"\(20800 Hz\) says 48\.08 us"),
])
def test_bad_sync_is_refused(tmp_path, static_capture, mutate, message):
    path = tmp_path / "bad.h5"
    shutil.copy(static_capture, path)
    with h5py.File(path, "a") as f:
        mutate(f)
    with pytest.raises(CaptureError) as err:
        process(path)
    assert str(err.value).startswith(str(path)) and re.search(message, str(err.value))


@pytest.mark.parametrize("ratio", [1.025, 1 / 1.025])
def test_a_sync_off_its_stated_frequency_within_the_tolerance_is_converted(tmp_path, static_capture, ratio):
    """A sync 2.5 % off /modulation frequency_hz, which the period check lets through
    (plan.PERIOD_TOLERANCE: 3 %), is converted, the ratio stated: not "no complete
    modulation period found" (the turning points' spacing test allowed 2 %)."""
    path = tmp_path / "off.h5"
    shutil.copy(static_capture, path)
    with h5py.File(path, "a") as f:
        bad_sync(frequency=20e3 * ratio)(f)
    track = process(path)
    assert track.attrs["sync_period_ratio"] == pytest.approx(ratio, rel=1e-3)
    assert track.valid.mean() > 0.95
    np.testing.assert_allclose(track.distance_m[track.valid], R, atol=1e-4)


def test_truncated_file(tmp_path, static_capture, fmcw):
    cut = tmp_path / "cut.h5"
    shutil.copy(static_capture, cut)
    with open(cut, "r+b") as fh:
        fh.truncate(cut.stat().st_size // 2)
    proc = fmcw("process", cut, static_capture, "-o", tmp_path / "out", "-q", check=False)
    assert proc.returncode == 1
    assert proc.stderr.strip() == f"error: {cut}: truncated HDF5 file " \
        f"({cut.stat().st_size} of {static_capture.stat().st_size} bytes: an interrupted copy or write?)"
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["static.track.h5"]


@pytest.mark.parametrize("backend", ["auto", "numpy"])
def test_ctrl_c_stops_cleanly(tmp_path, static_capture, backend):
    """Ctrl-C in the middle of a batch: exit 130 with one line, the tracks already
    finished are whole, and the interrupted one leaves nothing (not even a .part); also
    where two captures convert at once (numpy: batch.process_each's workers)."""
    from fmcw_cl.track import read_track

    caps = [shutil.copy(static_capture, tmp_path / f"cap{k}.h5") for k in range(8)]
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "fmcw_cl.cli.main", "process", *map(str, caps),
                             "-o", str(out), "-q", "--backend", backend], stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while not (out.exists() and any(out.glob("*.h5"))) and time.monotonic() < deadline:
        time.sleep(0.05)                        # interrupt while the second capture converts
    assert proc.poll() is None, "finished before it could be interrupted"
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130
    assert err.strip() == "interrupted"
    left = sorted(out.iterdir())
    assert 1 <= len(left) < len(caps) and all(p.suffix == ".h5" for p in left)
    for p in left:
        assert read_track(p).pairs > 0


def test_ctrl_c_lost_in_a_finalizer_is_raised_again():
    """A KeyboardInterrupt raised inside a finalizer (device buffers return to their pool
    that way) is printed as ignored and lost; with the command line's latch the next
    progress report raises it again."""
    import gc
    import os
    import weakref

    from fmcw_cl import progress

    previous, hook = signal.getsignal(signal.SIGINT), sys.unraisablehook
    try:
        progress.latch_interrupts()

        class Rows:
            pass

        def back_to_the_pool():
            os.kill(os.getpid(), signal.SIGINT)     # Ctrl-C arrives while the finalizer runs
            sum(range(1000))                        # its KeyboardInterrupt is raised here

        rows = Rows()
        weakref.finalize(rows, back_to_the_pool)
        del rows
        gc.collect()
        time.sleep(0.01)                            # no KeyboardInterrupt got out
        with pytest.raises(KeyboardInterrupt):
            progress.Progress("job", enabled=False)(1)
    finally:
        signal.signal(signal.SIGINT, previous)
        sys.unraisablehook = hook
        progress._interrupted = False


def test_target_crossing_the_unambiguous_range_is_flagged(tmp_path):
    """A target receding at 1 m/s from 0.42 m crosses the 0.468 m limit after 48 ms:
    pairs well inside are valid and accurate, none beyond the limit is reported valid
    (the check runs on every 4th pair near the limit, every 16th far from it)."""
    from fmcw_cl.simulator.scene import Trajectory

    path = tmp_path / "crossing.h5"
    trajectory = Trajectory.from_velocity(0.0, 0.07, lambda t: np.full_like(t, 1.0), np.zeros_like, 0.42)
    simulate_capture(path, trajectory, 0.06, seed=23)
    track = process(path, Options(points=1000))
    limit = track.attrs["unambiguous_range_m"]
    true = 0.42 + 1.0 * track.time_s
    inside = true < limit - 0.03
    assert track.valid[inside].mean() > 0.97
    assert np.abs(track.distance_m - true)[track.valid].max() < 0.3e-3
    assert not np.any(track.valid[true > limit])
    assert np.all(track.reason[true > limit + 0.002] == faults.BEYOND_RANGE)
