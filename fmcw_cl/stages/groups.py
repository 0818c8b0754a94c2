"""Groups of pairs tracked apart, and the running median and continuity prior of a
group's velocities: the pairs of each group (`group_slices`, `group_bounds`,
`group_ends`), a step run on each group alone (`_each`), and the tracker's
regularisation (`running_median`, `regularise`).
"""

from __future__ import annotations

import numpy as np

from .. import numeric
from .spectrum import Search

NEIGHBOURS = Search.reach   # half-width (pairs) of the continuity median (a leg's; fmcw_cl.motion)


def group_slices(groups: np.ndarray | None, pairs: int) -> list[slice]:
    """The pairs of each group (`groups`: the first pair of each, 0 first; None: one
    group of all `pairs`): pairs converted together but apart from one another (the
    delay's trial stretches: ChunkProcessor.process_apart), which are nobody's neighbours
    across a group's ends."""
    edges = [0] if groups is None else [int(g) for g in groups]
    return [slice(a, b) for a, b in zip(edges, [*edges[1:], pairs], strict=True) if b > a]


def group_bounds(groups: np.ndarray | None, pairs: int) -> np.ndarray:
    """(2 pairs,) int32: the first pair of each pair's group (`group_slices`), then the
    last of each: what a kernel is told of the groups."""
    first, last = _ends(groups, pairs)
    return np.concatenate([first, last]).astype(np.int32)


def group_ends(groups: np.ndarray | None, pairs: int) -> tuple[np.ndarray, np.ndarray] | None:
    """The first and last pair of each pair's group (`group_slices`); None for one group
    (numeric.window_index's segments)."""
    return None if groups is None or len(group_slices(groups, pairs)) < 2 else _ends(groups, pairs)


def _ends(groups: np.ndarray | None, pairs: int) -> tuple[np.ndarray, np.ndarray]:
    slices = group_slices(groups, pairs)
    size = [g.stop - g.start for g in slices]
    return (np.repeat([g.start for g in slices], size).astype(np.int64),
            np.repeat([g.stop - 1 for g in slices], size).astype(np.int64))


def _each(groups: np.ndarray, step, pairs: int, dtype=np.float64) -> np.ndarray:
    """`step(g)` of each group's slice g of `pairs`, laid end to end."""
    parts = [step(g) for g in group_slices(groups, pairs)]
    return np.concatenate(parts) if parts else np.zeros(0, dtype)


def running_median(v: np.ndarray, groups: np.ndarray | None = None, reach: int = NEIGHBOURS) -> np.ndarray:
    """Median of each pair's 2 reach + 1 pairs (edges, a group's too: nearest)."""
    return numeric.running_median(v, 2 * reach + 1, group_ends(groups, v.size))


def regularise(v: np.ndarray, trusted: np.ndarray, time: np.ndarray,
               smooth: np.ndarray | None = None, groups: np.ndarray | None = None) -> np.ndarray:
    """Continuity prior: running median of trusted velocities, gaps filled linearly
    (`smooth`: running_median(v) when the caller has it), each group on its own."""
    smooth = running_median(v, groups) if smooth is None else smooth
    if groups is not None:
        return _each(groups, lambda g: regularise(v[g], trusted[g], time[g], smooth[g]), v.size)
    if not np.any(trusted):
        return np.zeros_like(v)
    return np.interp(time, time[trusted], smooth[trusted])
