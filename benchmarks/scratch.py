"""What the benchmarks share: a folder for the captures one makes (the one the user
names, kept, or a temporary one removed when the script ends: the captures of one run
of hunt.py take 1.2 GB), and the seeds a `--seeds A-B` names."""

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


def seeds(text: str) -> list[int]:
    """The seeds of `--seeds A-B` (or of one, `A`)."""
    lo, _, hi = text.partition("-")
    return list(range(int(lo), int(hi or lo) + 1))
