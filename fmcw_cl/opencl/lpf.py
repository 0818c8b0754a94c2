"""Launcher of kernels/lpf.cl (twin: fmcw_cl.stages.lpf.intensity_each)."""

from __future__ import annotations

import functools

import numpy as np

from ..stages import lpf
from .buffers import Buffers, Packed
from .context import Runtime


@functools.lru_cache(maxsize=4)
def cic_taps(factor: int, order: int = lpf.CIC_ORDER) -> np.ndarray:
    """Impulse response of `order` cascaded boxcars of `factor` samples (float32)."""
    h = np.ones(1)
    for _ in range(order):
        h = np.convolve(h, np.full(factor, 1.0 / factor))
    return h.astype(np.float32)


@functools.lru_cache(maxsize=4)
def fir_taps(sample_rate_hz: float) -> np.ndarray:
    """The low-pass FIR at the decimated rate (float32), the same object each time."""
    return lpf.lowpass_taps(sample_rate_hz).astype(np.float32)


def intensity_each(rt: Runtime, bufs: Buffers, channels: list, sample_rate_hz: float,
                   factor: int = lpf.DECIMATION) -> list[tuple[np.ndarray, float, float]]:
    """Low-passed int16 codes at the decimated rate of each array of `channels` (the
    beat and the sync), of each row alone where one is (rows, samples), all rows in one
    launch a kernel; every result back by one download (twin: lpf.intensity_each)."""
    out, shapes = launch(rt, bufs, channels, sample_rate_hz, factor)
    views = out.download() if any(v.size for v in out.views) else out.views
    return [(view.reshape(shape).astype(np.float64), lpf.CIC_ORDER * (factor - 1) / 2.0, float(factor))
            for view, shape in zip(views, shapes, strict=True)]


def launch(rt: Runtime, bufs: Buffers, channels: list, sample_rate_hz: float, factor: int = lpf.DECIMATION
           ) -> tuple[Packed, list[tuple]]:
    """`intensity_each`'s launches: the low-passed rows of each channel in a part of a
    Packed, not yet downloaded, and their shapes."""
    if any(x.dtype != np.int16 for x in channels):
        raise TypeError("the low-pass kernel takes int16 ADC codes")
    h = cic_taps(factor)
    taps = fir_taps(sample_rate_hz / factor)
    shapes = [(*x.shape[:-1], lpf.outputs(x.shape[-1], factor)) for x in channels]
    out = Packed(bufs, "lpf_out", [(np.float32, int(np.prod(shape))) for shape in shapes])
    for i, (x, view, d_out) in enumerate(zip(channels, out.views, out.buffers, strict=True)):
        if not view.size:
            continue
        rows, m = x.shape[0] if x.ndim == 2 else 1, shapes[i][-1]
        d_dec = bufs.get("lpf_decimated", view.nbytes)      # read by the next launch alone
        rt.kernel("lpf", "cic_decimate")(rt.queue, *rt.items(view.size), bufs.upload_once(f"lpf_in{i}", x),
                                         bufs.constant("lpf_cic", h), np.int32(h.size), np.int32(factor),
                                         np.int32(m), np.int32(rows), np.int32(x.shape[-1]), d_dec)
        rt.kernel("lpf", "fir_same")(rt.queue, *rt.items(view.size), d_dec, np.int32(m), np.int32(rows),
                                     bufs.constant("lpf_taps", taps), np.int32(taps.size // 2), d_out)
    return out, shapes
