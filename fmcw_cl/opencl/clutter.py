"""Launcher of kernels/clutter.cl (twin: fmcw_cl.stages.clutter.without_still)."""

from __future__ import annotations

import numpy as np

from ..stages import clutter
from .buffers import Buffers, DeviceRows
from .context import Runtime
from .spectrum import as_device


def without_still(rt: Runtime, bufs: Buffers, rows, half: int):
    """`rows` (DeviceRows, or a host array) each less the running mean of its
    neighbours (see the twin), where they are: new DeviceRows from device rows (one
    launch, a work-item a point), a host array from a host array or on a device without
    double precision (there the rows come down, and go up again if they were up)."""
    if not isinstance(rows, DeviceRows):
        return clutter.without_still(rows, half)
    if not rt.fp64:
        return as_device(bufs, clutter.without_still(rows.get(), half))
    n, points = rows.shape
    out = DeviceRows(bufs, n, points)
    if n:
        rt.kernel("clutter", "without_still")(rt.queue, *rt.items(points), rows.buffer, np.int32(n),
                                              np.int32(points), np.int32(half), out.buffer)
    return out
