"""Launcher of kernels/integrate.cl, or of integrate_lanes.cl on CPU devices (twin:
fmcw_cl.stages.integrate.peaks)."""

from __future__ import annotations

import numpy as np

from ..stages.groups import group_bounds
from ..stages.integrate import window
from ..stages.spectrum import GUARD_BINS, Search
from .buffers import Buffers, DeviceRows, Packed
from .context import Runtime, cl
from .spectrum import band_buffers, zeros


def peaks(rt: Runtime, bufs: Buffers, store: DeviceRows, disp: np.ndarray, k: int, search: Search,
          bounds: np.ndarray | None = None, direction: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(bin, SNR dB, count) of the tracked peak of each row's K-window integrated
    spectrum; `store` holds the power spectra (rows, nfft/2) on the device, `disp` each
    row's target displacement in bins, `bounds` each row's group's first and last row
    (None: one group); in `direction`'s bands (0: rising, 1: falling) where the search
    has them."""
    rows, half = store.shape
    if rows == 0:
        return np.zeros(0), np.zeros(0, np.float32), np.zeros(0, np.int32)
    bounds = group_bounds(None, rows) if bounds is None else bounds
    # relative to the first row: float32 keeps 1e-4 bin over a chunk's displacement
    d_disp, d_bounds = Packed(bufs, "disp", [(np.float32, rows), (np.int32, 2 * rows)]).upload(
        np.asarray(disp - disp[0], np.float32), bounds)
    out = Packed(bufs, "integrated", [(np.float32, rows), (np.float32, rows), (np.int32, rows)])
    launch(rt, bufs, [(store, *out.buffers)], d_disp, d_bounds, k, search,
           bufs.constant("state0", zeros(2), np.int32), band_buffers(bufs, search, (direction,)))
    b, snr, count = out.download()                  # one copy of the three
    return b.astype(np.float64), snr.copy(), count.copy()


def launch(rt: Runtime, bufs: Buffers, jobs: list, d_disp, d_bounds, k: int, search: Search, d_state,
           bands: tuple | None = None) -> None:
    """Enqueue the integration of one or two jobs (store, bin, SNR, count) of the same
    rows (a pair's two directions, one launch): each `store` (DeviceRows of power
    spectra) read at `d_disp` (float32, bins) within `d_bounds` (int32, group_bounds),
    its peaks into the device buffers after it, each job's in its rows' own bands where
    `bands` gives them (spectrum.band_buffers, one per job); nothing is done where
    `d_state[1]` is set (the tracker's passes stopped, kernels/track.cl; outside them a
    zero constant)."""
    rows, half = jobs[0][0].shape
    before, after = window(k)
    (store, *out), second = jobs[0], jobs[-1]
    none = bufs.constant("index0", zeros(1), np.int32)
    band = (none, none) if bands is None else (bands[0], bands[-1])
    args = (store.buffer, np.int32(rows), np.int32(half), d_disp, d_bounds, np.int32(before), np.int32(after),
            np.int32(search.lo), np.int32(search.hi), band[0], np.int32(bands is not None),
            np.int32(GUARD_BINS), *out, d_state, second[0].buffer, band[1], *second[1:],
            cl.LocalMemory(4 * half))
    if rt.lanes and half % 8 == 0:      # CPUs: a row an item, eight bins a float8
        rt.kernel("integrate", "integrate_lanes")(rt.queue, (rows, len(jobs)), (1, 1), *args)
    else:
        lsz = rt.group_size(16, 256)
        rt.kernel("integrate", "integrate_peak")(rt.queue, (rows * lsz, len(jobs)), (lsz, 1), *args,
                                                  cl.LocalMemory(12 * lsz))
