"""Launcher of kernels/phase.cl (twin: fmcw_cl.stages.phase.phasors)."""

from __future__ import annotations

import numpy as np

from .buffers import Buffers, Packed
from .context import Runtime, cl
from .spectrum import as_device


def phasors_each(rt: Runtime, bufs: Buffers, xs, betas, v: np.ndarray | None, bins,
                 nfft: int) -> list[np.ndarray]:
    """stages.phase.phasors of a pair's two directions `xs` (DeviceRows or host arrays,
    one shape) with their Doppler bases `betas` and peak bins `bins`, the same
    velocities `v` (None: plain): one upload of the velocities and bins, one launch, one
    download of the (2, rows) complex values."""
    rows_of = [as_device(bufs, x) for x in xs]
    rows, points = rows_of[0].shape
    if rows == 0:
        return [np.zeros(0, np.complex128), np.zeros(0, np.complex128)]
    vel = np.zeros(rows, np.float32) if v is None else np.asarray(v, np.float32)
    d_v, d_bins = Packed(bufs, "phase_in", [(np.float32, rows), (np.float32, 2 * rows)]).upload(
        vel, np.concatenate([np.asarray(b, np.float32) for b in bins]))
    out = Packed(bufs, "phase_out", [(np.float32, 4 * rows)])
    size, lsz = _items(rt, rows)
    rt.kernel("phase", "peak_phasor")(
        rt.queue, (size, 2), (lsz, 1), rows_of[0].buffer, rows_of[1].buffer, *_betas(bufs, betas), d_v,
        d_bins, np.int32(rows), np.int32(points), np.float32(1.0 / nfft), np.int32(v is not None),
        np.int32(rt.lanes), *out.buffers, cl.LocalMemory(8 * lsz))
    (z,) = out.download()
    return complex_pairs(z)


def launch_state(rt: Runtime, bufs: Buffers, rows: tuple, model, vel, d_r, d_f, out) -> None:
    """Enqueue the phasors of both directions of `rows` (DeviceRows) at the velocities
    `vel` and apparent distances `d_r`, `d_f` (double device buffers, where the tracker's
    passes left them) into the device buffer `out` (4 float32 a pair; `complex_pairs`)."""
    pairs, points = rows[0].shape
    if pairs == 0:
        return
    size, lsz = _items(rt, pairs)
    rt.kernel("phase", "peak_phasor_state")(
        rt.queue, (size, 2), (lsz, 1), rows[0].buffer, rows[1].buffer,
        *_betas(bufs, (model.beta_rise, model.beta_fall)), vel, d_r, d_f, np.float64(model.metres_per_bin),
        np.int32(pairs), np.int32(points), np.float32(1.0 / model.nfft), np.int32(rt.lanes), out,
        cl.LocalMemory(8 * lsz))


def _items(rt: Runtime, rows: int) -> tuple[int, int]:
    """Work-items along the rows and their group size: a work-group a row (GPUs), or on
    CPU devices (`Runtime.lanes`) a work-item a row, each in vectors along its points."""
    if rt.lanes:
        (size,), (lsz,) = rt.items(rows)
        return size, lsz
    lsz = rt.group_size(16, 128)
    return rows * lsz, lsz


def _betas(bufs: Buffers, betas) -> list:
    return [bufs.constant("beta", b, np.float32) for b in betas]


def complex_pairs(z: np.ndarray) -> list[np.ndarray]:
    """The (rising, falling) complex phasors of a download of 4 float32 a pair."""
    z = np.asarray(z, np.float64).reshape(2, -1, 2)
    return [z[k, :, 0] + 1j * z[k, :, 1] for k in range(2)]
