"""The OpenCL runtimes pip installs, made visible (vendors), and the automatic device
choice: the fastest of the devices of the first kind that pass the self-check, each
checked in a child process, the verdicts kept (choice)."""

from __future__ import annotations

import os
import platform
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest

from fmcw_cl.engine import process
from fmcw_cl.errors import FmcwError
from fmcw_cl.opencl import choice, vendors
from fmcw_cl.opencl.context import lanes_width
from fmcw_cl.options import Options
from fmcw_cl.processor import NumpyProcessor

X86_LINUX = platform.system() == "Linux" and platform.machine() == "x86_64"


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """A cache folder of the test's own."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    return tmp_path / "cache" / "fmcw-cl"


def test_a_pip_runtime_is_registered_beside_the_systems(tmp_path, cache, monkeypatch):
    system = tmp_path / "vendors"
    system.mkdir()
    (system / "pocl.icd").write_text("libpocl.so.2\n")
    lib = tmp_path / "lib" / "libintelocl.so"
    monkeypatch.setattr(vendors, "SYSTEM_VENDORS", system)
    monkeypatch.setattr(vendors, "pip_runtimes", lambda: {"intel-opencl-rt": lib})
    monkeypatch.delenv("OCL_ICD_VENDORS", raising=False)
    monkeypatch.delenv(vendors.MARK, raising=False)
    assert vendors.register() == ["intel-opencl-rt"]
    folder = os.environ["OCL_ICD_VENDORS"]
    icds = {p.name: p.read_text().strip() for p in sorted(cache.glob("icd-*/*.icd"))}
    assert icds == {"pocl.icd": "libpocl.so.2", "pip-intel-opencl-rt.icd": str(lib)}
    assert vendors.register() == ["intel-opencl-rt"] and os.environ["OCL_ICD_VENDORS"] == folder  # once
    (system / "other.icd").write_text("libother.so\n")           # a new system runtime: a new folder
    vendors.register()
    assert os.environ["OCL_ICD_VENDORS"] != folder
    monkeypatch.setenv("OCL_ICD_VENDORS", str(system))            # the user's own: left as it is
    assert vendors.register() == [] and os.environ["OCL_ICD_VENDORS"] == str(system)


@pytest.mark.skipif(not X86_LINUX, reason="intel-opencl-rt is a dependency on x86-64 Linux only")
def test_intels_runtime_from_pip_is_seen_with_no_system_opencl(tmp_path):
    """The wheel's own ICD file names a build machine's path; registered, the loader
    finds the library where pip put it, with an empty system vendors folder."""
    found = vendors.pip_runtimes()
    assert found["intel-opencl-rt"].name == "libintelocl.so" and found["intel-opencl-rt"].is_file()
    env = {k: v for k, v in os.environ.items() if k not in ("OCL_ICD_VENDORS", vendors.MARK)}
    env["XDG_CACHE_HOME"] = str(tmp_path)
    code = ("from fmcw_cl.opencl import vendors; vendors.SYSTEM_VENDORS = vendors.Path('/nonexistent'); "
            "vendors.register(); import pyopencl as cl; print([p.name for p in cl.get_platforms()])")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "Intel(R) OpenCL" in proc.stdout


@pytest.mark.parametrize("preferred,version,lanes", [
    (16, "OpenCL 3.0 PoCL HSTR: pthread-x86_64-unknown-linux-gnu-znver3", 8),     # pip's PoCL on a Zen 4
    (16, "OpenCL 3.0 PoCL HSTR: pthread-x86_64-pc-linux-gnu-skylake-avx512", 16),
    (16, "OpenCL 3.0 PoCL HSTR: cpu-x86_64-pc-linux-gnu-znver4", 16),
    (8, "OpenCL 3.0 PoCL HSTR: pthread-x86_64-pc-linux-gnu-haswell", 8),
    (1, "OpenCL 3.1 (Build 0)", 8),                                                 # Intel's CPU runtime
    (16, "OpenCL 3.0 CUDA", 16),
])
def test_lanes_are_as_wide_as_the_compiled_code(preferred, version, lanes):
    device = SimpleNamespace(preferred_vector_width_float=preferred, version=version)
    assert lanes_width(device) == lanes


@pytest.mark.parametrize("cpu,width,local_kib,nfft,lanes", [
    (True, 8, 256, 2048, 8), (True, 8, 256, 4096, 4),       # Intel's CPU runtime: the range check in 4
    (True, 8, 1024, 4096, 8), (True, 16, 1024, 4096, 16),   # pip's PoCL
    (True, 16, 256, 2048, 8), (True, 8, 256, 8192, 0),     # --points 2048's check: spectrum_peak
    (False, 8, 48, 2048, 0),                                 # a GPU: work-groups
])
def test_spectrum_lanes_as_wide_as_local_memory_holds(cpu, width, local_kib, nfft, lanes):
    from fmcw_cl.opencl import spectrum as k_spectrum

    rt = SimpleNamespace(lanes=cpu, width=width, device=SimpleNamespace(local_mem_size=local_kib * 1024))
    assert k_spectrum.lanes_of(rt, nfft) == lanes
    assert k_spectrum.uses_lanes(rt, nfft) == (lanes > 0)


def test_the_narrower_spectrum_programs_a_device_may_run_are_named():
    """opencl.spectrum.widths: the lanes other than the device's that `lanes_of` picks for
    some transform up to 8192 points, whose programs the processor builds up front."""
    from fmcw_cl.opencl import spectrum as k_spectrum

    def rt(width, kib):
        return SimpleNamespace(lanes=True, width=width, device=SimpleNamespace(local_mem_size=kib * 1024))

    assert k_spectrum.widths(rt(8, 256)) == {4}            # Intel's CPU runtime
    assert k_spectrum.widths(rt(8, 1024)) == set()         # pip's PoCL
    assert k_spectrum.widths(rt(16, 1024)) == {8}          # ... on an AVX-512 machine: 8192 points in 8


def _fake(kind: int, name: str, n: int):
    plat = SimpleNamespace(name=name, version="1.0")
    return (n, 0, plat, SimpleNamespace(platform=plat, name=f"{name} device", version="v", driver_version="d",
                                        type=kind, int_ptr=1000 + n))


def test_the_fastest_device_that_passes_is_chosen_and_the_verdicts_kept(cache, monkeypatch):
    gpu, cpu = int(choice.cl.device_type.GPU), int(choice.cl.device_type.CPU)
    seen = [_fake(cpu, "Oclgrind", 0), _fake(gpu, "Broken GPU", 1), _fake(cpu, "Slow CPU", 2),
            _fake(cpu, "Fast CPU", 3), _fake(cpu, "Crashing CPU", 4)]
    outcome = {"Broken GPU": choice.Verdict(False, "kernel x.cl failed to build"),
               "Slow CPU": choice.Verdict(True, seconds=0.30), "Fast CPU": choice.Verdict(True, seconds=0.20),
               "Crashing CPU": choice.Verdict(False, "crashed (signal 6): LLVM ERROR")}
    checked = []

    def check(selector, device, capture):
        assert capture.exists()                    # the reference capture, simulated once
        checked.append(device.platform.name)
        return outcome[device.platform.name]

    monkeypatch.setattr(choice, "devices", lambda: seen)
    monkeypatch.setattr(choice, "check", check)
    monkeypatch.setattr(choice, "REFERENCE_S", 0.002)
    monkeypatch.delenv("PYOPENCL_CTX", raising=False)
    said = []
    assert choice.select_device(say=said.append).platform.name == "Fast CPU"
    assert checked == ["Broken GPU", "Slow CPU", "Fast CPU", "Crashing CPU"]          # never the simulator
    assert any("Crashing CPU device: failed: crashed" in line for line in said)
    assert choice.select_device(say=said.append).platform.name == "Fast CPU"
    assert len(checked) == 4                                                          # kept
    assert str(choice.cached(seen[2][3])) == "passed, reference 0.300 s"
    outcome["Fast CPU"] = choice.Verdict(False, "survey: kernel and numpy twin differ")
    seen.append(_fake(cpu, "New CPU", 5))                  # another runtime installed: all checked again
    outcome["New CPU"] = choice.Verdict(True, seconds=0.5)
    assert choice.select_device(say=said.append).platform.name == "Slow CPU"
    assert len(checked) == 4 + 4
    for name in ("Slow CPU", "New CPU"):
        outcome[name] = choice.Verdict(False, "crashed (signal 11): ")
    seen.append(_fake(cpu, "Third CPU", 6))
    outcome["Third CPU"] = choice.Verdict(False, "the check took over 300 s")
    with pytest.raises(FmcwError, match=r"no OpenCL device passes the self-check \(Broken GPU / Broken GPU "
                                        r"device: kernel x\.cl failed to build; .*Third CPU device: the"):
        choice.select_device(say=said.append)
    assert choice.select_device("Fast").platform.name == "Fast CPU"       # named: used, not checked


def test_the_check_in_a_child_passes_fails_and_survives_a_crash(static_capture, tmp_path, monkeypatch):
    (p, d, _, device), *_ = [item for item in choice.devices() if choice.rank(item[3]) != choice.SIMULATOR]
    passed = choice.check(f"{p}:{d}", device, static_capture)
    assert passed.passed and 0 < passed.seconds < 60
    failed = choice.check("99:99", device, static_capture)
    assert not failed.passed and "no OpenCL device '99:99'" in failed.why
    crash = tmp_path / "crash"
    crash.write_text("#!/bin/sh\necho 'LLVM ERROR: Do not know how to scalarize' >&2\nkill -ABRT $$\n")
    crash.chmod(0o755)
    monkeypatch.setattr(sys, "executable", str(crash))
    crashed = choice.check(f"{p}:{d}", device, static_capture)
    assert not crashed.passed
    assert crashed.why == "crashed (signal 6): LLVM ERROR: Do not know how to scalarize"


def test_every_opencl_device_here_converts_as_numpy_does(static_capture):
    """Each runtime seen (PoCL, Intel's CPU runtime on x86-64 Linux, a GPU), not only
    the chosen one: the same valid pairs as numpy, distances within 0.1 um (float32
    kernels: 0.014 um seen)."""
    from fmcw_cl.opencl.processor import OpenCLProcessor

    same = Options(chunk_periods=256)
    want = process(static_capture, same, NumpyProcessor())
    runnable = [(p, d) for p, d, _, dev in choice.devices() if choice.rank(dev) != choice.SIMULATOR]
    assert runnable
    for p, d in runnable:
        got = process(static_capture, same, OpenCLProcessor(f"{p}:{d}"))
        np.testing.assert_array_equal(got.valid, want.valid)
        assert np.abs(got.distance_m - want.distance_m)[want.valid].max() < 1e-7
