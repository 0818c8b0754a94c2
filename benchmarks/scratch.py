"""What the benchmarks share: a folder for the captures one makes (the one the user
names, kept, or a temporary one removed when the script ends: the captures of one run
of hunt.py take 1.2 GB), the seeds a `--seeds A-B` names, and the head of a script that
draws its captures at random (`draws`)."""

from __future__ import annotations

import argparse
import atexit
import shutil
import tempfile
from pathlib import Path

import numpy as np


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


def draws(doc: str, prefix: str, seed: int, count: int, *extra: tuple[str, dict]
          ) -> tuple[argparse.Namespace, Path, np.random.Generator]:
    """The command line of a script that draws `--count` captures from `--seed` into
    `--out` (`folder`, named from `prefix`), with the `extra` options ((flag, keywords
    of add_argument)): its arguments, the folder and the generator of its draws."""
    parser = argparse.ArgumentParser(description=doc.splitlines()[0])
    parser.add_argument("--seed", type=int, default=seed, help="seed of the draws")
    parser.add_argument("--count", type=int, default=count, help="captures")
    for flag, keywords in extra:
        parser.add_argument(flag, **keywords)
    parser.add_argument("--out", default=None,
                        help="folder for the captures, kept (default: a removed temp dir)")
    args = parser.parse_args()
    return args, folder(args.out, prefix), np.random.default_rng(args.seed)
