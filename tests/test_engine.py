"""The stream engine: chunking invariance, dropped samples, option checks."""

from __future__ import annotations

import numpy as np
import pytest

from fmcw_cl.capture import Capture
from fmcw_cl.capture_writer import CaptureWriter
from fmcw_cl.engine import process
from fmcw_cl.errors import FmcwError
from fmcw_cl.options import Options
from fmcw_cl.stages import faults


def test_chunk_size_does_not_change_the_track(static_capture):
    a = process(static_capture, Options(chunk_periods=2048))
    b = process(static_capture, Options(chunk_periods=97, context_periods=16))
    np.testing.assert_array_equal(a.valid, b.valid)
    # each chunk fits its own turning-point grid: times agree to a small fraction of a sample
    np.testing.assert_allclose(a.time_s, b.time_s, rtol=0, atol=1e-9)
    np.testing.assert_allclose(a.distance_m, b.distance_m, rtol=0, atol=1e-7)
    np.testing.assert_allclose(a.velocity_mps, b.velocity_mps, rtol=0, atol=1e-4)


@pytest.mark.parametrize("kind", ["numpy", "opencl"])
def test_a_conversion_in_place_equals_one_that_reads(static_capture, kind, monkeypatch):
    """Chunks as views of the file's pages (a processor that reads in place: numpy's, a
    CPU device's) and chunks read into slots make the same track, bit for bit; once the
    conversion is done the file's map is closed (the processor let the codes go before
    the capture closed, and a reader thread unmapped it)."""
    import time

    from fmcw_cl.backend import make_processor

    processor = make_processor(kind)
    maps, mapped = [], Capture._map

    def watched(self):
        got = mapped(self)
        maps.append(self._mmap)
        return got

    monkeypatch.setattr(Capture, "_map", watched)
    assert processor.reads_in_place
    in_place = process(static_capture, Options(chunk_periods=150), processor)
    deadline = time.monotonic() + 5
    while len(maps) == 1 and not maps[0].closed and time.monotonic() < deadline:
        time.sleep(0.01)
    assert len(maps) == 1 and maps[0].closed
    monkeypatch.setattr(type(processor), "reads_in_place", False)
    read = process(static_capture, Options(chunk_periods=150), processor)
    assert len(maps) == 1 and in_place.pairs > 350
    for name in ("time_s", "distance_m", "velocity_mps", "valid", "reason", "sweep_distance_m"):
        np.testing.assert_array_equal(getattr(in_place, name), getattr(read, name))


def test_chunks_fit_the_device_memory(static_capture):
    """A backend whose device holds 300 periods gets chunks of 300 - 2 x 64 context
    - 2; the track matches the default chunks'."""
    from fmcw_cl.processor import NumpyProcessor

    class Small(NumpyProcessor):
        def chunk_limit(self, samples_per_period, points):
            return 300

    a = process(static_capture, Options())
    b = process(static_capture, Options(), Small())
    np.testing.assert_array_equal(a.valid, b.valid)
    np.testing.assert_allclose(a.distance_m, b.distance_m, rtol=0, atol=1e-7)
    from fmcw_cl.plan import fit_chunks

    with Capture(static_capture) as cap:
        assert fit_chunks(Options(), cap.info, Small()).chunk_periods == 300 - 128 - 2
        assert fit_chunks(Options(), cap.info, NumpyProcessor()).chunk_periods == 1024

        class Device(NumpyProcessor):       # a device's own chunk size, unless one is asked for
            chunk_default = 8192

        assert fit_chunks(Options(), cap.info, Device()).chunk_periods == 8192
        assert fit_chunks(Options(chunk_periods=500), cap.info, Device()).chunk_periods == 500
        assert fit_chunks(Options(chunk_periods=5000), cap.info, Small()).chunk_periods == 300 - 128 - 2


def test_dropped_samples_split_the_stream(tmp_path, static_capture):
    """Lose 1234 samples in the middle: the periods around the jump are invalid,
    the rest is as accurate as before."""
    cut = tmp_path / "dropped.h5"
    with Capture(static_capture) as cap:
        info = cap.info
        beat, sync = cap.read(0, info.samples)
        keep = np.r_[0:1_000_000, 1_001_234:info.samples]
        with CaptureWriter(cut, keep.size, info.sample_rate_hz, info.bits, info.modulation,
                           info.tuning_current_a, info.tuning_frequency_hz) as w:
            w.write(0, beat[keep], sync[keep])
    whole = process(static_capture)
    track = process(cut)
    assert 1 <= np.sum(~track.valid) <= 3
    assert np.all(track.reason[~track.valid] == faults.SYNC_GAP)
    bad_t = track.time_s[~track.valid]
    assert np.all(np.abs(bad_t - 0.01) < 2e-4)          # around sample 1 000 000
    assert track.pairs >= whole.pairs - 1                # the lost period is listed, invalid
    np.testing.assert_allclose(track.distance_m[track.valid], 0.25, atol=2e-5)


def test_min_range_beyond_the_unambiguous_range_is_refused(static_capture):
    with pytest.raises(FmcwError, match="unambiguous range"):
        process(static_capture, Options(points=100, min_range=0.1))


def test_process_each_keeps_order_and_reports_bad_files(tmp_path, static_capture):
    """A batch converted two at a time: results in the order given, each equal to the
    capture converted alone, a bad file reported as its error without stopping the
    others, and each capture's progress under its own index (zeros when it starts)."""
    from fmcw_cl.batch import process_each
    from fmcw_cl.processor import NumpyProcessor

    bad = tmp_path / "bad.h5"
    bad.write_bytes(b"not a capture")
    paths = [static_capture, bad, static_capture, static_capture]
    started, seen = set(), set()

    def progress(i, done, total, fs):
        (seen if total else started).add(i)

    got = list(process_each(paths, processor=NumpyProcessor(), workers=2, progress=progress))
    assert [p for p, _ in got] == paths
    assert isinstance(got[1][1], FmcwError) and str(bad) in str(got[1][1])
    alone = process(static_capture)
    for _, track in (got[0], got[2], got[3]):
        np.testing.assert_array_equal(track.valid, alone.valid)
        np.testing.assert_array_equal(track.distance_m, alone.distance_m)
    assert started == {0, 1, 2, 3} and seen == {0, 2, 3}


def test_process_each_stops_on_an_exception(static_capture):
    """An exception other than a capture's error (here Ctrl-C seen by a progress report)
    ends the batch: it reaches the caller, and no later capture is started."""
    from fmcw_cl.batch import process_each
    from fmcw_cl.processor import NumpyProcessor

    started = set()

    def progress(i, done, total, fs):
        started.add(i)
        if i == 0:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        list(process_each([static_capture] * 5, processor=NumpyProcessor(), workers=2, progress=progress))
    assert started <= {0, 1}


def test_read_ahead_starts_at_once_and_close_waits():
    """The chunk reader starts its first read when made (a capture's first chunk is read
    while its plan is made), yields in order, and `close` returns only when a read in
    flight has ended (its slot must not be handed on mid-read)."""
    import threading

    from fmcw_cl.chunks import ReadAhead

    assert list(ReadAhead(iter([1, 2, 3]))) == [1, 2, 3]
    started, release, finished = threading.Event(), threading.Event(), threading.Event()

    def items():
        started.set()
        release.wait(10)
        finished.set()
        yield 1

    ahead = ReadAhead(items())
    assert started.wait(10)                      # before anything asked for an item
    threading.Timer(0.2, release.set).start()
    ahead.close()
    assert finished.is_set()


def test_the_first_chunk_is_read_while_the_plan_is_made(static_capture, monkeypatch):
    """`process` starts the first conversion's reader before the plan, and capture_parts
    takes it; a reader of chunks of another geometry is closed and its own read instead,
    with the same measurements."""
    from dataclasses import replace

    from fmcw_cl import chunks, engine
    from fmcw_cl.plan import make_plan
    from fmcw_cl.processor import NumpyProcessor

    calls = []

    def spy(module, name):
        real = getattr(module, name)

        def call(*args, **kwargs):
            calls.append(name)
            return real(*args, **kwargs)
        monkeypatch.setattr(module, name, call)

    spy(chunks, "read_chunks")
    spy(engine, "make_plan")
    spy(engine, "capture_parts")
    monkeypatch.setattr(engine, "read_chunks", chunks.read_chunks)
    engine.process(static_capture, processor=NumpyProcessor())
    assert calls[:3] == ["read_chunks", "make_plan", "capture_parts"]
    assert calls[3:4] != ["read_chunks"]
    monkeypatch.undo()
    with Capture(static_capture) as cap:
        plan = make_plan(cap, Options(), processor=NumpyProcessor())
        alone = chunks.capture_parts(cap, plan, NumpyProcessor())
        other = chunks.read_chunks(cap, replace(plan.options, chunk_periods=plan.options.chunk_periods + 3))
        given = chunks.capture_parts(cap, plan, NumpyProcessor(), ahead=other)
    assert len(given) == len(alone) > 0
    for a, b in zip(given, alone, strict=True):
        np.testing.assert_array_equal(a.t_rise, b.t_rise)
        np.testing.assert_array_equal(a.result.distance, b.result.distance)


@pytest.fixture(scope="module")
def receding(tmp_path_factory):
    """60 ms of a target receding at 1 m/s from 0.42 m: it crosses the 0.468 m limit
    of --points 1000 after 48 ms (the range check flags the pairs beyond)."""
    from fmcw_cl.simulator.scene import Trajectory
    from fmcw_cl.simulator.writer import simulate_capture

    path = tmp_path_factory.mktemp("receding") / "receding.h5"
    trajectory = Trajectory.from_velocity(0.0, 0.07, lambda t: np.full_like(t, 1.0), np.zeros_like, 0.42)
    simulate_capture(path, trajectory, 0.06, seed=23)
    return path


@pytest.mark.parametrize("kind", ["numpy", "opencl"])
def test_a_capture_s_next_conversions_take_what_its_chunks_gave(receding, kind, monkeypatch):
    """A processor's next conversion of a capture (another band from the same bin, as an
    object's) makes neither the chunks' turning points and clipping nor their range
    checks again (chunk_memo), and measures what a new processor measures, the pairs
    beyond the range flagged as there; a band from another bin checks its own; the next
    capture's chunks, and those of a processor closed since, are their own."""
    from fmcw_cl.backend import make_processor
    from fmcw_cl.chunks import capture_parts
    from fmcw_cl.plan import make_plan

    def made(processor) -> list:
        calls = []

        def spied(name):
            real = getattr(processor, name)

            def call(*args):
                checks = name.startswith("prepare") or args[0].check is not None
                calls.append(name[:7] if checks else "survey")
                return real(*args)
            return call

        for name in ("prepare", "prepare_later", "check_and_survey", "check_and_survey_later"):
            monkeypatch.setattr(processor, name, spied(name))
        return calls

    def reasons(parts) -> np.ndarray:
        return np.concatenate([p.reason for p in parts])

    processor = make_processor(kind)
    calls = made(processor)
    options = Options(points=1000, chunk_periods=200)
    with Capture(receding) as cap:
        plan = make_plan(cap, options, processor=make_processor(kind))
        capture_parts(cap, plan, processor)
        assert {"prepare", "check_a"} <= set(calls)
        for band, made_again in (((plan.options.band_m[0], 0.46), set()), ((0.2, None), {"check_a"})):
            calls.clear()
            again = capture_parts(cap, plan.with_band(band), processor)
            assert set(calls) - {"survey"} == made_again
            fresh = capture_parts(cap, plan.with_band(band), make_processor(kind))
            np.testing.assert_array_equal(reasons(again), reasons(fresh))
            for a, b in zip(again, fresh, strict=True):
                np.testing.assert_array_equal(a.result.distance, b.result.distance)
            assert np.mean(reasons(again) == faults.BEYOND_RANGE) > 0.1
    calls.clear()
    with Capture(receding) as cap:
        plan = make_plan(cap, options, processor=make_processor(kind))
        capture_parts(cap, plan, processor)
        assert "prepare" in calls
        calls.clear()
        processor.close()
        capture_parts(cap, plan, processor)
    assert "prepare" in calls


def test_read_ahead_peeks_at_the_next_item_and_reads_no_further():
    """`peek` gives the item after the one being processed (its slot is the other one);
    the read after that starts only when the iteration moves on (it takes the slot of
    the item being processed)."""
    from fmcw_cl.chunks import ReadAhead

    made = []

    def items():
        for x in (1, 2, 3):
            made.append(x)
            yield x

    seen = []
    with ReadAhead(items()) as ahead:
        for x in ahead:
            nxt = ahead.peek()
            seen.append((x, nxt, list(made)))
    assert seen == [(1, 2, [1, 2]), (2, 3, [1, 2, 3]), (3, None, [1, 2, 3])]


def test_a_choice_beside_walls_keeps_the_first_assemblys_echo_table(tmp_path, monkeypatch):
    """A choice that lists walls re-assembles the first conversion's pairs (their
    ambiguity and the walls' images depend on it) with the echo table the first assembly
    made of them, which the choice does not change: the track equals one whose table is
    made again."""
    from dataclasses import replace

    from fmcw_cl import engine
    from fmcw_cl.simulator import LAB, jump, simulate_capture

    path = tmp_path / "take-off.h5"
    walls = replace(LAB, reflectors=((0.25, 400.0),))
    simulate_capture(path, jump(0.3), 0.05, seed=3, start_s=0.06, config=walls)
    real, kept = engine.assemble, []

    def assemble(*args, **kw):
        kept.append(len(args) > 5 or kw.get("seen") is not None)
        return real(*args, **kw)

    monkeypatch.setattr(engine, "assemble", assemble)
    track = process(path, Options())
    assert kept == [False, True] and track.valid.any()
    monkeypatch.setattr(engine, "assemble", lambda *args: real(*args[:5]))
    again = process(path, Options())
    for key in ("time_s", "distance_m", "velocity_mps", "valid", "reason"):
        np.testing.assert_array_equal(getattr(track, key), getattr(again, key))
    np.testing.assert_equal(track.echoes.attrs(), again.echoes.attrs())     # NaN equals NaN


def test_owned_pairs_are_a_slice_where_they_are_one_run():
    """A chunk's owned pairs (first turn in its core) are taken as views where they are
    one run, as with increasing turns; otherwise by index, the same pairs."""
    from fmcw_cl.chunk_checks import owned

    first = np.arange(10) * 5000.0 + 100.0
    got = owned(first, 10_000, 30_000)
    assert got == slice(2, 6) and np.array_equal(first[got], first[(first >= 10_000) & (first < 30_000)])
    shuffled = first[[0, 3, 1, 2, 9, 4]]
    got = owned(shuffled, 10_000, 30_000)
    assert np.array_equal(got, [1, 3, 5])
    assert first[owned(first, 0, 50)].size == 0                 # none owned
