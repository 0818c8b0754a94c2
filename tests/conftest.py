"""Shared fixtures: small simulated captures, made once per test session."""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile

import pytest

# keep PoCL's kernel cache out of the user's home during tests
os.environ.setdefault("POCL_CACHE_DIR", tempfile.mkdtemp(prefix="pocl-cache-"))

from fmcw_cl.simulator import SimulationConfig, jump, simulate_capture, static  # noqa: E402


def run_cli(*args, check=True) -> subprocess.CompletedProcess:
    """`fmcw-cl ARGS` in a subprocess, as a user runs it; asserts success unless told."""
    proc = subprocess.run([sys.executable, "-m", "fmcw_cl.cli.main", *map(str, args)],
                          capture_output=True, text=True)
    if check:
        assert proc.returncode == 0, proc.stderr
    return proc


@pytest.fixture(params=["groups", "lanes"])
def kernel_variant(request, backend):
    """Both variants of the kernels that have two, on the test's device: work-groups
    (GPUs: `spectrum_peak`, `line_fit`, `resample`, one block or output an item) and
    explicit float8/int8 lanes or spans of work an item (CPUs: `spectrum_lanes`,
    `line_fit_lanes`, `resample_lanes`, `block_sum_span`)."""
    rt = backend.rt
    chosen = rt.lanes
    rt.lanes = request.param == "lanes"
    yield request.param
    rt.lanes = chosen


@pytest.fixture(scope="session")
def fmcw():
    return run_cli


@pytest.fixture(scope="session")
def capdir(tmp_path_factory):
    return tmp_path_factory.mktemp("captures")


@pytest.fixture(scope="session")
def static_capture(capdir):
    """20 ms of a static target at 0.25 m."""
    path = capdir / "static.h5"
    simulate_capture(path, static(0.02, 0.25), 0.02, seed=11)
    return path


@pytest.fixture(scope="session")
def jump_capture(capdir):
    """The full 300 ms jump (120 MB)."""
    path = capdir / "jump.h5"
    simulate_capture(path, jump(0.3), 0.3, seed=3, config=SimulationConfig())
    return path


@pytest.fixture(scope="session")
def jump_track(capdir, jump_capture):
    """The jump processed by the numpy backend, written as a track file."""
    from fmcw_cl.engine import process
    from fmcw_cl.track import track_path, write_track

    return write_track(track_path(capdir, jump_capture), process(jump_capture))


def realistic(path, ground_m=0.07, seed=31, **cfg):
    """The jump at a lab's SNR (0 dB per sample at 0.3 m), with `cfg` added."""
    simulate_capture(path, jump(0.3, ground_m=ground_m), 0.3, seed=seed,
                     config=SimulationConfig(snr_db=0.0, **cfg))
    return path


@pytest.fixture(scope="session")
def wall_capture(capdir):
    """The jump at 0 dB with a static wall at 0.42 m whose echo is stronger than the
    target's in flight (800 codes against 500 at 0.3 m)."""
    return realistic(capdir / "wall.h5", reflectors=((0.42, 800.0),))
