"""What a capture's chunks gave one conversion, given again to the next ones.

A scene of several objects converts its capture once for the tables, then once in each
object's band and again along each mover's course: five to seven conversions of the same
chunks at the same delay. Two of each chunk's steps do not depend on the band: what
`prepare` finds in its codes (the sync's turning points, the clipping counts) and the
2N-point range check of a given set of pairs searched from a given bin (the same pairs
and search in most of the conversions). Those took 40 % of each later conversion's device
time on a jump beside a static object (53 of 135 ms); a `ChunkMemo` keeps their results
for the capture, keyed by what they are computed from, so the same inputs give the very
results the first conversion got.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from .chunk_state import Later, Pending, Prepared

if TYPE_CHECKING:
    from .capture import Chunk


class ChunkMemo:
    """The prepared chunks and range checks of one capture (its CaptureInfo, held: a
    processor's next capture starts a memo of its own)."""

    def __init__(self) -> None:
        self._info = None
        self._prepared: dict[tuple, Prepared] = {}
        self._checked: dict[tuple, object] = {}

    def _for(self, info) -> None:
        if info is not self._info:
            self._info, self._prepared, self._checked = info, {}, {}

    def prepared(self, chunk: Chunk, info, make: Callable[[], Later]) -> Later:
        """`make()` (a processor's prepare_later of `chunk`), or what it gave before."""
        self._for(info)
        key = (chunk.start, chunk.stop)
        if key in self._prepared:
            return Later(self._prepared[key])

        def keep(value: Prepared) -> Prepared:
            self._prepared[key] = value
            return value

        return _mapped(make(), keep)

    def checked(self, chunk: Pending, info, make: Callable[[Pending], Later]) -> Later:
        """`make(chunk)` (a processor's check_and_survey_later), its range check's
        results what they were before for the same pairs, positions, resampling and
        search (the survey, its conversion's own, still made)."""
        check = chunk.check
        if check is None:
            return make(chunk)
        self._for(info)
        times = chunk.times[0][chunk.own][check.checked]
        key = (_digest(times, check.window, *(a for job in check.jobs for a in job)),
               check.search.lo, check.search.hi, check.model.nfft)
        if key in self._checked:
            known = self._checked[key]
            return _mapped(make(replace(chunk, check=None)), lambda got: (known, *got[1:]))

        def keep(got: tuple) -> tuple:
            self._checked[key] = got[0]
            return got

        return _mapped(make(chunk), keep)


def _digest(*arrays) -> bytes:
    """A digest of the arrays' dtypes, shapes and contents (the key of a range check,
    whose inputs are tens of kB a chunk)."""
    h = hashlib.blake2b(digest_size=16)
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(str((a.dtype, a.shape)).encode())
        h.update(a.data)
    return h.digest()


def _mapped(later: Later, to: Callable[[object], object]) -> Later:
    """`later` (just made), its results passed through `to` once known."""
    if later.rider is None:
        later.value = to(later.value)
        return later
    land, fetch, begin = later.land, later.fetch, later.begin
    later.land = lambda raw: to(land(raw))
    later.fetch = lambda: to(fetch())
    if begin is not None:
        later.begin = lambda: (lambda done: lambda: to(done()))(begin())
    return later
