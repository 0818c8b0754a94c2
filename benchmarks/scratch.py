"""A benchmark's folder for the captures it makes: the one the user names, kept, or a
temporary one removed when the script ends (the captures of one run of hunt.py: 1.2 GB)."""

from __future__ import annotations

import atexit
import shutil
import tempfile
from pathlib import Path


def folder(given: str | Path | None, prefix: str) -> Path:
    """`given` (made if missing), or a new temporary folder named from `prefix`."""
    if given:
        out = Path(given)
        out.mkdir(parents=True, exist_ok=True)
        return out
    out = Path(tempfile.mkdtemp(prefix=prefix))
    atexit.register(shutil.rmtree, out, ignore_errors=True)
    return out
