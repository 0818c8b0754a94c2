"""A candidate of the scene converted in a band of its own: its plan and measurements
(converted once per band and running mean), its track assembled under its choice.

`convert` sets the candidate's band (target.choose at its centre) and converts it: a
moving echo whose span holds fixed objects on rows without still echoes (stages.clutter),
where something still trembles in bands cut off each side of it; `measured` converts a
band once a capture; `assembled` and `again` assemble measurements under a choice.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from . import fixed_echoes, objects, target
from .assemble import assemble
from .capture import Capture
from .chunks import capture_parts
from .errors import FmcwError
from .options import RANGE_GAP_M
from .plan import Plan
from .processor import ChunkMeasurements, ChunkProcessor
from .stages import clutter
from .track import Track

# a mover's side bands end this far from a fixed object inside its span, where rows without
# still echoes still hold it (`convert`)
SIDE_MARGIN_M = target.WALL_MARGIN_M


@dataclass
class Converted:
    """One candidate's conversion: the choice that set its band, the plan and
    measurements in that band, and its track."""

    candidate: objects.Candidate
    choice: target.Choice
    plan: Plan
    parts: list[ChunkMeasurements]
    track: Track
    joined: bool = False        # the track joins several bands' (`plan`, `parts`: one of them)
    whole: Track | None = None  # the conversion's track, where `track` is one body's part of it


@dataclass
class First:
    """The first conversion (the user's band): plan, measurements, track, the fixed
    echoes of its tables and the moving echoes a second look found (`beside`)."""

    plan: Plan
    parts: list[ChunkMeasurements]
    track: Track
    fixed: fixed_echoes.Fixed
    beside: list[tuple[float, float]]


def looked(c: objects.Candidate, beside: list[tuple[float, float]]) -> bool:
    """Whether moving candidate `c` overlaps a moving echo that the second look found
    (fmcw_cl.second_look, on rows without still echoes): the first conversion's tracker
    held the fixed echo beside it, whose peaks a tracker in its band pairs with its own
    (a hand passing a foot at rest: none of its pairs verified)."""
    return c.moving and any(lo <= c.hi and c.lo <= hi for lo, hi in beside)


def convert(cap: Capture, first: First, c: objects.Candidate, spans: list[tuple[float, float]],
            made: dict, processor: ChunkProcessor, seconds, progress, own: Converted | None = None
            ) -> Converted:
    """Candidate `c` converted in its own band (target.choose with `near_m` at its centre,
    its kind before the other at a tie), the measurements of a band already converted
    (`made`) assembled again. A moving echo whose span holds fixed objects is converted
    on rows without still echoes (stages.clutter; none of a still echo's images looked
    for, no displacement: the running mean bends a slow mover's phase). `own`: the
    target's conversion, where it holds this candidate but not alone (one side of the
    fixed objects inside its span: target.choose), the tracks one (objects.joined; where
    both verify a pair more than objects.SAME_M apart, it is `ambiguous`)."""
    tr = first.track
    beside = list(spans) + ([] if c.fixed or c.moving else [(c.lo, c.hi)])
    choice = target.choose("auto", c.centre_m, tr.time_s, tr.distance_m, tr.velocity_mps, tr.valid, tr.echoes,
                           first.plan.lut.unambiguous_range_m, first.plan.options.band_m, beside,
                           fixed=first.fixed, moving=c.moving, sides=c.moving)
    if c.fixed:
        choice = replace(choice, at_rest_m=c.centre_m, band_m=_wide_enough(choice.band_m))
    # the user's --target-near chooses among the objects, and need not lie in this one's band
    unnamed = replace(first.plan, options=replace(first.plan.options, target_near=None))
    if not searchable(unnamed, choice.band_m):
        # no band of its own can be searched (its start past plan.MIN_RANGE_SHARE of the
        # range, or narrower than a band may be): an object without pairs, not a crash
        empty = replace(tr, attrs={**tr.attrs, **choice.attrs()})
        objects.invalidate(empty, np.ones(tr.pairs, bool))
        return Converted(c, choice, first.plan, first.parts, empty)
    # a mover among fixed objects, or one only a second look on such rows found: its rows
    # without still echoes, its band whole
    still = clutter.half_width(cap.info.modulation.period_s) if (
        c.moving and choice.moving and (choice.ambiguous_m.size or looked(c, first.beside))) else 0

    def one(band: tuple[float, float | None], half: int) -> Converted:
        if own is not None and (band, half) == (own.choice.band_m, 0):
            plan = replace(unnamed.with_band(band), still_half=half)
            return Converted(c, own.choice, plan, own.parts, replace(own.track, attrs=dict(own.track.attrs)))
        plan, parts = measured(cap, first, band, half, made, processor, progress)
        side = replace(choice, band_m=band)
        if half:        # no still echo's image in these rows; a trembling one's: `_stays`, `_exclusive`
            side = replace(side, walls_m=np.zeros(0), walls_db=np.zeros(0))
        seen = tr.echoes if (band, half) == (first.plan.options.band_m, 0) else None   # the band's own table
        track = assembled(plan, parts, processor, seconds, side, seen)
        return Converted(c, side, plan, parts, track)

    items = [(choice.band_m, still)]
    done = [one(*items[0])]
    if still and _stays(done[0].track, choice.ambiguous_m, first):
        # something trembles: a shorter running mean takes it out, a mover keeps its echo
        # from a few mm/s (stages.clutter); where it still stays, bands cut off each side
        still = clutter.half_width(cap.info.modulation.period_s, clutter.TREMBLING_S)
        items = [(choice.band_m, still)]
        done = [one(*items[0])]
        if _stays(done[0].track, choice.ambiguous_m, first):
            items += [(b, still) for b in _sides(choice.band_m, choice.ambiguous_m)
                      if searchable(unnamed, b)]
            done += [one(*item) for item in items[1:]]
    if own is not None and (own.choice.band_m, 0) not in items:
        items.append((own.choice.band_m, 0))
        done.append(one(*items[-1]))
    out = done[0]
    for d in done[1:]:                  # the other's pairs where only it holds them; both apart: ambiguous
        both = out.track.valid & d.track.valid
        apart = both & (np.abs(out.track.distance_m - d.track.distance_m) > objects.SAME_M)
        objects.invalidate(out.track, apart)
        objects.invalidate(d.track, apart | both)
        joined = objects.joined(out.track, d.track)
        out = replace(d if d.track.valid.sum() > out.track.valid.sum() else out, track=joined, joined=True)
    if len(items) > 1:
        out.track.attrs["object_bands_m"] = np.asarray([(a, np.nan if b is None else b)
                                                         for (a, b), _ in items]).ravel()
    return out


def measured(cap: Capture, first: First, band: tuple[float, float | None], half: int, made: dict,
             processor: ChunkProcessor, progress) -> tuple[Plan, list[ChunkMeasurements]]:
    """The plan of `band` (m; on rows without still echoes of a running mean of 2 `half`
    + 1 periods where `half`, stages.clutter) and its measurements: converted once per
    capture (`made`, by band and half), the user's --target-near left out."""
    unnamed = replace(first.plan, options=replace(first.plan.options, target_near=None))
    plan = replace(unnamed.with_band(band), still_half=half)
    key = (band, half) if half else band
    if key not in made:
        made[key] = capture_parts(cap, plan, processor, progress=progress)
    return plan, made[key]


def searchable(plan: Plan, band: tuple[float, float | None]) -> bool:
    """Whether `plan` can search `band` (m): Options' and plan.make_search's limits."""
    try:
        plan.with_band(band)
    except FmcwError:
        return False
    return True


def held(track: Track, first: First) -> np.ndarray:
    """The distances (m) of the fixed objects `track`'s own echo table lists
    (fixed_echoes.fixed_of: echoes seen while its target is away)."""
    left = fixed_echoes.fixed_of(track.echoes, first.plan.lut.unambiguous_range_m, track.time_s,
                                 track.distance_m, track.velocity_mps, track.valid)
    return left.distance_m[left.objects]


def _wide_enough(band: tuple[float, float | None]) -> tuple[float, float | None]:
    """`band` (m) at least options.RANGE_GAP_M wide, its far end moved out: a fixed
    object between the near end of the range and a mover's span (a hand come to rest at
    0.038 m, the jump's span from 0.041 m: its band 9.3 mm, searched by none)."""
    lo, hi = band
    return band if hi is None or hi - lo >= RANGE_GAP_M else (lo, lo + RANGE_GAP_M)


def _stays(track: Track, inner: np.ndarray, first: First) -> bool:
    """Whether rows without still echoes (`track`'s) still hold a fixed object within
    fixed_echoes.APART_M of one of the fixed echoes `inner` (m) (`held`): something
    that trembles (a cable, a pane: a micrometre turns its phase through radians)."""
    there = held(track, first)
    near = np.abs(there[:, None] - np.asarray(inner)[None, :]) <= fixed_echoes.APART_M
    return bool(there.size and np.any(near))


def _sides(band: tuple[float, float | None], inner: np.ndarray) -> list[tuple[float, float | None]]:
    """`band` cut at the fixed objects `inner` (m), SIDE_MARGIN_M off each, the parts at
    least options.RANGE_GAP_M wide."""
    edges = [(band[0], None)]
    for f in np.sort(np.asarray(inner, float)):
        edges[-1] = (edges[-1][0], f - SIDE_MARGIN_M)
        edges.append((f + SIDE_MARGIN_M, None))
    edges[-1] = (edges[-1][0], band[1])
    return [(a, b) for a, b in edges if (b is None or b - a >= RANGE_GAP_M)] or [band]


def again(d: Converted, choice: target.Choice, processor: ChunkProcessor, seconds) -> Track:
    """Conversion `d`'s measurements assembled again under `choice` (its echo table kept)."""
    return assembled(d.plan, d.parts, processor, seconds, choice, d.track.echoes)


def assembled(plan: Plan, parts: list[ChunkMeasurements], processor: ChunkProcessor, seconds,
              choice: target.Choice, seen) -> Track:
    """`assemble`, its attribute objects.STILL_ATTR set; on rows without still echoes
    no displacement (the running mean bends a slow mover's phase)."""
    track = assemble(plan, parts, processor, seconds(), choice, seen)
    track.attrs[objects.STILL_ATTR] = (2 * plan.still_half * plan.info.modulation.period_s if plan.still_half
                                       else 0.0)
    if plan.still_half:
        objects.no_displacement(track)
    return track
