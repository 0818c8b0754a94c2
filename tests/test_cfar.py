"""The CFAR echo detector: its numpy twin on known tones and on noise, and the kernel."""

from __future__ import annotations

import numpy as np
import pytest

from fmcw_cl.opencl import spectrum as k_spectrum
from fmcw_cl.stages import cfar, resample, spectrum

NFFT, POINTS, LO = 2048, 1000, 64


def tones(bins_amps, rows=40, noise=1.0, seed=0):
    """Windowed rows of real tones at (padded bin, amplitude) in white noise."""
    rng = np.random.default_rng(seed)
    j = np.arange(POINTS)
    x = rng.normal(0, noise, (rows, POINTS))
    for b, a in bins_amps:
        x += a * np.cos(2 * np.pi * b / NFFT * j + rng.uniform(0, 2 * np.pi, (rows, 1)))
    return x * resample.window(POINTS)


def test_finds_every_echo_nearest_first():
    # a strong near echo, a weak far one 25 dB below it, and one at the band's top
    x = tones([(150.3, 40.0), (700.6, 2.2), (1010.0, 8.0)])
    det = cfar.detect(spectrum.power_spectra(x, NFFT), LO)
    assert (det.count == 3).all()
    np.testing.assert_allclose(det.bin[:, :3].mean(axis=0), [150.3, 700.6, 1010.0], atol=0.05)
    assert (det.snr_db[:, 0] > det.snr_db[:, 1]).all()
    assert np.isnan(det.bin[:, 3:]).all()


def test_band_limits_and_no_echo():
    x = tones([(150.3, 40.0), (700.6, 10.0)])
    power = spectrum.power_spectra(x, NFFT)
    det = cfar.detect(power, 300, 600)          # neither echo inside the band
    assert (det.count == 0).all()
    det = cfar.detect(power, 300)               # the far one only
    assert (det.count == 1).all() and np.allclose(det.bin[:, 0], 700.6, atol=0.05)
    # an echo just above the band's first bin: training cells come from one side only
    det = cfar.detect(spectrum.power_spectra(tones([(LO + 3.2, 20.0)]), NFFT), LO)
    assert (det.count >= 1).all() and np.allclose(det.bin[:, 0], LO + 3.2, atol=0.1)


def test_false_alarm_rate_on_noise():
    """The stated rate: about 6e-6 false echoes per bin on white noise (2x padding)."""
    power = spectrum.power_spectra(tones([], rows=4000, seed=3), NFFT)
    det = cfar.detect(power, LO)
    rate = det.count.sum() / (power.shape[0] * (NFFT // 2 - LO))
    assert rate < 2e-5
    assert cfar.scales()[2 * cfar.TRAIN] == pytest.approx(16 * (1e-6 ** (-1 / 16) - 1))


def test_keeps_the_nearest_max_echoes():
    x = tones([(100 + 60 * k + 0.3, 30.0) for k in range(cfar.MAX_ECHOES + 3)], rows=5)
    det = cfar.detect(spectrum.power_spectra(x, NFFT), LO)
    assert (det.count == cfar.MAX_ECHOES).all()
    np.testing.assert_allclose(det.bin[0], 100.3 + 60 * np.arange(cfar.MAX_ECHOES), atol=0.05)


@pytest.fixture(scope="module")
def backend():
    from fmcw_cl.opencl.processor import OpenCLProcessor

    return OpenCLProcessor()


@pytest.mark.parametrize("rows,nfft,lo,hi", [(41, 2048, LO, None), (40, 2048, 200, 900), (7, 4096, 130, None),
                                             (1, 2048, LO, None)])
def test_kernel_matches_numpy(backend, kernel_variant, rows, nfft, lo, hi):
    """Several echoes (one at the band's top bins), noise-only rows, odd row counts
    (plain rows go two to a transform), both FFT shapes."""
    points = nfft // 2 - 24
    rng = np.random.default_rng(rows + nfft)
    j = np.arange(points)
    x = rng.normal(0, 1.0, (rows, points))
    for b, a in ((0.09, 30.0), (0.31, 3.0), (0.4985, 6.0)):
        x[::2] += a * np.cos(2 * np.pi * b * j + rng.uniform(0, 6, (x[::2].shape[0], 1)))
    x *= resample.window(points)
    want = cfar.detect(spectrum.power_spectra(x, nfft), lo)     # echoes ignore the band's top
    _, _, got = k_spectrum.measure(backend.rt, backend.bufs, x.astype(np.float32), None, None, nfft, lo, hi,
                                   echoes=True)
    np.testing.assert_array_equal(got.count, want.count)
    assert want.count[::2].min() >= 1      # the tone rows have echoes in every band tried
    np.testing.assert_allclose(got.bin, want.bin, atol=2e-3)
    np.testing.assert_allclose(got.snr_db, want.snr_db, atol=0.02)


def test_kernel_with_other_widths_matches_numpy(backend, kernel_variant, monkeypatch):
    """Guard and training widths other than the tables' (8 and 16) take the kernels'
    direct sums everywhere."""
    monkeypatch.setattr(cfar, "GUARD", 5)
    monkeypatch.setattr(cfar, "TRAIN", 11)
    monkeypatch.setattr(k_spectrum, "cfar_scales", cfar.scales)
    x = tones([(150.3, 40.0), (170.6, 4.0), (700.6, 2.2), (1020.0, 8.0)], rows=9, seed=4)
    want = cfar.detect(spectrum.power_spectra(x, NFFT), LO)
    _, _, got = k_spectrum.measure(backend.rt, backend.bufs, x.astype(np.float32), None, None, NFFT, LO,
                                   echoes=True)
    assert want.count.min() >= 3
    np.testing.assert_array_equal(got.count, want.count)
    np.testing.assert_allclose(got.bin, want.bin, atol=2e-3)
