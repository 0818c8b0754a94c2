"""The OpenCL backend: the resampling and the de-chirp/FFT/peak stages on a device.

Low-pass, sync and pairing stay on the host (numpy); see docs/pipeline.md.
"""

from __future__ import annotations

import numpy as np

from . import resample as k_resample
from . import spectrum as k_spectrum
from .buffers import Buffers
from .context import runtime


class OpenCLBackend:
    """Same interface as engine.NumpyBackend."""

    name = "opencl"
    programs = ("resample", "fft", "peak")

    def __init__(self, selector: str | None = None) -> None:
        self.rt = runtime(selector)
        for program in self.programs:      # build now: a failure must surface before any work
            self.rt.program(program)
        self.bufs = Buffers(self.rt)
        self.device = self.rt.name

    def resample(self, codes, starts, lengths, u, win):
        return k_resample.resample(self.rt, self.bufs, codes, starts, lengths, u, win)

    def measure(self, x, beta, v, model, lo_bin):
        d_power = k_spectrum.power_spectra(self.rt, self.bufs, x, beta, v, model.nfft)
        pk = k_spectrum.find_peaks(self.rt, self.bufs, d_power, x.shape[0], model.nfft, lo_bin)
        return pk.bin * model.metres_per_bin, pk.snr_db


def spectra(backend: OpenCLBackend, x: np.ndarray, nfft: int) -> np.ndarray:
    """Power spectra of the plain (not de-chirped) rows of x, copied back to the host."""
    import pyopencl as cl

    d = k_spectrum.power_spectra(backend.rt, backend.bufs, x, None, None, nfft)
    out = np.empty((x.shape[0], nfft // 2), np.float32)
    cl.enqueue_copy(backend.rt.queue, out, d)
    return out
