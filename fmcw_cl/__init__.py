"""fmcw-cl: batch processor for FMCW LiDAR captures.

The data flow is one way: capture -> chunks -> stages -> pairs -> track.

The Python API (docs/api.md): ``process``, ``process_each``, ``read_track``, ``write_track``,
``open_capture``, ``simulate``, ``calibrate`` and ``Track``, loaded on first use so
that ``import fmcw_cl`` and the command line start at once.
"""

__version__ = "0.1.0"

__all__ = ["process", "process_each", "read_track", "write_track", "open_capture", "simulate", "calibrate",
           "Track", "__version__"]


def __getattr__(name: str):
    if name in __all__:
        from . import api

        return getattr(api, name)
    raise AttributeError(f"module 'fmcw_cl' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
