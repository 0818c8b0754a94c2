"""fmcw-cl: batch processor for FMCW LiDAR captures.

The data flow is one way: capture -> chunks -> stages -> pairs -> track.

The Python API (docs/api.md): ``process``, ``process_each``, ``read_track``, ``write_track``,
``open_capture``, ``simulate``, ``calibrate`` and ``Track``, loaded on first use so
that ``import fmcw_cl`` and the command line start at once.
"""

from pathlib import Path as _Path

__version__ = "0.1.0"

# The command line (cli/) and the OpenCL sources (kernels/) sit beside this folder in a
# checkout; an install maps them into fmcw_cl (pyproject.toml). Run from a checkout,
# where the source folder shadows the install, they are found the same way.
_root = _Path(__file__).resolve().parent.parent
if not _Path(__file__).with_name("kernels").is_dir() and (_root / "kernels" / "__init__.py").is_file():
    __path__.append(str(_root))

__all__ = ["process", "process_each", "read_track", "write_track", "open_capture", "simulate", "calibrate",
           "Track", "__version__"]


def __getattr__(name: str):
    if name in __all__:
        from . import api

        return getattr(api, name)
    raise AttributeError(f"module 'fmcw_cl' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
