"""The backend a user names (--backend, backend=): the chunk processor it chooses."""

from __future__ import annotations

from .errors import FmcwError
from .processor import ChunkProcessor, NumpyProcessor


def make_processor(name: str = "auto", device: str | None = None, warn=None) -> ChunkProcessor:
    """The chunk processor of backend `name`: "numpy", "opencl", or "auto".

    "auto" takes OpenCL whenever a device is there (on PoCL, the CPU, it measured 2.4-3x
    faster end to end than numpy; see benchmarks/README.md). A failing OpenCL (no
    platform, a kernel that does not build) falls back to numpy with a one-line warning
    through `warn`; "opencl", or a `device` named, forces it and fails loudly.
    """
    if name == "numpy":
        return NumpyProcessor()
    try:
        from .opencl.processor import OpenCLProcessor

        return OpenCLProcessor(device)
    except FmcwError as exc:
        if name == "opencl" or device is not None:     # what the user named is used or refused
            raise
        if warn:
            warn(f"warning: OpenCL unavailable ({exc}); using the numpy backend")
        return NumpyProcessor()
