"""Launchers of kernels/fft.cl and kernels/peak.cl (twins: fmcw_cl.stages.spectrum)."""

from __future__ import annotations

import functools

import numpy as np

from ..stages.spectrum import GUARD_BINS, Peaks
from .buffers import Buffers
from .context import Runtime, cl

LOCAL = 256


@functools.lru_cache(maxsize=8)
def _tables(nfft: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Bit-reversal permutation and twiddles of an nfft-point FFT (made once per length)."""
    bits = int(np.log2(nfft))
    idx = np.arange(nfft)
    rev = np.zeros(nfft, np.int64)
    for b in range(bits):
        rev |= ((idx >> b) & 1) << (bits - 1 - b)
    m = np.arange(nfft // 2)
    tw = np.exp(-2j * np.pi * m / nfft)
    return rev.astype(np.int32), tw.real.astype(np.float32), tw.imag.astype(np.float32)


def power_spectra(rt: Runtime, bufs: Buffers, x: np.ndarray, beta: np.ndarray | None,
                  velocity: np.ndarray | None, nfft: int):
    """Device buffer of |FFT|^2 over bins 0 .. nfft/2 - 1 of the de-chirped rows of x."""
    sweeps, points = x.shape
    rev, twr, twi = _tables(nfft)
    beta = np.zeros(points) if beta is None else beta
    velocity = np.zeros(sweeps) if velocity is None else velocity
    args = [bufs.upload("x", np.asarray(x, np.float32)), np.int32(points),
            bufs.upload("beta", np.asarray(beta, np.float32)),
            bufs.upload("velocity", np.asarray(velocity, np.float32)),
            bufs.upload("bitrev", rev), bufs.upload("tw_re", twr), bufs.upload("tw_im", twi),
            np.int32(nfft)]
    d_power = bufs.get("power", 4 * sweeps * (nfft // 2))
    k = rt.kernel("fft", "dechirp_fft_power")
    k(rt.queue, (sweeps * LOCAL,), (LOCAL,), *args, d_power,
      cl.LocalMemory(4 * nfft), cl.LocalMemory(4 * nfft))
    return d_power


def find_peaks(rt: Runtime, bufs: Buffers, d_power, sweeps: int, nfft: int, lo: int,
               hi: int | None = None) -> Peaks:
    """Peaks of the spectra in a device buffer (see the numpy twin)."""
    half = nfft // 2
    hi = half if hi is None else hi
    d_bin = bufs.get("bin", 4 * sweeps)
    d_snr = bufs.get("snr", 4 * sweeps)
    k = rt.kernel("peak", "peak")
    k(rt.queue, (sweeps * LOCAL,), (LOCAL,), d_power, np.int32(half), np.int32(lo), np.int32(hi),
      np.int32(GUARD_BINS), d_bin, d_snr, cl.LocalMemory(4 * LOCAL), cl.LocalMemory(4 * LOCAL),
      cl.LocalMemory(4 * LOCAL))
    b = np.empty(sweeps, np.float32)
    s = np.empty(sweeps, np.float32)
    cl.enqueue_copy(rt.queue, b, d_bin)
    cl.enqueue_copy(rt.queue, s, d_snr)
    return Peaks(b.astype(np.float64), s)
