"""The stream engine: capture -> chunks -> chunk processor -> pairs -> track.

`process` makes the capture's plan (`plan`), streams its chunks through a chunk
processor (`chunks`, `processor`), assembles the track (`assemble`), chooses the target
(a lone fixed echo after a second look beside it: `second_look`) and, where the target
is alone in a band of its own, converts once more in that band;
last it checks that the laser's chirp still matches its table (`refine`) and, where it
is far off, converts once more with a chirp calibrated on the capture's own rest
(`rest_calibration`), or marks every pair uncalibrated.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from . import conversions, fixed_echoes, heap, lone_bodies, objects, rest_calibration, scene, target
from .assemble import assemble
from .band import echo_outside
from .capture import Capture
from .chunks import capture_parts, read_chunks
from .errors import CaptureError
from .options import Options
from .plan import TABLE, Plan, fit_chunks, make_plan
from .processor import ChunkMeasurements, ChunkProcessor, NumpyProcessor
from .refine import refine_lag
from .second_look import moving_beside
from .stages import clutter, faults
from .track import Track
from .tuning import WIDTH_LIMIT, peak_width_ratio, stillest

# peaks this much wider than the window's own: the chirp is so far from its table that no
# distance is vouched for (a jump under 5 us of thermal lag: 2.24, distances to 96 mm off;
# under 2 us: 1.26 once the delay is refined, 0.72 mm at worst; a matching table: 1.02)
UNCALIBRATED_RATIO = 1.5
BAND_VALID = 0.5     # fewer valid pairs than this share, in a band the user set: is the target outside?


def process(path, options: Options | None = None, processor: ChunkProcessor | None = None,
            progress: Callable[[int, int, float], None] | None = None) -> Track:
    """Convert one capture file into a Track (not yet written).

    Parameters
    ----------
    path : the capture file.
    options : processing parameters.
    processor : the chunk processor (default NumpyProcessor); closed when done.
    progress : callable(samples_done, samples_total, sample_rate_hz), optional.
    """
    options = options or Options()
    processor = processor or NumpyProcessor()
    heap.keep_freed()
    started = time.perf_counter()
    try:
        # the processor closes before the capture: it lets the codes go, and the file's map
        # can then go too (on a reader thread; a second close does nothing)
        with Capture(path, processor.reads_in_place) as cap, contextlib.closing(processor):
            # the plan converts stretches itself (the delay's refinement; slots of its own)
            # while the first chunk is read (the 0.3 s jump: 19 ms of the device's idle time)
            with read_chunks(cap, fit_chunks(options, cap.info, processor)) as ahead:
                plan = make_plan(cap, options, processor=processor)
                # the first conversion's echo table lists the fast movers too (stages.bank)
                parts = capture_parts(cap, replace(plan, bank=True), processor, progress=progress,
                                      ahead=ahead)
            first = assemble(plan, parts, processor, time.perf_counter() - started)
            choice, fixed, beside = chosen(cap, plan, processor, first)
            was = conversions.First(plan, parts, first, fixed, beside)
            # a mover only a second look found (on rows without still echoes): on such rows too
            looked = bool(choice.moving) and choice.span_m is not None and conversions.looked(
                objects.Candidate(*choice.span_m, True), beside)
            if choice.band_m != plan.options.band_m:          # the target alone in its band: again
                plan = plan.with_band(choice.band_m)
                if looked:
                    plan = replace(plan, still_half=clutter.half_width(cap.info.modulation.period_s))
                parts = capture_parts(cap, plan, processor, progress=progress)
                track = assemble(plan, parts, processor, time.perf_counter() - started, choice)
            else:
                track = with_choice(plan, parts, processor, time.perf_counter() - started, first, choice)
            whole = track
            if plan.options.target == "strongest" and plan.options.target_near is None:
                found, pick = [objects.SceneObject(1, bool(choice.moving), track, "the strongest echo "
                                                   "of the band, pair by pair")], 0
            else:
                own = conversions.Converted(objects.Candidate(np.nan, np.nan, bool(choice.moving)), choice,
                                            plan, parts, track)
                found, pick, own = scene.objects_of(cap, was, choice, own, processor,
                                                    lambda: time.perf_counter() - started, progress)
                plan, choice, track = own.plan, own.choice, own.track
                # a chirp far from its table bends distances apart: its tuning is checked and
                # its rest sought on the whole conversion, not on one body's part of it
                whole = track if own.whole is None else own.whole
            # such a mover holds no rest: the tuning is read on the still echo the first
            # conversion held (a hand moving throughout read peaks 8.7 times too wide); so
            # is a mover's converted along its course (fmcw_cl.along), whose plan searches
            # the whole band (a glide's: a stronger swaying object's peaks, de-chirped at
            # the glide's velocity, read 1.6 times too wide, and the scene became one object
            # without a valid pair; movers.py seed 1, capture 9)
            elsewhere = looked or plan.course is not None
            ratio = check_tuning(cap, *((was.plan, first) if elsewhere else (plan, whole)), processor)
            track.attrs.update({k: (first if elsewhere else whole).attrs[k] for k in TUNING_ATTRS})
            if ratio > UNCALIBRATED_RATIO and plan.options.dechirp:
                track = calibrated_on_rest(cap, plan, whole, processor, choice, started, progress)
                # its pairs may still be two movers' (a glide through a swaying object, the
                # tracker passing 39 mm between them in 0.2 ms: 259 valid pairs on the glide)
                track = lone_bodies.one_body(track, bool(choice.moving))
                found, pick = [objects.SceneObject(1, bool(choice.moving), track, "the target: objects not "
                                                   "sought on a chirp calibrated on its rest")], 0
            track = with_objects(found, pick)
            check_band(cap, plan, options, track, processor)
    finally:
        processor.close()
    return track


def with_choice(plan: Plan, parts: list[ChunkMeasurements], processor: ChunkProcessor, seconds: float,
                track: Track, choice: target.Choice) -> Track:
    """The first conversion's `track` with a target `choice` that kept its band: made
    again where the choice makes pairs ambiguous (or may: fixed echoes not the target
    show in de-chirped half-sweeps, fmcw_cl.wall_images), else its attributes added."""
    if choice.undecided or choice.walls_m.size:
        return assemble(plan, parts, processor, seconds, choice, track.echoes)
    track.attrs.update(choice.attrs())
    return track


def chosen(cap: Capture, plan: Plan, processor: ChunkProcessor, track: Track
           ) -> tuple[target.Choice, fixed_echoes.Fixed, list[tuple[float, float]]]:
    """The target of a first conversion `track` (choose_target), with a second look
    (fmcw_cl.second_look, by `processor`) beside a lone fixed echo; the fixed echoes of
    its tables and the moving echoes the second look found."""
    fixed = fixed_echoes.fixed_of(track.echoes, plan.lut.unambiguous_range_m, track.time_s, track.distance_m,
                                  track.velocity_mps, track.valid)
    choice = choose_target(plan, track, fixed)
    beside: list[tuple[float, float]] = []
    if choice.lone:
        beside = moving_beside(cap, plan, processor, float(choice.fixed_m[0]))
        choice = choose_target(plan, track, fixed, beside)
    return choice, fixed, beside


def with_objects(found: list[objects.SceneObject], pick: int) -> Track:
    """The track of the target, `found[pick]`, with the scene's objects and the target's
    id (`target_object`); the other objects named, each with the option that chooses it
    (`target_others`). `pick` -1: no object is told to be the target (objects.choose):
    the pairs of the one with the most verified pairs, every one `ambiguous`, id 0."""
    if pick < 0:        # no object moves: several fixed ones, none told to be the target
        base = max(found, key=lambda o: int(o.track.valid.sum()))
        chosen_track = objects.invalidated(base.track, base.track.valid.copy())
        seen = ", ".join(f"{objects.where_m(o.track):.3f}" for o in found if o.track.valid.any())
        chosen_track.attrs["target_choice"] = (f"no object moves: the fixed objects at {seen} m cannot be "
                                               "told apart as the target")
    else:
        chosen_track = found[pick].track
    others = [o for k, o in enumerate(found) if k != pick]
    chosen_track.attrs.update(
        target_object=int(found[pick].id) if pick >= 0 else 0, objects=len(found),
        target_others="; ".join(objects.describe(o) + (
            f": --target-near {objects.where_m(o.track):.3f} chooses it" if o.track.valid.any() else "")
            for o in others))
    chosen_track.objects = found
    return chosen_track


def choose_target(plan: Plan, track: Track, fixed: fixed_echoes.Fixed, beside: list | None = None
                  ) -> target.Choice:
    """The target of a first conversion (fmcw_cl.target.choose) from its `fixed` echoes
    (fixed_echoes.fixed_of), with the moving echoes a second look found beside a lone fixed
    echo (`beside`, fmcw_cl.second_look)."""
    clipped = track.reason is not None and bool(np.any(track.reason == faults.CLIPPED))
    try:
        return target.choose(plan.options.target, plan.options.target_near, track.time_s, track.distance_m,
                             track.velocity_mps, track.valid, track.echoes, plan.lut.unambiguous_range_m,
                             plan.options.band_m, beside, clipped, fixed)
    except ValueError as exc:
        raise CaptureError(plan.info.path, str(exc)) from None


TUNING_ATTRS = ("tuning_peak_width_ratio", "tuning_matches", "uncalibrated_ratio")   # `check_tuning`'s


def check_tuning(cap: Capture, plan: Plan, track: Track, processor: ChunkProcessor) -> float:
    """Record how much wider than the window's own the track's peaks of its stillest
    stretch are (`tuning_peak_width_ratio`, returned; `tuning_matches` is false beyond
    WIDTH_LIMIT): the sign that the laser's real chirp has left its G(I) table or its
    calibration."""
    ratio = peak_width_ratio(cap, plan, stillest(track.time_s, track.velocity_mps),
                             track.time_s, track.velocity_mps, processor, track.distance_m)
    track.attrs.update(dict(zip(TUNING_ATTRS, (ratio, bool(not ratio > WIDTH_LIMIT), UNCALIBRATED_RATIO),
                                strict=True)))
    return ratio


def check_band(cap: Capture, plan: Plan, options: Options, track: Track, processor: ChunkProcessor) -> None:
    """Where the user's --min-range/--max-range gave next to no valid pair, record the
    strongest echo outside that band (`echo_outside_band_m`, `_db`; band.echo_outside):
    the range gate, not the target, is then the cause."""
    narrowed = options.max_range is not None or options.min_range != Options.min_range
    if narrowed and not (track.valid.mean() if track.valid.size else 0.0) >= BAND_VALID:
        found = echo_outside(cap, plan.with_band(options.band_m), processor)
        if found is not None:
            track.attrs["echo_outside_band_m"], track.attrs["echo_outside_band_db"] = found


def calibrated_on_rest(cap: Capture, plan: Plan, track: Track, processor: ChunkProcessor,
                       choice: target.Choice, started: float, progress=None) -> Track:
    """A track whose chirp is far from its G(I) table converted again with a chirp
    calibrated on the capture's own rest (`rest_calibration`) where that can be made
    and its peaks then match; else `track` with every valid pair marked uncalibrated
    (a given chirp calibration is not replaced)."""
    if plan.tuning != TABLE:
        return uncalibrated(track, {"rest_calibration": "not tried: a chirp calibration was given"})
    own, attrs = rest_calibration.calibrate(cap, plan, track, processor)
    if own is None:
        return uncalibrated(track, attrs)
    # the delay refined again on the calibrated chirp: the table's misfit inflates the
    # uncertainty of the delay found with it (the 0.3 s jump under 5 us of lag, seeds 0
    # and 165: +-20.9 and +-24.1 samples on the table, +-0.05 and +-0.12 on the chirp)
    own = refine_lag(cap, own, processor)
    before = track.attrs["tuning_peak_width_ratio"]
    parts = capture_parts(cap, own, processor, progress=progress)
    calibrated = assemble(own, parts, processor, time.perf_counter() - started, choice)
    calibrated.attrs.update(attrs, table_peak_width_ratio=before)
    ratio = check_tuning(cap, own, calibrated, processor)
    if ratio > UNCALIBRATED_RATIO:
        return uncalibrated(calibrated, {"rest_calibration": f"made on its rest, but its peaks are still "
                                                             f"{ratio:.2f}x the window's"})
    return calibrated


def uncalibrated(track: Track, attrs: dict) -> Track:
    """`track` with `attrs` and no valid pair: the chirp is so far from its table that
    distances cm off pass every neighbour test when all are off alike."""
    track.attrs.update(attrs)
    track.reason[track.reason == faults.OK] = faults.UNCALIBRATED
    track.sweep_reason[track.sweep_reason == faults.OK] = faults.UNCALIBRATED
    track.valid[:] = False
    # the tracked span assemble took from the valid pairs: none is left
    track.attrs.update(invalid_uncalibrated=int(np.sum(track.reason == faults.UNCALIBRATED)),
                       target_tracked_m=np.full(2, np.nan))
    return track
