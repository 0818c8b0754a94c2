"""The OpenCL chunk processor: the low-pass, the sync delay's per-period fits, the sync's
block sums, level, hysteresis and line fits, the clipping counts, resampling, the
de-chirp/FFT/peak/echo stage and the tracker's passes with their regularisation on a
device. The resampled half-sweeps stay on the device; the following chunk's sync line
fits (the clipping counts riding with them) and the tracker's state come back, one
download each, the first before the tracker's passes and the next chunk's resampling
launched while they run; the range check's peaks with the survey's results ride on the
following chunk's tracker state (a copy of their own after the last chunk). The
turning-point grid, pairing,
ownership and the tracker's verdicts stay on the host (docs/pipeline.md). CPU devices get
the lanes variants of the kernels that have two.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from .. import pool
from ..chunk_state import Later, Prepared, clipping
from ..processor import ChunkProcessor
from ..spectrum_ops import NUMPY
from ..stages import bank, sync, verification
from ..stages.spectrum import fft_length
from . import clutter as k_clutter
from . import delay as k_delay
from . import faults as k_faults
from . import integrate as k_integrate
from . import lpf as k_lpf
from . import phase as k_phase
from . import resample as k_resample
from . import spectrum as k_spectrum
from . import survey as k_survey
from . import sync as k_sync
from . import track as k_track
from . import verify as k_verify
from .buffers import Buffers, DeviceRows, Packed, page_locked
from .context import Runtime, is_simulator, runtime


class OpenCLProcessor(ChunkProcessor):
    """The chunk processor on an OpenCL device (processor.ChunkProcessor's life cycle).

    Spectra are taken on the device where their transform fits its local memory, else
    by the numpy twins: rows resampled to a length whose transform does not fit come
    down once, as host arrays, and every spectrum step of theirs runs on the host (a
    GPU's 48 KB and the 8192-point range check of --points 2048).
    """

    name = "opencl"
    # periods a chunk: a chunk's launches, copies and host steps cost about the same
    # whatever its size (0.4 s of capture: 160 MB of codes, 65 MB of resampled rows)
    chunk_default = 8192
    programs = ("lpf", "delay", "sync", "resample", "spectrum", "integrate", "survey", "faults", "track",
                "verify", "copy", "phase", "clutter")

    def __init__(self, selector: str | None = None, rt: Runtime | None = None) -> None:
        super().__init__()
        self.rt = rt or runtime(selector)
        for program in self.programs:      # build now: a failure must surface before any work
            self.rt.program(program)
        for width in k_spectrum.widths(self.rt):
            self.rt.program("spectrum", width)
        self.bufs = Buffers(self.rt)
        self.device = self.rt.name
        if not (self.rt.zero_copy or is_simulator(self.rt.device)):
            # codes are read into page-locked memory, which the device copies by DMA
            pool.use(page_locked(self.rt.context))
        self._fitted = functools.partial(k_sync.fitted, self.rt, self.bufs)
        self._riders: tuple = ()        # what the tracker's next download carries (`ride`)
        self._turn = 0                  # the pairs' positions' buffer (`resample_pairs`)

    def _fits(self, nfft: int) -> bool:
        """Whether an nfft-point transform runs on this device (its local memory)."""
        return k_spectrum.fits(self.rt, nfft)

    def _passes_here(self, nfft: int) -> bool:
        """Whether the tracker's passes run on this device: its rows are here (the
        transform fits) and it has double precision."""
        return k_track.supported(self.rt) and self._fits(nfft)

    @property
    def batch_workers(self) -> int:
        """Captures a batch converts at once (batch.process_each). A GPU waits on the
        host for most of a capture: two overlap one's host steps with the other's
        kernels. A CPU device's kernels already keep its cores busy (PoCL, 2 cores: 1.75
        of them), and a second capture cost more CPU than it filled: one."""
        return 1 if self.rt.zero_copy else 2

    @property
    def reads_in_place(self) -> bool:
        """A CPU device reads host memory, the file's pages too (CL_MEM_USE_HOST_PTR); a
        GPU's codes go up from page-locked memory."""
        return self.rt.zero_copy

    def fork(self) -> OpenCLProcessor:
        """The same device for another thread (batch.process_each): its own queue,
        kernels and buffers; the programs are built once."""
        return OpenCLProcessor(rt=self.rt.stream())

    def chunk_limit(self, samples_per_period: float, points: int) -> int:
        """Modulation periods of one chunk that fit in a quarter of the device's memory
        (and each buffer in its largest allocation): the int16 beat of three chunks (the
        range check of one runs while the one after the next is resampled) and one sync,
        the resampled rows of both directions of three chunks (so the survey) and the
        range check's (2N points, a quarter of the pairs)."""
        dev = self.rt.device
        per_period = 8 * samples_per_period + 4 * points * (6 + 1)
        budget = min(dev.global_mem_size // 4, dev.max_mem_alloc_size)
        return max(1, int(budget // per_period))

    def finish(self) -> None:
        """Wait for the device (the launches are asynchronous)."""
        self.rt.finish()

    def close(self) -> None:
        """Let the plan and the capture's codes go, once the device is done with them."""
        self.rt.finish()
        self.bufs.forget_sources()
        super().close()

    def traffic(self) -> dict[str, int]:
        return self.rt.traffic.counts()

    def profile(self, on: bool) -> float | None:
        traffic = self.rt.traffic
        busy = None if on else traffic.busy_seconds()
        traffic.events = [] if on else None
        return busy

    def intensity_each(self, channels, sample_rate_hz):
        return k_lpf.intensity_each(self.rt, self.bufs, channels, sample_rate_hz)

    def fit_periods(self, y, z, shift, period, span):
        return k_delay.fit_periods(self.rt, self.bufs, y, z, shift, period, span)

    def period_delays(self, beat, sync_codes, sample_rate_hz, half_period):
        return k_delay.period_delays(self.rt, self.bufs, beat, sync_codes, sample_rate_hz, half_period)

    def turning_points(self, codes, half_period):
        return sync.sync_turning_points(codes, half_period, self._fitted)

    def resample_each(self, codes, jobs, win):
        return self._kept(k_resample.resample_each(self.rt, self.bufs, codes, jobs, win), win)

    def _kept(self, rows: list, win: np.ndarray) -> list:
        """Resampled `rows` left on the device where their spectra are taken here, else
        brought down."""
        return rows if self._fits(fft_length(win.size)) else [x.get() for x in rows]

    def prepare(self, chunk, info):
        """ChunkProcessor.prepare, the clipping counts coming down with the sync's line
        fits (one copy)."""
        return self.prepare_later(chunk, info).get()

    def prepare_later(self, chunk, info) -> Later:
        """ChunkProcessor.prepare_later: the sync's search and the clipping counts
        launched, their results riding on the tracker's next download (`ride`)."""
        half = info.samples_per_period / 2
        if chunk.sync.size < 2 * sync.fit_half_width(half) + 6:     # no crossing to fit
            return Later(ChunkProcessor.prepare(self, chunk, info))
        job = clipping(chunk, info)
        clip = k_faults.clip_rider(self.rt, self.bufs, *job)
        launched = k_sync.launch_fits(self.rt, self.bufs, chunk.sync, half, (clip,))
        if launched is None:
            return Later(ChunkProcessor.prepare(self, chunk, info))
        packed, finish = launched

        def prepared(views: list) -> Prepared:
            fitted = finish(views)
            turns = sync.sync_turning_points(chunk.sync, half, lambda *_: fitted)
            return Prepared(turns, self.clip_counts(*job) if clip.value is None else clip.value)

        return _riding(packed, prepared)

    def ride(self, *later: Later) -> None:
        self._riders = tuple(x.rider for x in later if x.rider is not None)

    def _landing(self) -> tuple:
        """The riders of the tracker's download (`ride`), handed over once."""
        riders, self._riders = self._riders, ()
        return riders

    def resample_pairs(self, codes, jobs, win, times):
        """ChunkProcessor.resample_pairs: where the tracker's passes run here, the pairs'
        times go up in the positions' copy, into one of two buffers by turns: the next
        chunk's go up while this one's tracker may still read its own (`meanwhile`)."""
        passes = self._passes_here(fft_length(win.size))
        self._turn ^= 1
        rows, extra = k_resample.resample_groups(self.rt, self.bufs, [(codes, jobs, win)],
                                                 k_track.times_up(times, passes), f"positions{self._turn}")
        _, times = k_track.times_down(extra, times, passes)
        return self._kept(rows[0], win), times

    def without_still(self, rows, half):
        return k_clutter.without_still(self.rt, self.bufs, rows, half)

    def check_and_survey_later(self, chunk):
        """ChunkProcessor.check_and_survey_later: where the spectra of `chunk`'s range
        check and survey run here, their positions and inputs go up by one copy, their
        kernels are launched, and their results ride on the tracker's next download."""
        if not self._checked_here(chunk):
            return super().check_and_survey_later(chunk)
        return _riding(*self._check_and_survey(chunk))

    def _checked_here(self, chunk) -> bool:
        """Whether `chunk` has a range check or survey, and the spectra of both run here."""
        return ((chunk.check is not None or chunk.survey is not None)
                and (chunk.check is None or self._fits(chunk.check.model.nfft))
                and (chunk.survey is None or self._fits(chunk.survey.args[3])))

    def clip_counts(self, codes, block, full_scale):
        return k_faults.clip_counts(self.rt, self.bufs, codes, block, full_scale)

    def measure(self, x, beta, v, model, search, rows=None, direction=0):
        if search.bands is not None:        # the one direction's bands, as a pair's first
            search = replace(search, bands=search.bands[direction: direction + 1])
        return self.measure_each([x], [beta], v, model, search, rows)[0]

    def measure_each(self, xs, betas, v, model, search, rows=None, riders: tuple = (), times=None,
                     meanwhile=None):
        """Twin: spectrum_ops.SpectrumOps.measure_each; one upload of the rows and velocities,
        one download of every result (and of `riders`); plain rows paired within the groups
        of `times` (pairing.Times, their copy on the device where it went up)."""
        if not self._fits(model.nfft):
            return NUMPY.measure_each(xs, betas, v, model, search, rows)
        jobs = [(x, b, None) for x, b in zip(xs, betas, strict=True)]
        groups, device = (None, None) if times is None else (times.groups, times.device)
        got = k_spectrum.measure_each(self.rt, self.bufs, jobs, v, model.nfft, search.lo, search.hi,
                                      index=rows, echoes=search.echoes, riders=riders, groups=groups,
                                      d_groups=None if device is None else device[3], meanwhile=meanwhile,
                                      bands=k_spectrum.band_buffers(self.bufs, search, tuple(range(len(xs)))))
        return _measured(got, model, search)

    def track(self, rows, times, model, search, iterations, single):
        """Twin: spectrum_ops.SpectrumOps.track; the passes on the device (`_passes_here`),
        their state read by one copy, which carries the riders of `ride`."""
        if not (single and iterations > 0 and self._passes_here(model.nfft)):
            return super().track(rows, times, model, search, iterations, single)
        first, state = k_track.track(self.rt, self.bufs, rows, times, model, search, iterations,
                                     self._landing(), self.meanwhile)
        return tuple(_measured(first, model, search)), state

    def integrated(self, rows, times, model, search, iterations, k):
        """Twin: spectrum_ops.SpectrumOps.integrated; the passes on the device (`_passes_here`),
        their state read by one copy."""
        if not (iterations > 0 and self._passes_here(model.nfft)):
            return super().integrated(rows, times, model, search, iterations, k)
        return k_track.integrated(self.rt, self.bufs, rows, times, model, search, iterations, k,
                                  self._landing())

    def plain_pass(self, rows, model, search, times=None):
        """Twin: spectrum_ops.SpectrumOps.plain_pass; its download carries the riders of `ride`,
        and `meanwhile`'s work runs before it."""
        return self.measure_each(rows, (model.beta_rise, model.beta_fall), None, model, search,
                                 riders=self._landing(), times=times, meanwhile=self.meanwhile)

    def _verifies(self, pairs: int) -> bool:
        """Whether the verification's tests of `pairs` run on this device: it has double
        precision, and they are many (k_verify.PAIRS_MIN)."""
        return k_track.supported(self.rt) and pairs >= k_verify.PAIRS_MIN

    def residuals(self, t, dist, vel, trusted, rows=None):
        """Twin: spectrum_ops.SpectrumOps.residuals; every pair's on the device (`_verifies`),
        where the host would take them for every pair too (verification.every_row)."""
        if not (self._verifies(t.size) and verification.every_row(rows, t.size)):
            return super().residuals(t, dist, vel, trusted, rows)
        resid, support = k_verify.residuals(self.rt, self.bufs, t, dist, vel, trusted)
        return (resid, support) if rows is None else (resid[rows], support[rows])

    def disagreed(self, t, dist, vel, ok):
        """Twin: spectrum_ops.SpectrumOps.disagreed; on the device (`_verifies`)."""
        if not self._verifies(t.size):
            return super().disagreed(t, dist, vel, ok)
        return k_verify.disagreed(self.rt, self.bufs, t, dist, vel, ok)

    def power(self, x, beta, v, nfft, rows=None):
        """Power spectra of rows of x (plain, or de-chirped at v); twin: doppler.power."""
        if not self._fits(nfft):
            return NUMPY.power(x, beta, v, nfft, rows)
        _, spec, _ = k_spectrum.measure(self.rt, self.bufs, x, beta, v, nfft, 1, keep_power=True, index=rows)
        return spec

    def power_each(self, jobs, nfft):
        """Twin: spectrum_ops.SpectrumOps.power_each; every spectrum comes back by one copy."""
        if not self._fits(nfft):
            return NUMPY.power_each(jobs, nfft)
        each = [([(x, beta, None)], np.shape(x)[0], v) for x, beta, v in jobs]
        parts = [k_spectrum.parts(one, rows, nfft, keep_power=True) for one, rows, _ in each]
        out = Packed(self.bufs, "power", [p for part in parts for p in part])
        firsts = np.cumsum([0, *map(len, parts)])[:-1].tolist()
        for (one, _, v), first in zip(each, firsts, strict=True):
            k_spectrum.measure_each(self.rt, self.bufs, one, v, nfft, 1, keep_power=True, out=out,
                                    first=first)
        views = out.download()
        return [k_spectrum.results(views[first: first + len(part)], one, rows, nfft, keep_power=True)[0][1]
                for (one, rows, _), part, first in zip(each, parts, firsts, strict=True)]

    def spectra(self, x, beta, v, nfft, rows=None, store=None):
        """`store` (DeviceRows of power spectra, new when None) with the rows `rows`
        replaced by their power spectra; twin: spectrum_ops.SpectrumOps.spectra."""
        if not self._fits(nfft):
            return NUMPY.spectra(x, beta, v, nfft, rows, store)
        if store is None:
            store = DeviceRows(self.bufs, x.shape[0], nfft // 2)
        k_spectrum.measure(self.rt, self.bufs, x, beta, v, nfft, 1, index=rows, store=store)
        return store

    def phasors_each(self, xs, betas, v, bins, nfft):
        """Twin: spectrum_ops.SpectrumOps.phasors_each; on the device where the rows are."""
        if not self._fits(nfft):
            return NUMPY.phasors_each(xs, betas, v, bins, nfft)
        return k_phase.phasors_each(self.rt, self.bufs, xs, betas, v, bins, nfft)

    def survey(self, x, beta, v, nfft, rows, lo, tracked_bin, plain_bin, others):
        return self.survey_each([x], [beta], v, nfft, rows, lo, [tracked_bin], [plain_bin], [others])[0]

    def survey_each(self, xs, betas, v, nfft, rows, lo, tracked_bins, plain_bins, others):
        """Twin: spectrum_ops.SpectrumOps.survey_each; the spectra stay on the device, the rows,
        velocities and bins go up in one copy, the results come back in one."""
        if not self._fits(nfft):
            return NUMPY.survey_each(xs, betas, v, nfft, rows, lo, tracked_bins, plain_bins, others)
        bins = list(zip(tracked_bins, plain_bins, others, strict=True))
        d_in = k_survey.upload(self.bufs, bins, _picked(rows, v))
        return self._surveyed(xs, betas, v, nfft, rows, lo, bins, d_in)

    def _surveyed(self, xs, betas, v, nfft, rows, lo, bins, d_in, out=None, first=0):
        """survey_each's launches, its inputs `d_in` already up (`_picked`, then `bins`):
        each direction's spectra plain (de-chirped at v along a zero basis: the phase is
        0) and de-chirped at v, left on the device, then k_survey.hidden_each (into `out`
        from part `first`, when given)."""
        jobs, spectra = [], []
        for x, beta in zip(xs, betas, strict=True):
            both = [DeviceRows(self.bufs, np.size(rows), nfft // 2) for _ in range(2)]
            jobs += [(x, k_spectrum.zeros(x.shape[1]), both[0]), (x, beta, both[1])]
            spectra.append(both)
        k_spectrum.measure_each(self.rt, self.bufs, jobs, v, nfft, 1, index=rows, scatter=False,
                                picked=d_in[:2])
        per = [(*sp, *b) for sp, b in zip(spectra, bins, strict=True)]
        return k_survey.hidden_each(self.rt, self.bufs, per, lo, d_in[2:], out, first)

    def bank_each(self, xs, betas, rows, nfft, lo):
        """Twin: spectrum_ops.SpectrumOps.bank_each; the picks go up in one copy, every
        echo comes back in one."""
        if not self._fits(nfft):
            return NUMPY.bank_each(xs, betas, rows, nfft, lo)
        idx, v = bank.picks(rows)
        jobs = [(x, b, None) for x, b in zip(xs, betas, strict=True)]
        got = k_spectrum.measure_each(self.rt, self.bufs, jobs, v, nfft, lo, index=idx, echoes=True)
        return tuple(det for _, _, det in got)

    def check_and_survey(self, chunk):
        """ChunkProcessor.check_and_survey in one trip each way: the survey's inputs go up
        with the check's resampling positions; both results come down by one copy."""
        if not self._checked_here(chunk):
            return super().check_and_survey(chunk)
        out, read = self._check_and_survey(chunk)
        return read(out.download())

    def _check_and_survey(self, chunk) -> tuple[Packed, Callable]:
        """The range check of `chunk` resampled (its positions up with the survey's inputs,
        `_survey_inputs`, by one copy), and the spectra and peaks of both launched into one
        Packed; and `read(views)`: (checked, surveyed) from its parts once down."""
        groups = [] if chunk.check is None else [(chunk.beat, chunk.check.jobs, chunk.check.window)]
        also = () if chunk.survey is None else _survey_inputs(chunk.survey)
        rows, inputs = k_resample.resample_groups(self.rt, self.bufs, groups, also, "check_positions")
        checked = rows[0] if groups else None
        first = []
        if checked is not None:
            check = chunk.check
            jobs = [(x, None, None) for x in checked]
            sweeps, nfft2 = jobs[0][0].shape[0], check.model.nfft
            first = k_spectrum.parts(jobs, sweeps, nfft2)
        survey = chunk.survey
        rest = [] if survey is None else k_survey.parts([np.size(survey.args[4])] * len(survey.args[0]),
                                                         survey.args[3] // 2)
        banked = survey is not None and survey.bank is not None
        if banked:          # the velocity bank's echoes, after the survey's parts
            xs, betas, picked, nfft, lo = survey.bank_args
            idx, trial = bank.picks(picked)
            bank_jobs = [(x, b, None) for x, b in zip(xs, betas, strict=True)]
            bank_parts = k_spectrum.parts(bank_jobs, idx.size, nfft, echoes=True)
        at = len(first) + len(rest)
        out = Packed(self.bufs, "check_survey", first + rest + (bank_parts if banked else []))
        if checked is not None:
            k_spectrum.measure_each(self.rt, self.bufs, jobs, None, nfft2, check.search.lo, check.search.hi,
                                    out=out)
        if survey is not None:
            xs, betas, v, nfft, rows, lo, *_ = survey.args
            self._surveyed(xs, betas, v, nfft, rows, lo, _bins(survey), inputs, out, len(first))
        if banked:
            k_spectrum.measure_each(self.rt, self.bufs, bank_jobs, trial, nfft, lo, index=idx, echoes=True,
                                    out=out, first=at)

        def read(views: list) -> tuple:
            got = None
            if checked is not None:
                got = _measured(k_spectrum.results(views[: len(first)], jobs, sweeps, nfft2), check.model,
                                check.search)
            if survey is None:
                return got, None, None
            dets = None if not banked else tuple(
                det for _, _, det in k_spectrum.results(views[at:], bank_jobs, idx.size, nfft, echoes=True))
            return got, k_survey.results(views[len(first): at]), dets

        return out, read

    def integrated_peaks(self, store, disp, k, search, bounds=None, direction=0):
        if not self._fits(2 * store.shape[1]):       # (pairs, nfft / 2) power spectra
            return NUMPY.integrated_peaks(store, disp, k, search, bounds, direction)
        return k_integrate.peaks(self.rt, self.bufs, store, disp, k, search, bounds, direction)


def _riding(packed: Packed, make: Callable[[list], object]) -> Later:
    """The results `make(views)` of the parts of `packed`, riding on the tracker's next
    download (`ride`), or by a copy of their own where none took them (begun early:
    Later.start)."""
    def begin() -> Callable[[], object]:
        landed = packed.download_later()
        return lambda: make(landed())

    return Later(rider=packed.rider(), land=lambda raw: make(packed.read(raw)),
                 fetch=lambda: make(packed.download()), begin=begin)


def _bins(survey) -> list[tuple]:
    """The (tracked, plain, others) bins of each direction of a Survey."""
    return list(zip(*survey.args[6:9], strict=True))


def _survey_inputs(survey) -> tuple:
    """A Survey's inputs as k_survey takes them up."""
    return k_survey.input_arrays(_bins(survey), _picked(survey.args[4], survey.args[2]))


def _picked(rows, v) -> tuple[np.ndarray, np.ndarray]:
    """The rows picked and their velocities as the kernels take them (int32, float32)."""
    return np.asarray(rows, np.int32), np.asarray(v, np.float32)


def _measured(got: list, model, search) -> list[tuple]:
    """doppler.measure's results from k_spectrum.measure_each's: distance (m), SNR (dB),
    and the echoes with `search.echoes`."""
    return [(pk.bin * model.metres_per_bin, pk.snr_db, *([det] if search.echoes else []))
            for pk, _, det in got]
