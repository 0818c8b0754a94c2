"""Atomic file output: a file appears under its final name only when complete."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from pathlib import Path

from .errors import FmcwError

PART_SUFFIX = ".part"


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary sibling path; rename it to `path` if the block succeeds.

    On any exception (Ctrl-C included) the temporary file is removed, so an
    interrupted write never leaves a file that looks finished. A file system's refusal
    (a folder that cannot be written, a full disk) becomes one FmcwError naming `path`.
    """
    final = Path(path)
    tmp = final.with_name(final.name + PART_SUFFIX)
    try:
        tmp.unlink(missing_ok=True)
        yield tmp
        os.replace(tmp, final)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)
        if isinstance(exc, OSError) and (tmp.name in str(exc) or final.name in str(exc)
                                         or exc.filename is not None and Path(exc.filename) in (tmp, final)):
            raise FmcwError(f"{final}: cannot write it ({exc.strerror or exc})") from exc
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


def output_folder(path: str | os.PathLike) -> Path:
    """`path` made (with its parents) and checked writable before any work is done.

    Raises
    ------
    FmcwError : naming the folder and the file system's reason.
    """
    folder = Path(path)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise FmcwError(f"{folder}: cannot make the output folder ({exc.strerror or exc})") from None
    if not os.access(folder, os.W_OK | os.X_OK):
        raise FmcwError(f"{folder}: the output folder is not writable")
    return folder
