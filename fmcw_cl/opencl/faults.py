"""Launcher of kernels/faults.cl (twin: fmcw_cl.stages.faults.clip_counts)."""

from __future__ import annotations

import numpy as np

from .buffers import Buffers, Packed, Rider
from .context import Runtime
from .resample import codes_of


def clip_rider(rt: Runtime, bufs: Buffers, codes: np.ndarray, block: int, full_scale: int) -> Rider:
    """How many codes of each block of `block` are clipped (see the twin), as a Rider of
    another step's download; the codes are the chunk's beat, uploaded once for all its
    launches (opencl.resample.codes_of)."""
    blocks = -(-codes.size // block)

    def launch(d_counts) -> None:
        if blocks:
            rt.kernel("faults", "clip_blocks")(rt.queue, *rt.items(blocks), codes_of(bufs, codes),
                                               np.int32(codes.size), np.int16(-full_scale),
                                               np.int16(full_scale - 1), np.int32(block), d_counts)

    return Rider(np.uint16, blocks, launch)


def clip_counts(rt: Runtime, bufs: Buffers, codes: np.ndarray, block: int, full_scale: int) -> np.ndarray:
    """`clip_rider`'s counts by a download of their own."""
    rider = clip_rider(rt, bufs, codes, block, full_scale)
    if rider.count:
        Packed(bufs, "clip_counts", [], (rider,)).download()
        return rider.value
    return np.zeros(0, np.uint16)
