"""What a chunk processor carries between its steps and its chunks: what a chunk's codes
say whatever the delay (`Prepared`, from the arguments of `clipping`), chunks held to be
converted again (`Held`), the last chunk waiting for its range check and survey
(`Pending`), the next chunk as the last one left it (`Ahead`), and a step's results
that come with a later download of a device (`Later`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .chunk_checks import RangeCheck, Survey
from .stages import faults, pairing, sync

if TYPE_CHECKING:
    from .capture import Chunk


def clipping(chunk: Chunk, info) -> tuple:
    """`clip_counts`' arguments for a chunk's beat (`info`: its CaptureInfo): blocks of
    faults.CLIP_BLOCK codes, full scale 2^(bits - 1)."""
    return chunk.beat, faults.CLIP_BLOCK, info.full_scale + 1


@dataclass(frozen=True)
class Prepared:
    """What a chunk's codes say whatever the delay: its sync's turning points and how
    many beat codes of each faults.CLIP_BLOCK are at full scale."""

    turns: sync.TurningPoints
    clip_counts: np.ndarray


@dataclass(frozen=True)
class Held:
    """Chunks read once to be converted again and again (the delay's trial stretches):
    their beat codes end to end in `beat`, chunk k's from `offsets[k]` (its arrays are
    views into it), what `prepare` found in each, the stretch each belongs to, and the
    delay (samples) each is converted at (None: the open plan's)."""

    beat: np.ndarray
    chunks: list
    offsets: list[int]
    prepared: list[Prepared]
    stretch: list[int]
    lags: list[float] | None = None

    def at(self, lags: list[float]) -> Held:
        """These chunks once at each delay of `lags`, converted in one pass: the stretches
        of the j-th delay numbered after those of the ones before it."""
        n = max(self.stretch, default=-1) + 1
        return Held(self.beat, self.chunks * len(lags), self.offsets * len(lags), self.prepared * len(lags),
                    [k + j * n for j in range(len(lags)) for k in self.stretch],
                    [lag for lag in lags for _ in self.chunks])


@dataclass
class Pending:
    """A chunk measured but for its range check and survey: its beat codes, the times
    (s) of its pairs' rising and falling half-sweeps, which pairs it owns, the owned
    pairs' tracker results (`result`) and clipping, its clipped codes, and the range
    check and survey to run."""

    beat: np.ndarray
    times: tuple[np.ndarray, np.ndarray]
    own: slice | np.ndarray
    result: pairing.PairResult
    clip: np.ndarray
    clipped_codes: int
    check: RangeCheck | None
    survey: Survey | None


@dataclass
class Ahead:
    """The chunk processed next, as the one before left it: what `prepare` found in it,
    its pairs (`_pairs`, None: none) and their resampling, launched (None: not yet)."""

    chunk: Chunk
    prepared: Prepared
    found: tuple | None
    resampled: tuple | None


@dataclass
class Later:
    """A step's results: known now (`value`), or once a later download of a device
    brings them (`rider`, a buffers.Rider that download carries; `land(raw)` makes the
    results from its bytes, `fetch()` by a copy of their own where no download took it,
    `begin()` queues that copy and returns the function that finishes it: `start`)."""

    value: object = None
    rider: object = None
    land: Callable | None = None
    fetch: Callable | None = None
    begin: Callable | None = None

    def get(self):
        """The results (waits for the device where they are still there)."""
        if self.rider is not None:
            raw, self.rider = self.rider.value, None
            self.value = self.fetch() if raw is None else self.land(raw)
        return self.value

    def start(self) -> Later:
        """Queue the copy of its own now (where a device has one to begin), for `get`
        to wait for; itself. Not to ride on another download after."""
        if self.rider is not None and self.begin is not None:
            self.fetch, self.begin = self.begin(), None
        return self
