"""Launcher of kernels/faults.cl (twin: fmcw_cl.stages.faults.clip_flags)."""

from __future__ import annotations

import numpy as np

from .buffers import Buffers
from .context import Runtime


def clip_flags(rt: Runtime, bufs: Buffers, codes: np.ndarray, block: int, full_scale: int) -> np.ndarray:
    """Whether each block of `block` codes holds a clipped one (see the twin); the codes
    are the chunk's beat, uploaded once for all its launches."""
    blocks = -(-codes.size // block)
    flags = np.zeros(blocks, np.uint8)
    if blocks:
        d_flags = bufs.get("clip_flags", blocks)
        rt.kernel("faults", "clip_blocks")(rt.queue, *rt.items(blocks), bufs.upload_once("codes", codes),
                                           np.int32(codes.size), np.int16(-full_scale),
                                           np.int16(full_scale - 1), np.int32(block), d_flags)
        rt.copy(flags, d_flags)
    return flags.view(bool)
