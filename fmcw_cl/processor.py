"""The chunk processor: one chunk of raw codes in, its measurements out.

A processor has one life cycle whatever runs it (the model is OCT's streaming
processors): `open(plan)` binds a capture's plan (a device uploads its constants once),
`process(chunk)` turns each chunk into `ChunkMeasurements`, `fork()` gives another
thread its own (queue, kernels, buffers), `close()` lets the plan go. `NumpyProcessor`
runs every stage in numpy/scipy and is the reference; `opencl.processor.OpenCLProcessor`
runs the same steps on a device. What the steps are, in order (`process`):

1. the sync's turning points, shifted by the plan's delay: the half-sweeps;
2. each pair's rising and falling half-sweeps resampled at uniform optical frequency;
3. the tracker's passes (plain FFT, de-chirp, regularisation; `stages.pairing`);
4. ownership: the pairs whose first turning point lies in the chunk's core;
5. clipping by its effect, the 2N-point range check, the survey of hidden echoes.

A processor's later conversions of a capture (its objects') take the turning points,
clipping counts and range checks its chunks gave before (chunk_memo.ChunkMemo).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from . import echoes, spectrum_ops
from .chunk_checks import RangeCheck, Survey, no_survey, owned
from .chunk_memo import ChunkMemo
from .chunk_state import Ahead, Held, Later, Pending, Prepared, clipping
from .errors import FmcwError
from .stages import bank, clutter, delay, faults, integrate, lpf, pairing, resample, sync
from .stages.groups import group_slices

if TYPE_CHECKING:
    from .capture import Chunk
    from .plan import Plan


@dataclass
class ChunkMeasurements:
    """The owned pairs of one chunk (absolute times in s): per pair both half-sweeps'
    apparent, de-chirped and Doppler-free distances, velocity and echoes (`result`), why
    it is invalid (`reason`, stages.faults), the survey of hidden echoes, and the beat
    codes at full scale in the chunk's core."""

    t_rise: np.ndarray
    t_fall: np.ndarray
    result: pairing.PairResult
    reason: np.ndarray
    survey: dict          # echoes.hidden of every SURVEY_STRIDE-th pair's half-sweeps
    clipped_codes: int = 0  # beat codes at full scale in the chunk's core (to a block at its edges)
    spectrum: np.ndarray | None = None   # (2, nfft/2) the surveyed half-sweeps' plain power, summed
    spectrum_rows: int = 0               # per direction (rising, falling), over this many of each


class ChunkProcessor(spectrum_ops.SpectrumOps):
    """The life cycle and the steps of a chunk processor; a subclass supplies the stage
    operations (low-pass, the delay's per-period fits, turning points, resampling,
    clipping counts, and the spectrum operations of spectrum_ops.SpectrumOps) and its sizes.

    Attributes
    ----------
    name, device : what runs it, as the track records it.
    chunk_default : modulation periods a chunk, unless the options say.
    batch_workers : captures a batch converts at once (batch.process_each).
    reads_in_place : whether its chunks are best read as views of the file's pages
        (`Capture` `in_place`): the host's memory is its own; a GPU's driver copies from
        page-locked memory only by DMA.
    chunks : chunks processed so far.
    """

    name = ""
    device = ""
    chunk_default = 1024
    batch_workers = 1
    reads_in_place = True

    def __init__(self) -> None:
        self.plan: Plan | None = None
        self.chunks = 0
        self._ahead: Ahead | None = None         # the next chunk, prepared by the last one
        self._pending: Pending | None = None     # the last chunk, but for its range check and survey
        self._meanwhile: Callable[[], None] | None = None    # `meanwhile`'s work
        self._memo = ChunkMemo()      # what the capture's chunks gave its other conversions

    # -- life cycle --
    def open(self, plan: Plan) -> None:
        """Bind the capture's plan (its LUT, window and search) for `process`."""
        self.plan, self._ahead, self._pending, self._meanwhile = plan, None, None, None

    def close(self) -> None:
        """Let the plan and what the capture's chunks gave go (a device processor also
        returns its pooled buffers)."""
        self.plan, self._ahead, self._pending, self._meanwhile = None, None, None, None
        self._memo = ChunkMemo()

    def fork(self) -> ChunkProcessor:
        """A processor of the same kind for another thread."""
        raise NotImplementedError

    def chunk_limit(self, samples_per_period: float, points: int) -> int | None:
        """The most periods a chunk may hold (a device's memory), None: no limit."""
        return None

    def finish(self) -> None:
        """Wait for work in flight (a device's launches are asynchronous)."""

    def traffic(self) -> dict[str, int]:
        """Copies each way, their bytes and the launches so far (a device's)."""
        return {}

    def profile(self, on: bool) -> float | None:
        """Start timing the device's work (`on`), or stop and return its busy seconds
        since (None: no device)."""
        return None

    # -- stage operations, each a twin of a stages/ function --
    def intensity_each(self, channels, sample_rate_hz) -> list[tuple]:
        """`lpf.intensity` of each array of `channels` (a device: one download)."""
        raise NotImplementedError

    def intensity(self, codes, sample_rate_hz):
        return self.intensity_each([codes], sample_rate_hz)[0]

    def fit_periods(self, y, z, shift, period, span):
        raise NotImplementedError

    def period_delays(self, beat, sync_codes, sample_rate_hz, half_period):
        """`delay.period_delays` of the stretches `beat`, `sync_codes` (rows of codes), by
        this processor's low-pass and per-period fit (a device: one download)."""
        return delay.period_delays(beat, sync_codes, sample_rate_hz, half_period, self.intensity_each,
                                  self.fit_periods)

    def turning_points(self, codes, half_period):
        raise NotImplementedError

    def resample_each(self, codes, jobs, win):
        """`resample` of each (starts, lengths, u[, runs]) of `jobs` (a device: one upload;
        `runs`: counts of consecutive half-sweeps that a device resamples as if alone)."""
        raise NotImplementedError

    def resample(self, codes, starts, lengths, u, win):
        return self.resample_each(codes, [(starts, lengths, u)], win)[0]

    def clip_counts(self, codes, block, full_scale):
        raise NotImplementedError

    # -- the chunk --
    def prepare(self, chunk: Chunk, info) -> Prepared:
        """What `chunk`'s codes say whatever the delay (`info`: its capture's CaptureInfo)."""
        return Prepared(self.turning_points(chunk.sync, info.samples_per_period / 2),
                        self.clip_counts(*clipping(chunk, info)))

    def prepare_later(self, chunk: Chunk, info) -> Later:
        """`prepare`, its results coming down with the tracker's next download (a
        device's; here: at once)."""
        return Later(self.prepare(chunk, info))

    def ride(self, *later: Later) -> None:
        """Have the tracker's next download carry the riders of `later` (a device's)."""

    def process(self, chunk: Chunk, prepared: Prepared | None = None,
                following: Callable[[], Chunk | None] | None = None) -> list[ChunkMeasurements]:
        """The measurements of the owned pairs of the chunks finished by this call, in
        order: none, this one's, or the one before's and this one's, under the open plan
        (a chunk without a pair has none). `prepared`: what `prepare` found in `chunk`,
        where already known (the delay's trial conversions repeat a chunk at other delays);
        `following`: gives the chunk processed next (None: none). With one, what `prepare`
        finds in the next chunk comes down before this chunk's tracker runs, and the next
        chunk's resampling is launched while the tracker's passes run (`meanwhile`): a
        device has the next chunk's work queued when this one's is done. This chunk's
        range check and survey wait for the next call and come down with its tracker's
        state."""
        plan = self.plan
        if plan is None:
            raise FmcwError("a chunk processor must be opened with a plan before it processes")
        self.chunks += 1
        info = plan.info
        ahead, self._ahead = self._ahead, None
        before, self._pending = self._pending, None
        if prepared is None and ahead is not None and ahead.chunk is chunk:
            prepared, found, resampled = ahead.prepared, ahead.found, ahead.resampled
        else:
            if prepared is None:
                prepared = self._memo.prepared(chunk, info, lambda: Later(self.prepare(chunk, info))).get()
            found, resampled = self._pairs(chunk, prepared, plan.lag), None
        if found is None:
            return [] if before is None else [self._finished(before, self._checked(before))]
        (xr, xf), times = resampled if resampled is not None else self._resampled(chunk, found)
        landed = None if before is None else self._memo.checked(before, info, self.check_and_survey_later)
        nxt = following() if following is not None else None
        if nxt is not None:
            # down before the tracker's passes
            coming = self._memo.prepared(nxt, info, lambda: self.prepare_later(nxt, info)).start()

            def launch_next() -> None:
                ready = coming.get()
                got = self._pairs(nxt, ready, plan.lag)
                self._ahead = Ahead(nxt, ready, got, None if got is None else self._resampled(nxt, got))

            self._meanwhile = launch_next
        self.ride(*(() if landed is None else (landed,)))
        res = pairing.track_pairs(xr, xf, times, plan.model, plan.searched(times), plan.options.iterations,
                                  plan.options.dechirp, self, plan.options.integrate)
        self.meanwhile()
        done = [] if before is None else [self._finished(before, landed.get())]
        mine = self._owned(chunk, prepared, found, res, (xr, xf), plan.lag)
        if nxt is None or (mine.check is None and mine.survey is None):
            return [*done, self._finished(mine, self._checked(mine))]
        self._pending = mine
        return done

    def meanwhile(self) -> None:
        """Run the host work that `process` left for the time the device spends on the
        tracker's passes (the next chunk's pairs and the launch of their resampling), once:
        a device processor calls it before it waits for the passes' results."""
        work, self._meanwhile = self._meanwhile, None
        if work is not None:
            work()

    def _resampled(self, chunk: Chunk, found: tuple) -> tuple[tuple, pairing.Times]:
        """The pairs `found` (`_pairs`) of `chunk` resampled (`resample_pairs`): (rising
        rows, falling rows) and their Times."""
        plan = self.plan
        hs, r, f, times = found
        jobs = [(hs.start[r], hs.length[r], plan.lut.u_rise), (hs.start[f], hs.length[f], plan.lut.u_fall)]
        rows, times = self.resample_pairs(chunk.beat, jobs, plan.window, times)
        return self._moving_only(rows), times

    def process_apart(self, held: Held) -> list[list[ChunkMeasurements]]:
        """`[process(chunk, prepared) for each of held]` in one pass, each chunk at its
        delay (`held.lags`): every chunk's pairs resampled and tracked together, each
        chunk's apart from the others' (pairing.Times.groups), under an open plan without
        range check or survey (the delay's trial conversions, the second look). Where the
        options set the integration, each chunk's windows end at its ends; where they
        leave it to the chunk, single half-sweeps are measured, and a chunk whose single
        pairs are too weak for that (pairing.track_pairs) is converted again on its own,
        as `process` does."""
        plan = self.plan
        if plan is None:
            raise FmcwError("a chunk processor must be opened with a plan before it processes")
        lags = held.lags or [plan.lag] * len(held.chunks)
        items = list(zip(held.chunks, held.prepared, lags, strict=True))
        if plan.check is not None or plan.survey or plan.still_half:
            # (rows without still echoes: a running mean must not reach across chunks)
            return [self._alone(*item) for item in items]
        k = plan.options.integrate
        found = [self._pairs(*item) for item in items]
        sides = [[], []]                                  # each direction's jobs, all chunks
        groups, rise, fall = [], [], []
        for at, got in zip(held.offsets, found, strict=True):
            if got is None:
                continue
            hs, r, f, times = got
            groups.append(sum(map(np.size, rise)))
            rise.append(times.rise)
            fall.append(times.fall)
            for side, idx in zip(sides, (r, f), strict=True):
                side.append((hs.start[idx] + at, hs.length[idx]))
        if not groups:
            self.chunks += len(items)
            return [[] for _ in items]
        # each chunk's half-sweeps a run of their own (resample_each) and a group of the
        # tracker's (Times.groups): converted as if alone, whatever chunks and delays are beside
        jobs = [(np.concatenate([a for a, _ in side]), np.concatenate([n for _, n in side]), u,
                 [a.size for a, _ in side])
                for side, u in zip(sides, (plan.lut.u_rise, plan.lut.u_fall), strict=True)]
        times = pairing.Times(np.concatenate(rise), np.concatenate(fall), np.array(groups))
        rows, times = self.resample_pairs(held.beat, jobs, plan.window, times)
        xr, xf = self._moving_only(rows)
        res = pairing.track_pairs(xr, xf, times, plan.model, plan.searched(times), plan.options.iterations,
                                  plan.options.dechirp, self, k or 1)
        out, slices = [], iter(group_slices(times.groups, times.rise.size))
        for (chunk, prepared, lag), got in zip(items, found, strict=True):
            one = None if got is None else res.take(next(slices))
            if one is not None and k is None and one.heard.mean() < integrate.AUTO_SHARE:
                out.append(self._alone(chunk, prepared, lag))
                continue
            self.chunks += 1
            if one is None:
                out.append([])
                continue
            none = (None, None, None)       # no range check, survey or bank
            out.append([self._finished(self._owned(chunk, prepared, got, one, None, lag), none)])
        return out

    def _alone(self, chunk: Chunk, prepared: Prepared, lag: float) -> list[ChunkMeasurements]:
        """`process(chunk, prepared)` at the delay `lag` (samples) of the open plan."""
        plan = self.plan
        self.plan = replace(plan, lag=lag)
        try:
            return self.process(chunk, prepared)
        finally:
            self.plan = plan

    def _pairs(self, chunk: Chunk, prepared: Prepared, lag: float) -> tuple | None:
        """The half-sweeps of `chunk` at the delay `lag` (samples), those of its pairs
        (the rising and falling ones that lie whole in the chunk, of one segment) and the
        pairs' Times (None: no pair)."""
        plan = self.plan
        hs = sync.half_sweeps(prepared.turns, lag)
        fits = resample.inside(hs.start, hs.length, plan.lut, chunk.beat.size)
        r = np.flatnonzero(hs.rising[:-1] & ~hs.rising[1:] & (hs.segment[:-1] == hs.segment[1:])
                           & fits[:-1] & fits[1:])
        if r.size == 0:
            return None
        f = r + 1
        fs = plan.info.sample_rate_hz
        return hs, r, f, pairing.Times((chunk.start + hs.centre[r]) / fs, (chunk.start + hs.centre[f]) / fs)

    def _owned(self, chunk: Chunk, prepared: Prepared, found: tuple, res: pairing.PairResult,
               rows: tuple | None, lag: float) -> Pending:
        """The owned pairs of `chunk` (`found`: `_pairs` at the delay `lag`, samples;
        `res`: their tracking) with their clipping, and their range check and survey to
        run where the plan asks (`rows`: the pairs' resampled half-sweeps, for the
        survey)."""
        plan = self.plan
        hs, r, f, times = found
        first = chunk.start + hs.start[r] + lag      # sync time of the pair's first turn
        own = owned(first, chunk.core_start, chunk.core_stop)
        sel = res.take(own)
        r, f = r[own], f[own]
        # the falling half-sweep starts where the rising one ends: one span per pair
        counts = prepared.clip_counts
        span = hs.start[f] + hs.length[f] - hs.start[r]
        clip = faults.clipped_share(hs.start[r], span, counts, chunk.beat.size) >= faults.CLIP_SHARE
        # the core's clipped codes, counted once over the capture
        core = slice((chunk.core_start - chunk.start) // faults.CLIP_BLOCK,
                     -(-(chunk.core_stop - chunk.start) // faults.CLIP_BLOCK))
        clipped = int(counts[core].sum(dtype=np.int64))
        return Pending(chunk.beat, (times.rise, times.fall), own, sel, clip, clipped,
                       RangeCheck.of(plan, hs, r, f, sel) if plan.check is not None and r.size else None,
                       self._survey(rows, res, np.arange(first.size)[own]) if plan.survey else None)

    def _finished(self, chunk: Pending, got: tuple) -> ChunkMeasurements:
        """The measurements of a `chunk` whose range check and survey gave `got`."""
        plan = self.plan
        checked, surveyed, banked = got
        sel, check, survey = chunk.result, chunk.check, chunk.survey
        alias = np.zeros(sel.distance.size, bool) if check is None else check.beyond(checked, sel, plan.lut)
        reason = faults.reasons(sel.valid, sel.heard, chunk.clip, alias, sel.continuous)
        sel.valid[:] = reason == faults.OK
        table = no_survey() if surveyed is None else {**survey.table(surveyed, chunk.times, plan.model),
                                                      **survey.points(banked, chunk.times, plan.model)}
        spectrum = (None, 0) if surveyed is None else survey.spectrum(surveyed)
        t_r, t_f = chunk.times
        return ChunkMeasurements(t_r[chunk.own], t_f[chunk.own], sel, reason, table, chunk.clipped_codes,
                                 *spectrum)

    def _moving_only(self, rows: list) -> tuple:
        """A chunk's (rising, falling) rows, their still echoes taken out where the plan
        says (Plan.still_half)."""
        half = self.plan.still_half
        return tuple(self.without_still(x, half) for x in rows) if half else tuple(rows)

    def without_still(self, rows, half: int):
        """`clutter.without_still` of `rows` (a device: where they are)."""
        return clutter.without_still(rows, half)

    def resample_pairs(self, codes, jobs, win, times: pairing.Times) -> tuple[list, pairing.Times]:
        """`resample_each` of a chunk's pairs (rising, falling) and their `times` for the
        tracker (a device: taken up with the positions)."""
        return self.resample_each(codes, jobs, win), times

    def _checked(self, chunk: Pending) -> tuple:
        """`check_and_survey(chunk)`, a range check the capture's chunks gave before kept."""
        return self._memo.checked(chunk, self.plan.info, lambda c: Later(self.check_and_survey(c))).get()

    def check_and_survey_later(self, chunk: Pending) -> Later:
        """`check_and_survey` of `chunk` (a device: launched, its inputs up by one copy,
        its results riding on the tracker's next download)."""
        return Later(self.check_and_survey(chunk))

    def check_and_survey(self, chunk: Pending) -> tuple[list | None, list | None, tuple | None]:
        """The range check's peaks of a measured `chunk`, (distance, SNR) of each side
        (measure_each), the survey's (ratio, centroid, found, sums) of each direction
        (survey_each) and the velocity bank's echoes (bank_each); None for those not
        asked (a device: one trip each way)."""
        checked, check, survey = None, chunk.check, chunk.survey
        if check is not None:
            xs = self.resample_each(chunk.beat, check.jobs, check.window)
            checked = self.measure_each(xs, (None, None), None, check.model, check.search)
        if survey is None:
            return checked, None, None
        return (checked, self.survey_each(*survey.args),
                None if survey.bank is None else self.bank_each(*survey.bank_args))

    def _survey(self, rows: tuple, res: pairing.PairResult, own: np.ndarray) -> Survey | None:
        """The survey of hidden echoes (echoes.hidden) in both half-sweeps of every
        SURVEY_STRIDE-th owned pair: their plain spectra and those de-chirped at the
        pair's velocity (None: nothing to survey)."""
        plan = self.plan
        m = plan.model
        idx = own[:: echoes.SURVEY_STRIDE]
        dets = (res.echoes_rise, res.echoes_fall)
        if idx.size == 0 or dets[0] is None:
            return None
        dists, others = (res.dist_rise, res.dist_fall), []
        for dist, det in zip(dists, dets, strict=True):
            o = det.take(idx).bin.copy()
            o[echoes.is_tracked(o * m.metres_per_bin, dist[idx, None])] = np.nan
            others.append(o)
        return Survey(idx, (rows, (m.beta_rise, m.beta_fall), res.velocity[idx], m.nfft, idx, plan.search.lo,
                            [d[idx] / m.metres_per_bin for d in (res.dechirped_rise, res.dechirped_fall)],
                            [d[idx] / m.metres_per_bin for d in dists], others),
                      idx[:: bank.BANK_STRIDE] if plan.bank else None)

class NumpyProcessor(ChunkProcessor):
    """The reference processor: every stage in numpy/scipy (`stages/`)."""

    name = "numpy"
    device = "numpy (CPU)"
    chunk_default = 1024       # periods a chunk: peak memory about 0.35 GB
    # numpy's steps run on one core each: two workers made 4 x 1 s captures 1.5-1.6x
    # faster on two cores
    batch_workers = 2

    def fork(self) -> NumpyProcessor:
        return NumpyProcessor()

    def intensity_each(self, channels, sample_rate_hz):
        return lpf.intensity_each(channels, sample_rate_hz)

    def fit_periods(self, y, z, shift, period, span):
        return delay.fit_periods(y, z, shift, period, span)

    def turning_points(self, codes, half_period):
        return sync.sync_turning_points(codes, half_period)

    def resample_each(self, codes, jobs, win):
        return [resample.resample(codes, *job[:3], win) for job in jobs]

    def clip_counts(self, codes, block, full_scale):
        return faults.clip_counts(codes, block, full_scale)
