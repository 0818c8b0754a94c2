"""Atomic file output: a file appears under its final name only when complete."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from pathlib import Path

PART_SUFFIX = ".part"


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary sibling path; rename it to `path` if the block succeeds.

    On any exception (Ctrl-C included) the temporary file is removed, so an
    interrupted write never leaves a file that looks finished.
    """
    final = Path(path)
    tmp = final.with_name(final.name + PART_SUFFIX)
    tmp.unlink(missing_ok=True)
    try:
        yield tmp
        os.replace(tmp, final)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


@contextlib.contextmanager
def atomic_hdf5(path: str | os.PathLike, fmt: str, version: int, attrs: dict | None = None):
    """An HDF5 file written atomically, its root stamped with `fmcw_format`,
    `format_version` and `attrs`; yields the open h5py.File."""
    import h5py

    with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
        f.attrs["fmcw_format"] = fmt
        f.attrs["format_version"] = version
        for k, v in (attrs or {}).items():
            f.attrs[k] = v
        yield f
