"""Batch conversion on a Dask LocalCluster of 2 workers: tracks equal the local run's,
long captures split into ranges and stitched, a killed worker's tasks rescheduled."""

from __future__ import annotations

import os
import signal
import time

import numpy as np
import pytest

from fmcw_cl.cluster import connect, run_batch
from fmcw_cl.engine import process
from fmcw_cl.options import Options
from fmcw_cl.simulator import simulate_capture, static
from fmcw_cl.track import read_track

OPTIONS = Options(chunk_periods=500, context_periods=16)   # 25 ms chunks: several per capture


@pytest.fixture(scope="module")
def client():
    c = connect("local:2")
    yield c
    c.close()
    c.cluster.close()


@pytest.fixture(scope="module")
def batch(tmp_path_factory):
    d = tmp_path_factory.mktemp("batch")
    paths = []
    for k, r in enumerate((0.12, 0.2, 0.33, 0.41)):
        p = d / f"s{k}.h5"
        simulate_capture(p, static(0.03, r), 0.03, seed=40 + k)
        paths.append(p)
    long = d / "long.h5"
    simulate_capture(long, static(0.1, 0.27), 0.1, seed=50)
    return paths, long


def assert_same(track_file, local):
    got = read_track(track_file)
    np.testing.assert_array_equal(got.valid, local.valid)
    np.testing.assert_array_equal(got.reason, local.reason)
    np.testing.assert_allclose(got.time_s, local.time_s, rtol=0, atol=1e-12)
    np.testing.assert_allclose(got.distance_m, local.distance_m, rtol=0, atol=1e-12)
    np.testing.assert_allclose(got.velocity_mps, local.velocity_mps, rtol=0, atol=1e-9)
    np.testing.assert_allclose(got.sweep_distance_m, local.sweep_distance_m, rtol=0, atol=1e-12)


def test_many_captures_and_a_bad_one(client, batch, tmp_path):
    paths, _ = batch
    bad = tmp_path / "bad.h5"
    bad.write_bytes(b"not hdf5")
    out = tmp_path / "out"
    out.mkdir()
    got = {r["capture"]: r for r in run_batch(client, [*paths, bad], out, OPTIONS, "numpy")}
    assert "not a readable HDF5 file" in got[str(bad)]["error"]
    for p in paths:
        assert "error" not in got[str(p)]
        assert_same(got[str(p)]["track"], process(p, OPTIONS))
    assert not list(out.glob("*.part"))


def test_long_capture_split_into_ranges(client, batch, tmp_path):
    _, long = batch
    out = tmp_path / "out"
    out.mkdir()
    done = []
    (res,) = run_batch(client, [long], out, OPTIONS, "numpy", split_seconds=0.05, task_seconds=0.05,
                       progress=lambda d, n, fs: done.append((d, n, fs)))
    local = process(long, OPTIONS)
    assert_same(res["track"], local)
    assert local.valid.all() and done == [(10_000_000, 10_000_000, 100e6)]   # 0.1 s, once


def test_killed_worker_is_rescheduled(client, batch, tmp_path):
    paths, _ = batch
    out = tmp_path / "out"
    out.mkdir()
    results = run_batch(client, paths, out, OPTIONS, "numpy")
    # kill a worker while it is converting
    deadline = time.time() + 30
    while time.time() < deadline:
        busy = [w for w, tasks in client.processing().items() if tasks]
        if busy:
            break
        time.sleep(0.05)
    assert busy, "no task ever ran"
    time.sleep(0.3)
    pid = client.run(os.getpid, workers=busy[:1])[busy[0]]
    os.kill(pid, signal.SIGKILL)                   # the nanny restarts it; its task is retried
    got = {r["capture"]: r for r in results}
    for p in paths:
        assert "error" not in got[str(p)], got[str(p)]
        assert_same(got[str(p)]["track"], process(p, OPTIONS))
    assert sorted(x.name for x in out.iterdir()) == sorted(f"{p.stem}.track.h5" for p in paths)


def test_local_workers_start_with_the_allocator_settings(client):
    """Dask's MALLOC_TRIM_THRESHOLD_=65536 slowed a conversion 1.6x; local workers get
    heap reuse instead (glibc reads these at process start, hence pre-spawn)."""
    seen = client.run(lambda: (os.environ.get("MALLOC_TRIM_THRESHOLD_"),
                               os.environ.get("MALLOC_MMAP_THRESHOLD_")))
    assert set(seen.values()) == {(str(256 << 20), str(32 << 20))}
