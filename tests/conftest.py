"""Shared fixtures: simulated captures made once per test session for all its workers;
the conversion the scene tests use."""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile

import pytest

# keep PoCL's kernel cache out of the user's home during tests
os.environ.setdefault("POCL_CACHE_DIR", tempfile.mkdtemp(prefix="pocl-cache-"))

from fmcw_cl.simulator import SimulationConfig, jump, simulate_capture, static  # noqa: E402


def process(path, options=None, processor=None):
    """A conversion as `fmcw-cl process` and `fmcw_cl.process` make it: on the automatic
    backend (OpenCL where a device is, numpy otherwise) unless a processor is named. The
    scene tests check what users run; tests/test_opencl.py checks that the OpenCL
    processor's decisions are the numpy reference's."""
    from fmcw_cl.backend import make_processor
    from fmcw_cl.engine import process as convert

    return convert(path, options, processor or make_processor("auto"))


def scene_of(track, path) -> list[dict]:
    """evaluate.object_scores of `track`'s objects against every truth of the capture;
    asserts that no object holds a valid pair off the truth it follows."""
    from fmcw_cl.capture import Capture
    from fmcw_cl.evaluate import object_scores

    with Capture(path) as cap:
        scores = object_scores(track, cap.truth_objects())
    assert sum(s["wrong"] for s in scores) == 0, scores
    return scores


def two_movers(path, target, other, amplitude: float, lab: bool, seed: int, start: float, span: float):
    """A capture of benchmarks/movers.py's draw (the target's trajectory, the other
    mover's at `amplitude` codes, a lab's SNR or clean) converted as a user does, and its
    objects' scores (`scene_of`: no valid pair off its own object)."""
    from dataclasses import replace

    from fmcw_cl.simulator.several import LAB_SCENE
    from fmcw_cl.simulator.writer import Mover

    cfg = replace(LAB_SCENE if lab else SimulationConfig(), movers=(Mover(other, amplitude),))
    simulate_capture(path, target, span, seed=seed, config=cfg, start_s=start)
    track = process(path)
    return track, scene_of(track, path)


def shifted_jump(off: float):
    """The jump `off` s ahead, at rest before its start: benchmarks/movers.py's second
    leg (its jump tabulated over 0.9 s, the trajectory over 0.7 s)."""
    import numpy as np

    from fmcw_cl.simulator.scene import Trajectory

    x = jump(0.9)

    def at(t, k):
        u = np.asarray(t) + off
        return np.where(u >= 0, x.at(np.maximum(u, 0.0))[k], 0.0)

    return Trajectory.from_velocity(0.0, 0.7, lambda t: at(t, 1), lambda t: at(t, 2),
                                    float(x.at(max(off, 0.0))[0]))


def bent_lut():
    """A 500-interval LUT of a 160 GHz sweep over 160-480 mA bent as ((I - 0.16) /
    0.32)^1.3, and its window: the kernels' and the tracker's test sweep."""
    import numpy as np

    from fmcw_cl.stages import resample
    from fmcw_cl.stages.lut import build_lut

    cur = np.linspace(0.16, 0.48, 50)
    lut = build_lut(cur, 190e12 + 160e9 * ((cur - 0.16) / 0.32) ** 1.3, 0.16, 0.48, 500, 1.0)
    return lut, resample.window(500)


def run_cli(*args, check=True) -> subprocess.CompletedProcess:
    """`fmcw-cl ARGS` in a subprocess, as a user runs it; asserts success unless told."""
    proc = subprocess.run([sys.executable, "-m", "fmcw_cl.cli.main", *map(str, args)],
                          capture_output=True, text=True)
    if check:
        assert proc.returncode == 0, proc.stderr
    return proc


def pytest_collection_modifyitems(items):
    """The long tests first: started last, one would keep a worker busy alone."""
    items.sort(key=lambda item: item.get_closest_marker("long") is None)


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
def capdir(tmp_path_factory, request):
    """The session's shared captures, one folder for all xdist workers: each is made
    once (`made_once`) and only read by the tests."""
    root = tmp_path_factory.getbasetemp()
    path = (root.parent if hasattr(request.config, "workerinput") else root) / "captures"
    path.mkdir(exist_ok=True)
    return path


def made_once(path, make):
    """`path`, made by `make(path)` unless a worker has made it (a lock file beside it
    keeps the others waiting meanwhile)."""
    import fcntl

    with open(path.with_name(path.name + ".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not path.exists():
            make(path)
    return path


@pytest.fixture(scope="session")
def static_capture(capdir):
    """20 ms of a static target at 0.25 m."""
    return made_once(capdir / "static.h5", lambda p: simulate_capture(p, static(0.02, 0.25), 0.02, seed=11))


@pytest.fixture(scope="session")
def jump_capture(capdir):
    """The full 300 ms jump (120 MB)."""
    return made_once(capdir / "jump.h5",
                     lambda p: simulate_capture(p, jump(0.3), 0.3, seed=3, config=SimulationConfig()))


@pytest.fixture(scope="session")
def jump_track(capdir, jump_capture):
    """The jump converted as users convert it (`process`), written as a track file."""
    from fmcw_cl.track import track_path, write_track

    return made_once(track_path(capdir, jump_capture), lambda p: write_track(p, process(jump_capture)))


def realistic(path, ground_m=0.07, seed=31, **cfg):
    """The jump at a lab's SNR (0 dB per sample at 0.3 m), with `cfg` added."""
    simulate_capture(path, jump(0.3, ground_m=ground_m), 0.3, seed=seed,
                     config=SimulationConfig(snr_db=0.0, **cfg))
    return path


@pytest.fixture(scope="session")
def wall_capture(capdir):
    """The jump at 0 dB with a static wall at 0.42 m whose echo is stronger than the
    target's in flight (800 codes against 500 at 0.3 m)."""
    return made_once(capdir / "wall.h5", lambda p: realistic(p, reflectors=((0.42, 800.0),)))
