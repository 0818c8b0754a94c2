"""A second look beside a lone fixed echo, before it is taken for the target.

The tracker follows the strongest peak of its band. A moving target weaker in its
plain spectra than a wall (smeared by its Doppler term, under noise at full scale) is
then never tracked, its echoes too rare to count (fixed_echoes.OTHERS_SHARE), and the wall is
"one echo: the target": a take-off beside a wall of 800 codes put 979 valid pairs on the
wall, up to 138 mm off. With the wall out of the band, the same capture tracks the
target. So before a lone fixed echo is taken for the target, or called indistinct from
the echoes beside it (fixed_echoes.OTHERS_SHARE of the half-sweeps hold others), the
delay's trial stretches (`refine.stretches`) are converted in the user's band on each
side of it, the echo and target.WALL_MARGIN_M about it left out, on rows without still
echoes (stages.clutter: on the plain rows a tracker paired a hand's peak in one
direction with a foot's at rest in the other, and none of its pairs passed), each
measurement integrating LOOK_K half-sweeps, their pairs verified as a track's are, and
the moving echoes they show (`fixed_echoes.moving_spans`) join the choice; such an echo
is converted on such rows too (conversions.looked).

The stretches are three of 12 ms, spread through the capture (most of a lab's 50 ms
capture): a target that moves only between them is not seen.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from . import fixed_echoes, target
from .capture import Capture
from .plan import MIN_RANGE_SHARE
from .refine import by_stretch, pairs_of, stretches
from .stages import clutter, faults

MIN_SIDE_M = 0.02     # a side band narrower than this is not converted
LOOK_K = 8            # half-sweeps of a direction integrated (stages.integrate) unless the user
                      # set K: single ones missed 3 of 6 lab take-offs and landings under noise
                      # at full scale, 8 none; the automatic choice probes 16 and up to 32 on an
                      # empty band's noise (a 50 ms static target on PoCL: 350 ms more; 8: 80)


def sides(fixed_m: float, band: tuple[float, float | None], unambiguous_m: float) -> list[tuple]:
    """The parts (lo, hi m; hi None: to the end of the range) of `band` below and above
    the fixed echo at `fixed_m`, target.WALL_MARGIN_M from it, at least MIN_SIDE_M wide
    and starting where a band may (plan.MIN_RANGE_SHARE of `unambiguous_m`)."""
    lo, hi = band
    out = [(lo, fixed_m - target.WALL_MARGIN_M), (fixed_m + target.WALL_MARGIN_M, hi)]
    return [(a, b) for a, b in out
            if a < MIN_RANGE_SHARE * unambiguous_m and (unambiguous_m if b is None else b) - a >= MIN_SIDE_M]


def moving_beside(cap: Capture, plan, processor, fixed_m: float) -> list[tuple[float, float]]:
    """The moving echoes (lo, hi m) of `plan`'s capture beside its lone fixed echo at
    `fixed_m`: the trial stretches converted by `processor` on each side of it (no range
    check, survey or echo list) together, each apart (ChunkProcessor.process_apart), the
    pairs verified (faults.verified)."""
    held = stretches(cap, plan, processor)
    t, d, v, ok = [], [], [], []
    half = clutter.half_width(cap.info.modulation.period_s)
    for band in sides(fixed_m, plan.options.band_m, plan.lut.unambiguous_range_m):
        p = replace(plan.with_band(band), still_half=half)
        processor.open(replace(p, check=None, survey=False, search=replace(p.search, echoes=False),
                               options=replace(p.options, integrate=p.options.integrate or LOOK_K)))
        for parts in by_stretch(held, processor.process_apart(held)):
            if not parts:
                continue
            tt, dd, vv, _ = pairs_of(parts, p.model, p.motion)
            code = faults.verified(tt, dd, vv, np.concatenate([q.reason for q in parts]), processor,
                                   np.concatenate([q.result.integrated for q in parts]))
            t.append(tt)
            d.append(dd)
            v.append(vv)
            ok.append(code == faults.OK)
    processor.open(plan)
    if not t:
        return []
    return fixed_echoes.moving_spans(*map(np.concatenate, (t, d, v, ok)), np.zeros(0))
