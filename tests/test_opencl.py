"""Each OpenCL kernel against its numpy twin (PoCL in CI), and whole tracks."""

from __future__ import annotations

import numpy as np
import pytest

from fmcw_cl.engine import Options, make_backend, process
from fmcw_cl.opencl import spectrum as k_spectrum
from fmcw_cl.opencl.backend import OpenCLBackend, spectra
from fmcw_cl.stages import resample, spectrum


@pytest.fixture(scope="module")
def backend():
    return OpenCLBackend()


@pytest.mark.parametrize("sweeps,points", [(1, 1000), (777, 1000), (33, 2048), (5, 999)])
def test_resample_kernel_matches_numpy(backend, sweeps, points):
    rng = np.random.default_rng(sweeps)
    codes = rng.integers(-8192, 8192, 60_001).astype(np.int16)   # white: the hardest case
    codes[:5000] = 8191                                            # a clipped stretch
    starts = rng.uniform(2, 60_001 - 2600, sweeps)
    lengths = 2499.999 + rng.uniform(-1e-3, 1e-3, sweeps)
    u = np.sort(rng.uniform(0, 1, points))
    for uu in (u, 1 - u[::-1]):                                    # both sweep directions
        ref = resample.resample(codes, starts, lengths, uu, resample.window(points))
        got = backend.resample(codes, starts, lengths, uu, resample.window(points))
        assert got.shape == ref.shape
        assert np.abs(got - ref).max() < 0.02     # codes; float32 positions keep 1e-6 sample


@pytest.mark.parametrize("sweeps,nfft", [(1, 2048), (301, 2048), (17, 4096), (3, 64)])
def test_fft_kernel_matches_numpy(backend, sweeps, nfft):
    rng = np.random.default_rng(nfft + sweeps)
    points = nfft // 2 - 3
    x = rng.normal(0, 100, (sweeps, points))
    ref = spectrum.power_spectra(x, nfft)
    got = spectra(backend, x.astype(np.float32), nfft)
    assert np.abs(got - ref).max() <= 1e-5 * ref.max()
    beta = rng.uniform(-30, 30, points)          # de-chirp, folds of several cycles
    v = rng.uniform(-8, 8, sweeps)
    ref = spectrum.power_spectra(x * np.exp(-2j * np.pi * np.outer(v, beta)), nfft)
    d = k_spectrum.power_spectra(backend.rt, backend.bufs, x.astype(np.float32), beta, v, nfft)
    got = k_spectrum.find_peaks(backend.rt, backend.bufs, d, sweeps, nfft, 1)
    want = spectrum.find_peaks(ref, 1)
    np.testing.assert_allclose(got.bin, want.bin, atol=1e-3)
    np.testing.assert_allclose(got.snr_db, want.snr_db, atol=1e-2)


def test_peak_kernel_on_tones_and_band_edges(backend):
    nfft, points = 2048, 1000
    true_bins = np.array([40.3, 100.0, 511.75, 1000.2, 1022.6])
    j = np.arange(points)
    x = np.cos(2 * np.pi * np.outer(true_bins / nfft, j)) * resample.window(points)
    x += np.random.default_rng(1).normal(0, 0.01, x.shape)
    d = k_spectrum.power_spectra(backend.rt, backend.bufs, x.astype(np.float32), None, None, nfft)
    for lo, hi in ((30, None), (30, 700)):
        got = k_spectrum.find_peaks(backend.rt, backend.bufs, d, x.shape[0], nfft, lo, hi)
        want = spectrum.find_peaks(spectrum.power_spectra(x, nfft), lo, hi)
        np.testing.assert_allclose(got.bin, want.bin, atol=2e-3)
        np.testing.assert_allclose(got.snr_db, want.snr_db, atol=0.02)


@pytest.mark.parametrize("name", ["static_capture", "jump_capture"])
def test_opencl_track_equals_numpy_track(request, name):
    path = request.getfixturevalue(name)
    a = process(path, Options(), make_backend("numpy"))
    b = process(path, Options(), make_backend("opencl"))
    np.testing.assert_array_equal(a.valid, b.valid)
    v = a.valid
    assert np.abs(a.distance_m[v] - b.distance_m[v]).max() < 0.01e-3
    assert np.abs(a.velocity_mps[v] - b.velocity_mps[v]).max() < 1e-3
    assert b.attrs["backend"] == "opencl" and b.attrs["device"] == OpenCLBackend().device


def test_kernel_build_failure_falls_back_or_fails(monkeypatch):
    """A kernel that does not build: auto warns and takes numpy, opencl fails, and the
    build log is saved where the message says."""
    import re

    import fmcw_cl.kernels

    from fmcw_cl import engine
    from fmcw_cl.errors import FmcwError
    from fmcw_cl.opencl import context

    monkeypatch.setattr(fmcw_cl.kernels, "source", lambda name: "__kernel void broken( {")
    monkeypatch.setattr(context, "_RUNTIMES", {})            # a fresh context, no cached builds
    monkeypatch.setattr(engine, "opencl_preferred", lambda device=None: True)
    with pytest.raises(FmcwError, match=r"kernel resample\.cl failed to build on .*; build log: ") as err:
        engine.make_backend("opencl")
    log = re.search(r"build log: (\S+)", str(err.value)).group(1)
    assert "broken" in open(log).read() or "error" in open(log).read().lower()
    warnings = []
    backend = engine.make_backend("auto", warn=warnings.append)
    assert backend.name == "numpy"
    assert len(warnings) == 1 and warnings[0].startswith("warning: OpenCL unavailable (kernel resample.cl")


def test_no_opencl_platform(monkeypatch):
    from fmcw_cl import engine
    from fmcw_cl.errors import FmcwError
    from fmcw_cl.opencl import context

    monkeypatch.setattr(context, "devices", lambda: [])
    with pytest.raises(FmcwError, match="no OpenCL device found: pip install pocl-binary-distribution"):
        engine.make_backend("opencl")
    warnings = []
    assert engine.make_backend("auto", warn=warnings.append).name == "numpy"
    assert len(warnings) == 1 and "no OpenCL device found" in warnings[0]
