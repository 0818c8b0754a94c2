"""Launcher of kernels/faults.cl (twin: fmcw_cl.stages.faults.clip_counts)."""

from __future__ import annotations

import numpy as np

from .buffers import Buffers
from .context import Runtime


def clip_counts(rt: Runtime, bufs: Buffers, codes: np.ndarray, block: int, full_scale: int) -> np.ndarray:
    """How many codes of each block of `block` are clipped (see the twin); the codes are
    the chunk's beat, uploaded once for all its launches."""
    blocks = -(-codes.size // block)
    counts = np.zeros(blocks, np.uint16)
    if blocks:
        d_counts = bufs.get("clip_counts", 2 * blocks)
        rt.kernel("faults", "clip_blocks")(rt.queue, *rt.items(blocks), bufs.upload_once("codes", codes),
                                           np.int32(codes.size), np.int16(-full_scale),
                                           np.int16(full_scale - 1), np.int32(block), d_counts)
        rt.copy(counts, d_counts)
    return counts
