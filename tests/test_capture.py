"""Capture files: round trip, chunked reads, validation of malformed layouts."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

from fmcw_cl.capture import Capture
from fmcw_cl.capture_format import Modulation
from fmcw_cl.capture_writer import CaptureWriter
from fmcw_cl.errors import CaptureError

MOD = Modulation(20e3, 0.16, 0.48)
TABLE_I = np.linspace(0.02, 0.5, 25)
TABLE_F = 193.6e12 - 4e11 * TABLE_I


def write(path, samples=23_457, seed=0):
    rng = np.random.default_rng(seed)
    beat = rng.integers(-8192, 8192, samples, dtype=np.int16)
    sync = rng.integers(-8192, 8192, samples, dtype=np.int16)
    with CaptureWriter(path, samples, 1e8, 14, MOD, TABLE_I, TABLE_F, refractive_index=1.0003) as w:
        w.write(0, beat[:10_000], sync[:10_000])
        w.write(10_000, beat[10_000:], sync[10_000:])
    return beat, sync


def test_round_trip(tmp_path):
    path = tmp_path / "c.h5"
    beat, sync = write(path)
    with Capture(path) as cap:
        info = cap.info
        assert info.samples == beat.size
        assert info.sample_rate_hz == 1e8 and info.bits == 14
        assert info.modulation == MOD
        assert info.refractive_index == pytest.approx(1.0003)
        np.testing.assert_array_equal(info.tuning_current_a, TABLE_I)
        b, s = cap.read(0, info.samples)
        np.testing.assert_array_equal(b, beat)
        np.testing.assert_array_equal(s, sync)
        b, s = cap.read(1234, 5678)
        np.testing.assert_array_equal(b, beat[1234:5678])
    assert not (tmp_path / "c.h5.part").exists()


@pytest.mark.parametrize("periods,margin", [(1, 0), (3, 17), (2, 4999)])
def test_chunks_cover_capture_exactly(tmp_path, periods, margin):
    path = tmp_path / "c.h5"
    beat, sync = write(path, samples=23_457)  # 4.69 periods: the last one partial
    with Capture(path) as cap:
        cores, n = [], 0
        for ch in cap.chunks(periods=periods, margin=margin):
            assert ch.start == max(0, ch.core_start - margin)
            np.testing.assert_array_equal(ch.beat, beat[ch.start:ch.stop])
            np.testing.assert_array_equal(ch.sync, sync[ch.start:ch.stop])
            cores.append(beat[ch.core_start:ch.core_stop])
            assert ch.core_start == n
            n = ch.core_stop
        np.testing.assert_array_equal(np.concatenate(cores), beat)


def test_interrupted_writer_leaves_nothing(tmp_path):
    path = tmp_path / "c.h5"
    with pytest.raises(RuntimeError), CaptureWriter(path, 100, 1e8, 14, MOD, TABLE_I, TABLE_F):
        raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []


def _mutations():
    def drop(name):
        return lambda f: f.__delitem__(name)

    def attr(obj, name, value):
        def m(f):
            f[obj].attrs[name] = value
        return m

    def table(values=None, currents=None):
        def m(f):
            if values is not None:
                del f["laser/tuning_frequency_hz"]
                f["laser/tuning_frequency_hz"] = values
            if currents is not None:
                del f["laser/tuning_current_a"]
                f["laser/tuning_current_a"] = currents
        return m

    def resize_sync(f):
        del f["adc/sync"]
        f["adc/sync"] = np.zeros(100, np.int16)

    nan_table = TABLE_F.copy()
    nan_table[3] = np.nan
    return [
        (lambda f: f.attrs.__delitem__("fmcw_format"), "not a capture"),
        (attr("/", "fmcw_format", "track"), "not a capture"),
        (drop("adc/beat"), "missing dataset adc/beat"),
        (drop("adc/sync"), "missing dataset adc/sync"),
        (resize_sync, "samples but /adc/sync has"),
        (attr("adc", "sample_rate_hz", -5.0), "sample_rate_hz"),
        (lambda f: f["adc"].attrs.__delitem__("sample_rate_hz"), "missing attribute"),
        (attr("modulation", "waveform", "sine"), "not supported"),
        (attr("modulation", "frequency_hz", 0.0), "frequency_hz"),
        (attr("modulation", "current_min_a", 0.5), "not below"),
        (table(values=nan_table), "NaN"),
        (table(currents=TABLE_I[::-1].copy()), "not strictly increasing"),
        (table(currents=np.linspace(0.2, 0.5, 25)), "does not cover"),
    ]


@pytest.mark.parametrize("mutate,message", _mutations())
def test_malformed_captures_are_named_and_explained(tmp_path, mutate, message):
    path = tmp_path / "bad.h5"
    write(path)
    with h5py.File(path, "a") as f:
        mutate(f)
    with pytest.raises(CaptureError) as err:
        Capture(path)
    assert str(err.value).startswith(str(path))
    assert message in str(err.value)


def test_not_hdf5_and_too_short(tmp_path):
    junk = tmp_path / "junk.h5"
    junk.write_bytes(b"not an hdf5 file at all" * 10)
    with pytest.raises(CaptureError, match="not a readable HDF5 file"):
        Capture(junk)
    short = tmp_path / "short.h5"
    write(short, samples=9_000)  # fewer than two 5000-sample periods
    with pytest.raises(CaptureError, match="too short"):
        Capture(short)


def test_chunks_in_reused_slots_hold_the_same_samples(static_capture):
    """Chunks read into a ring of two slots: every chunk's samples as a fresh read, the
    last (partial) one too, and chunk i + 2 in chunk i's memory."""
    with Capture(static_capture) as cap:
        fresh = list(cap.chunks(150, margin=777))
        seen = []
        for i, chunk in enumerate(cap.chunks(150, margin=777, slots=2)):
            want = fresh[i]
            where = (chunk.start, chunk.core_start, chunk.core_stop)
            assert where == (want.start, want.core_start, want.core_stop)
            np.testing.assert_array_equal(chunk.beat, want.beat)
            np.testing.assert_array_equal(chunk.sync, want.sync)
            seen.append(chunk.beat.base if chunk.beat.base is not None else chunk.beat)
        assert len(fresh) >= 3 and fresh[-1].beat.size < fresh[0].beat.size
        assert seen[2] is seen[0] and seen[1] is not seen[0]


def test_held_chunks_lie_end_to_end_in_a_pooled_slot_of_their_own(static_capture):
    """Held chunks (the delay refinement's trial stretches): every chunk of each range
    as a fresh read, their codes end to end in the slot HELD_SLOT (each chunk's
    arrays views into it, where its offset says), none sharing memory with the
    read-ahead's slots 0 and 1; a range that ends before the capture does, one that
    starts in it and one past its end."""
    from fmcw_cl.chunks import HELD_SLOT, held_end_to_end, margin_samples
    from fmcw_cl.options import Options

    with Capture(static_capture) as cap:
        ring = [a for i in (0, 1) for a in cap.slot(i, 10)]
        opts = Options(chunk_periods=20)
        n = cap.info.samples
        ranges = [(1000, 400_000), (n - 150_000, n), (n + 10, n + 500)]
        beat, chunks, offsets, which = held_end_to_end(cap, opts, ranges)
        fresh = [(k, c) for k, (a, b) in enumerate(ranges)
                 for c in cap.chunks(20, margin=margin_samples(cap.info, opts), start=a, stop=b)]
        assert len(chunks) == len(fresh) >= 4 and which == [k for k, _ in fresh] and 2 not in which
        assert beat.size == sum(c.beat.size for c in chunks)
        assert np.shares_memory(beat, cap.slot(HELD_SLOT, 1)[0])
        for got, (_, want), at in zip(chunks, fresh, offsets, strict=True):
            assert (got.start, got.core_start, got.core_stop) == (want.start, want.core_start, want.core_stop)
            np.testing.assert_array_equal(got.beat, want.beat)
            np.testing.assert_array_equal(got.sync, want.sync)
            np.testing.assert_array_equal(beat[at: at + got.beat.size], want.beat)
            assert np.shares_memory(got.beat, beat) and not np.shares_memory(got.beat, got.sync)
        assert not any(np.shares_memory(x, a) for c in chunks for x in (c.beat, c.sync) for a in ring)


def test_slots_return_to_the_pool_for_the_next_capture(static_capture, monkeypatch):
    """A closed capture's slots serve the next capture (memory touched once per process);
    two open captures never share one; the pool keeps at most its limit, largest first."""
    from fmcw_cl import pool

    pool.clear()

    def owner(a):
        return a.base if a.base is not None else a

    with Capture(static_capture) as a, Capture(static_capture) as b:
        sa, sb = a.slot(0, 5000), b.slot(0, 5000)
        assert not np.shares_memory(sa[0], sb[0]) and not np.shares_memory(sa[0], sa[1])
        first = owner(sa[0])
        assert owner(a.slot(0, 4000)[0]) is first           # a smaller request keeps the slot
        grown = owner(a.slot(0, 9000)[0])                   # a larger one borrows anew ...
        assert grown is not first and grown.size == 9000
    with Capture(static_capture) as c:
        assert owner(c.slot(0, 8000)[0]) is grown            # ... and the smallest that fits is lent
        beat, sync = c.read_into(0, 8000, *c.slot(1, 8000))
        fresh = c.read(0, 8000)
        np.testing.assert_array_equal(beat, fresh[0])
        np.testing.assert_array_equal(sync, fresh[1])
    monkeypatch.setattr(pool, "LIMIT_BYTES", 3 * 9000 * 2)
    pool.give(np.empty(100, np.int16))
    kept = sorted(a.size for a in pool._free)
    assert sum(2 * n for n in kept) <= pool.LIMIT_BYTES and kept[-1] == 9000
    pool.clear()
    assert pool.lease(10).size == 10 and not pool._free


def test_page_locked_slots_are_kept_for_the_next_captures(static_capture, monkeypatch):
    """Memory of the pool's allocator (a GPU's page-locked memory, costly to make) is
    kept beyond the plain limit, so that two captures at once take theirs back from
    the pool rather than making it again; an allocator that fails leaves np.empty."""
    from fmcw_cl import pool

    made = []

    def allocate(samples):
        made.append(samples)
        return np.empty(samples, np.int16)

    monkeypatch.setattr(pool, "LIMIT_BYTES", 2 * 9000 * 2)        # two slots' worth
    monkeypatch.setattr(pool, "KEEP_PAGE_LOCKED_BYTES", 6 * 9000 * 2)
    pool.use(allocate)
    try:
        for _ in range(3):
            with Capture(static_capture) as a, Capture(static_capture) as b:
                for cap in (a, b):
                    cap.slot(0, 9000)
        assert len(made) == 4                  # the first two captures' slots, made once
        pool.use(None)                         # np.empty again: the kept ones let go
        assert not pool._free

        def none_left(samples):
            raise MemoryError("out of page-locked memory")

        pool.use(none_left)
        got = pool.lease(1234)
        assert got.size == 1234 and got.dtype == np.int16 and got.base is None
    finally:
        pool.use(None)
        pool.clear()


def _relayout(path, tmp_path, layout):
    """The capture at `path` with both channels stored in `layout`; whether the samples
    are then read straight from the file (fmcw_cl.extents) or through h5py."""
    with h5py.File(path, "r") as f:
        beat, sync = f["adc/beat"][()], f["adc/sync"][()]
    if layout == "user block":
        moved = tmp_path / "ub.h5"
        with h5py.File(path, "r") as src, h5py.File(moved, "w", userblock_size=512) as dst:
            for k, v in src.attrs.items():
                dst.attrs[k] = v
            for name in src:
                src.copy(name, dst)
        moved.replace(path)
        return False
    raw = {"contiguous": {}, "odd chunks": {"chunks": (4097,)},
           "chunks written backwards": {"chunks": (1000,)}}
    kinds = {**raw, "gzip": {"chunks": (5000,), "compression": "gzip"},
             "big-endian": {"dtype": ">i2"}, "int32": {"dtype": np.int32},
             "chunks not all written": {"chunks": (1000,)}, "external": {}, "virtual": {}}
    with h5py.File(path, "a") as f:
        for name, data in (("beat", beat), ("sync", sync)):
            attrs = dict(f["adc"][name].attrs)
            del f["adc"][name]
            if layout == "external":              # the samples in a raw file beside it
                side = tmp_path / f"{name}.raw"
                data.astype("<i2").tofile(side)
                ds = f["adc"].create_dataset(name, data.shape, "<i2", external=[(str(side), 0, data.nbytes)])
            elif layout == "virtual":             # a view of another dataset
                src = f.create_dataset(f"src_{name}", data=data)
                view = h5py.VirtualLayout(shape=data.shape, dtype=np.int16)
                view[:] = h5py.VirtualSource(src)
                ds = f["adc"].create_virtual_dataset(name, view)
            else:
                ds = f["adc"].create_dataset(name, data.shape, **{"dtype": np.int16, **kinds[layout]})
            if layout == "chunks written backwards":
                for a in range(data.size // 1000 * 1000, -1, -1000):
                    ds[a: a + 1000] = data[a: a + 1000]
            elif layout == "chunks not all written":
                ds[:3000] = data[:3000]              # the rest: HDF5's fill value, 0
            elif layout not in ("external", "virtual"):
                ds[...] = data
            for k, v in attrs.items():
                ds.attrs[k] = v
    return layout in raw


@pytest.mark.parametrize("layout", ["contiguous", "odd chunks", "chunks written backwards", "gzip",
                                    "big-endian", "int32", "chunks not all written", "user block", "external",
                                    "virtual"])
@pytest.mark.parametrize("piece", [None, 1000])
def test_every_layout_reads_the_same_samples(tmp_path, layout, piece, monkeypatch):
    """Raw int16 channels are read straight from the file (fmcw_cl.extents), any other
    layout through h5py; either way every range holds what h5py reads there, a read of
    several pieces (`piece` bytes, three threads) too, and so do all the ranges read at
    once (`read_spans`, a plan's stretches)."""
    from fmcw_cl import extents

    if piece:
        monkeypatch.setattr(extents, "PIECE_BYTES", piece)
        monkeypatch.setattr(extents, "READERS", 3)
    path = tmp_path / "c.h5"
    write(path, samples=23_457)
    direct = _relayout(path, tmp_path, layout)
    rng = np.random.default_rng(7)
    ranges = [(0, 1), (999, 1001), (4096, 4098), (0, 23_457), (23_450, 23_500)]
    ranges += [tuple(sorted(rng.integers(0, 23_457, 2))) for _ in range(20)]
    with Capture(path) as cap, h5py.File(path, "r") as f:
        assert [e is not None for e in cap._extents] == [direct, direct]
        for a, b in ranges:
            beat, sync = cap.read(a, b)
            np.testing.assert_array_equal(beat, f["adc/beat"][a:b].astype(np.int64).clip(-32768, 32767))
            np.testing.assert_array_equal(sync, f["adc/sync"][a:b].astype(np.int64).clip(-32768, 32767))
        spans = [*ranges, (23_000, 24_000)]                     # the last one past the end
        beats, syncs = ([np.full(b - a, -7, np.int16) for a, b in spans] for _ in range(2))
        got = cap.read_spans(spans, beats, syncs)
        for (a, b), (beat, sync), whole in zip(spans, got, beats, strict=True):
            assert beat.base is whole                        # views of the arrays given
            np.testing.assert_array_equal(beat, f["adc/beat"][a:b].astype(np.int64).clip(-32768, 32767))
            np.testing.assert_array_equal(sync, f["adc/sync"][a:b].astype(np.int64).clip(-32768, 32767))
        assert (beats[-1][457:] == -7).all()                 # nothing written past the file


@pytest.mark.parametrize("layout", ["contiguous", "odd chunks", "chunks written backwards", "gzip",
                                    "big-endian", "chunks not all written", "external"])
def test_chunks_read_in_place_hold_the_samples_of_every_layout(tmp_path, layout):
    """A capture opened in place gives its chunk reader's chunks as read-only views of the
    file's pages where each channel lies raw in one run of the file (always so for a
    contiguous dataset, never for chunks written backwards), else reads them into its
    slots; either way every chunk holds what h5py reads there, the last, partial one
    too."""
    path = tmp_path / "c.h5"
    write(path, samples=23_457)
    direct = _relayout(path, tmp_path, layout)
    with Capture(path, in_place=True) as cap, h5py.File(path, "r") as f:
        one_run = direct and all(e.file_offset() is not None for e in cap._extents)
        assert one_run == (cap._mapped is not None)
        assert one_run or layout != "contiguous"
        assert not one_run or layout != "chunks written backwards"
        ends = []
        for chunk in cap.chunks(1, margin=1234, slots=2):      # a ring of two: each before the next
            a, b = chunk.start, chunk.stop
            ends.append(chunk.core_stop)
            np.testing.assert_array_equal(chunk.beat, f["adc/beat"][a:b].astype(np.int64).clip(-32768, 32767))
            np.testing.assert_array_equal(chunk.sync, f["adc/sync"][a:b].astype(np.int64).clip(-32768, 32767))
            assert chunk.beat.flags.writeable != one_run and chunk.sync.flags.writeable != one_run
        assert len(ends) == 5 and ends[-1] == 23_457


def test_capture_writer_stores_raw_channels_in_one_run_each(tmp_path):
    """Uncompressed, each channel is one run of the file, which a capture opened in place
    maps; compressed, chunks, which it reads."""
    path = tmp_path / "c.h5"
    write(path)
    with h5py.File(path, "r") as f:
        assert f["adc/beat"].chunks is None and f["adc/sync"].chunks is None
    packed = tmp_path / "z.h5"
    with CaptureWriter(packed, 23_457, 1e8, 14, MOD, TABLE_I, TABLE_F, compression="gzip") as w:
        w.write(0, *write(path))
    with Capture(path, in_place=True) as raw, Capture(packed, in_place=True) as gz:
        assert raw._mapped is not None and gz._mapped is None


def test_a_file_cut_after_opening_in_place_fails_its_chunk(tmp_path):
    """A capture opened in place whose file is cut before a chunk is reached: a one-line
    error naming the file and the chunk's samples (a touch of the lost pages would end
    the process), the chunks before it whole."""
    path = tmp_path / "c.h5"
    beat, _ = write(path, samples=23_457)
    with Capture(path, in_place=True) as cap:
        assert cap._mapped is not None
        chunks = cap.chunks(1, slots=2)
        np.testing.assert_array_equal(next(chunks).beat, beat[:5000])
        with open(path, "r+b") as f:
            f.truncate(max(cap._map_offsets) + 2 * 7000)       # the later channel's samples 7000 on
        with pytest.raises(CaptureError, match=r"c\.h5: cannot read samples 5000-10000 \(the file ends"):
            list(chunks)


@pytest.mark.parametrize("piece", [None, 1000])
def test_a_file_cut_after_opening_fails_its_read(tmp_path, piece, monkeypatch):
    """A raw channel whose bytes are gone (the file cut after it was opened) is a
    one-line error naming the file and the samples, not short data, also where the
    read is shared by threads (`piece` bytes a piece)."""
    from fmcw_cl import extents

    if piece:
        monkeypatch.setattr(extents, "PIECE_BYTES", piece)
        monkeypatch.setattr(extents, "READERS", 3)
    path = tmp_path / "c.h5"
    write(path, samples=23_457)
    with Capture(path) as cap:
        assert cap._extents[0] is not None
        size = path.stat().st_size
        with open(path, "r+b") as f:
            f.truncate(size // 2)
        with pytest.raises(CaptureError, match=r"c\.h5: cannot read samples 0-23457 \(the file ends"):
            cap.read(0, 23_457)
        spans = [(0, 5000), (9000, 23_457)]
        with pytest.raises(CaptureError, match=r"c\.h5: cannot read samples 0-23457 \(the file ends"):
            cap.read_spans(spans, *([np.empty(b - a, np.int16) for a, b in spans] for _ in range(2)))


def test_extents_by_a_query_a_chunk_equal_the_index_walk(tmp_path):
    """Where HDF5 cannot walk a chunk index (chunk_iter: HDF5 >= 1.12.3), each chunk is
    queried alone: the same extents, chunks written backwards included."""
    from fmcw_cl.extents import Extents

    class NoWalk:
        """A dataset (or its id) whose id cannot walk its chunks."""

        def __init__(self, inner, top=True) -> None:
            self.inner, self.top = inner, top

        def __getattr__(self, name):
            if name == "chunk_iter" and not self.top:
                raise AttributeError(name)
            got = getattr(self.inner, name)
            return NoWalk(got, False) if name == "id" else got

    path = tmp_path / "c.h5"
    write(path, samples=23_457)
    _relayout(path, tmp_path, "chunks written backwards")
    with h5py.File(path, "r") as f:
        walked, queried = Extents.of(f["adc/beat"]), Extents.of(NoWalk(f["adc/beat"]))
    assert walked is not None and queried is not None and walked.starts.size == 24
    np.testing.assert_array_equal(walked.starts, queried.starts)
    np.testing.assert_array_equal(walked.offsets, queried.offsets)
