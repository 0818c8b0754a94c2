"""The stream engine: capture -> chunks -> stages -> pairs -> track.

The capture is read in chunks of whole modulation periods with a margin of context
periods on each side. Every pair (a current-rising half-sweep and the falling one
after it) is owned by the chunk whose core holds its first turning point; the
tracker also sees the context pairs, so that continuity reaches across chunk
boundaries. Memory is bounded by the chunk, not the capture.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from . import __version__, echoes, target
from .capture import Capture, CaptureInfo
from .errors import CaptureError, FmcwError
from .numeric import median
from .options import said
from .refine import WIDTH_LIMIT, peak_width_ratio, refine_lag, stillest
from .stages import cfar, faults, kinematics, lpf, pairing, resample, spectrum, sync
from .stages.cfar import Detections
from .stages.lut import Lut, build_lut
from .stages.spectrum import Search
from .track import Track

DELAY_STRETCHES = 6           # stretches of the capture used to estimate the sync delay
DELAY_STRETCH_PERIODS = 200
CHECK_STRIDE = 4             # the 2N-point range check runs on every 4th pair near the limit,
CHECK_STRIDE_FAR = 16        # ... every 16th where every distance of the chunk is below
CHECK_NEAR = 0.75            # this share of the unambiguous range
PERIOD_TOLERANCE = 0.03      # sync period against /modulation frequency_hz
NEAR_LIMIT = 0.95             # distances beyond this share of the unambiguous range may be aliased


@dataclass(frozen=True)
class Options:
    """Processing parameters (the defaults follow the paper where it says)."""

    points: int = 1000            # resampling intervals per half-sweep
    min_range_m: float = 0.03     # peaks below are ignored (DC, intensity ramp, lens)
    max_range_m: float | None = None   # peaks beyond are ignored (a wall behind the target)
    dechirp: bool = True          # False: the paper's method alone
    iterations: int = 6           # de-chirp passes
    chunk_periods: int | None = None   # modulation periods per chunk core; None: the backend's
    context_periods: int = 64     # periods of context on each side of a core
    range_check: bool = True      # flag targets beyond the unambiguous range (2N resampling)
    chirp: str | None = None      # a calibration file (fmcw-cl calibrate) instead of G(I)
    integrate: int | None = None  # half-sweeps of a direction per measurement; None: from the SNR
    target: str = "auto"          # which echo is the target (fmcw_cl.target.RULES)
    target_near_m: float | None = None   # ... the one nearest to this distance


@dataclass(frozen=True)
class Plan:
    """Everything fixed for one capture before its samples are touched."""

    info: CaptureInfo
    options: Options
    lut: Lut
    window: np.ndarray
    model: pairing.DopplerModel
    search: Search      # the band and rule of the tracked peak
    lag: float          # samples the sync lags the optics
    lag_periods: int    # periods that voted for it
    lag_misfit: float   # rms misfit of those periods' triangles (clean: < 0.2)
    check: tuple | None = None   # (LUT, window, model) at 2N points for the range check
    lag_refined: bool = False    # moved to kinematic consistency (refine)
    lag_mismatch_mps: float = float("nan")   # what remains of the inconsistency there
    lag_sigma_samples: float = float("nan")  # the refined delay's standard uncertainty
    lag_sigma_mps: float = float("nan")      # ... as a velocity bias (m/s)
    lag_sigma_m: float = float("nan")        # ... as a distance bias (m)
    lag_intensity: float = float("nan")      # the first estimate, from the intensity triangle
    lag_at_m: float = float("nan")           # the target's mean distance where it was refined


class NumpyBackend(pairing.SpectrumOps):
    """The reference backend: every stage in numpy/scipy."""

    name = "numpy"
    device = "numpy (CPU)"
    chunk_default = 1024       # periods a chunk: peak memory about 0.35 GB
    # captures a batch converts at once (process_each): numpy's steps run on one core
    # each, two workers made 4 x 1 s captures 1.5-1.6x faster on two cores
    batch_workers = 2

    def intensity(self, codes, sample_rate_hz):
        return lpf.intensity(codes, sample_rate_hz)

    def fit_periods(self, y, z, shift, period, span):
        return sync.fit_periods(y, z, shift, period, span)

    def turning_points(self, codes, half_period):
        return sync.sync_turning_points(codes, half_period)

    def resample(self, codes, starts, lengths, u, win):
        return resample.resample(codes, starts, lengths, u, win)

    def resample_each(self, codes, jobs, win):
        """`resample` of each (starts, lengths, u) of `jobs` (a backend: one upload)."""
        return [self.resample(codes, *job, win) for job in jobs]

    def clip_counts(self, codes, block, full_scale):
        return faults.clip_counts(codes, block, full_scale)

    def fork(self) -> NumpyBackend:
        """A backend for another thread (`process_each`)."""
        return NumpyBackend()


def make_backend(name: str = "auto", device: str | None = None, warn=None):
    """The stage implementation: "numpy", "opencl", or "auto".

    "auto" takes OpenCL whenever a device is there (on PoCL, the CPU, it measured 2.4-3x
    faster end to end than numpy; see benchmarks/README.md). A failing OpenCL (no
    platform, a kernel that does not build) falls back to numpy with a one-line warning
    through `warn`; "opencl", or a `device` named, forces it and fails loudly.
    """
    if name == "numpy":
        return NumpyBackend()
    try:
        from .opencl.backend import OpenCLBackend

        return OpenCLBackend(device)
    except FmcwError as exc:
        if name == "opencl" or device is not None:     # what the user named is used or refused
            raise
        if warn:
            warn(f"warning: OpenCL unavailable ({exc}); using the numpy backend")
        return NumpyBackend()


def estimate_capture_delay(cap: Capture, backend=None) -> tuple[float, int, float]:
    """Sync lag (samples) pooled over stretches spread through the capture.

    Returns (lag, periods used, misfit); see `sync.combine_delays`. `backend` runs the
    low-pass and the per-period fit (default numpy).
    """
    backend = backend or NumpyBackend()
    info = cap.info
    hp = info.samples_per_period / 2
    length = int(DELAY_STRETCH_PERIODS * info.samples_per_period)
    starts = np.unique(np.linspace(0, max(0, info.samples - length), DELAY_STRETCHES).astype(np.int64))
    length = min(length, info.samples)
    # the stretches as rows (in a chunk slot, free until the chunks are read), low-passed
    # by one launch a channel
    beat, sy = (x.reshape(starts.size, length) for x in cap.slot(1, starts.size * length))
    for a, b, s in zip(starts, beat, sy, strict=True):
        cap.read_into(a, a + length, b, s)
    return sync.combine_delays(*sync.period_delays(beat, sy, info.sample_rate_hz, hp, backend.intensity,
                                                   backend.fit_periods))


def make_lut(info: CaptureInfo, points: int, chirp=None) -> Lut:
    """The LUT at `points`: from the capture's G(I), or from a chirp calibration."""
    lut = build_lut(info.tuning_current_a, info.tuning_frequency_hz, info.modulation.current_min_a,
                    info.modulation.current_max_a, points, info.refractive_index)
    if chirp is None:
        return lut
    from .chirp import chirp_lut
    return chirp_lut(chirp, points, float(np.mean(lut.nu_hz)), info.refractive_index)


def make_plan(cap: Capture, options: Options, lag: float | None = None, backend=None) -> Plan:
    """Fit G(I) (or read the chirp calibration), build the LUT and the Doppler model,
    estimate the sync delay (from the intensity triangle, refined on the target: `refine`).

    A known `lag` (samples the sync lags the optics, e.g. from a track) skips the
    estimate; `backend` runs its low-pass (default numpy).
    """
    info = cap.info
    chirp = None
    if options.chirp:
        from .chirp import check_chirp, read_chirp
        chirp = read_chirp(options.chirp)
        check_chirp(chirp, info, options.chirp)
    lut = make_lut(info, options.points, chirp)
    win = resample.window(options.points)
    nfft = spectrum.fft_length(options.points)
    model = pairing.doppler_model(lut, info.modulation.period_s / 2, nfft, win)
    search = make_search(options, lut, model)
    check_sync_period(cap)
    options = fit_chunks(options, info, backend)
    known = lag is not None
    lag, votes, misfit = estimate_capture_delay(cap, backend) if lag is None else (lag, 0, 0.0)
    if not np.isfinite(lag):
        raise CaptureError(info.path, "no laser intensity triangle in the beat channel: "
                                      "cannot align the sync to the optics")
    check = None
    if options.range_check:
        lut2 = make_lut(info, 2 * options.points, chirp)
        win2 = resample.window(2 * options.points)
        check = (lut2, win2, pairing.doppler_model(lut2, info.modulation.period_s / 2,
                                                   spectrum.fft_length(2 * options.points), win2))
    plan = Plan(info, options, lut, win, model, search, lag, votes, misfit, check, lag_intensity=lag)
    if not known and options.dechirp:          # the paper's method (--no-dechirp) as published
        plan = refine_lag(cap, plan, capture_parts, backend or NumpyBackend())
    return plan


def make_search(options: Options, lut: Lut, model: pairing.DopplerModel) -> Search:
    """The band [--min-range, --max-range) in padded bins (the tracked peak is its
    strongest); the plain pass lists every echo of the band."""
    unamb = lut.unambiguous_range_m
    lo, top = options.min_range_m, options.max_range_m
    if not 0 <= lo < 0.9 * unamb:
        raise FmcwError(f"{said('min_range', lo)} m is not below the unambiguous range "
                        f"{unamb:.3f} m of {said('points', options.points)}")
    if top is not None and not lo + 0.01 <= top:
        raise FmcwError(f"{said('max_range', top)} m must exceed {said('min_range', lo)} m "
                        "by at least 0.01 m")
    if top is not None and top > unamb:
        raise FmcwError(f"{said('max_range', top)} m lies beyond the unambiguous range {unamb:.3f} m of "
                        f"{said('points', options.points)}: a target there would alias (raise "
                        f"{said('points')})")
    half = model.nfft // 2
    lo = max(1, int(np.ceil(options.min_range_m / model.metres_per_bin)))
    hi = half if top is None else min(half, int(np.floor(top / model.metres_per_bin)) + 1)
    return Search(lo, hi, echoes=True)


def fit_chunks(options: Options, info: CaptureInfo, backend=None) -> Options:
    """The options with chunks of the backend's size unless given (`chunk_default`:
    per-chunk costs are fixed, so a device wants large ones), no larger than the
    backend's device holds (cores and contexts)."""
    wanted = options.chunk_periods or getattr(backend, "chunk_default", NumpyBackend.chunk_default)
    limit = getattr(backend, "chunk_periods", None)
    if limit is not None:
        fits = limit(info.samples_per_period, options.points) - 2 * options.context_periods - 2
        wanted = min(wanted, max(16, fits))
    return replace(options, chunk_periods=wanted)


def check_sync_period(cap: Capture, periods: int = 40) -> None:
    """The sync must be a triangle at the modulation frequency: a flat or saturated
    channel, or a period off `frequency_hz` by more than PERIOD_TOLERANCE, is refused."""
    info = cap.info
    hp = info.samples_per_period / 2
    a = max(0, info.samples // 2 - int(periods * hp))
    _, sy = cap.read(a, min(info.samples, a + int(2 * periods * hp)))
    cr = sync.crossings(sy, hp)
    alternate = cr.direction[1:] != cr.direction[:-1]
    whole = alternate[1:] & alternate[:-1]            # two crossings apart: one period
    if np.ptp(sy) < 64 or whole.sum() < 3:
        raise CaptureError(info.path, "no turning points in the sync channel (flat, saturated "
                                      "or not a triangle)")
    measured = float(np.median((cr.time[2:] - cr.time[:-2])[whole])) / info.sample_rate_hz
    nominal = info.modulation.period_s
    if abs(measured / nominal - 1) > PERIOD_TOLERANCE:
        raise CaptureError(info.path, f"the sync repeats every {measured * 1e6:.2f} us but /modulation "
                                      f"frequency_hz ({info.modulation.frequency_hz:g} Hz) says "
                                      f"{nominal * 1e6:.2f} us")


@dataclass
class _Pairs:
    """Owned pairs of one chunk (absolute times in samples)."""

    t_rise: np.ndarray
    t_fall: np.ndarray
    result: pairing.PairResult
    reason: np.ndarray
    survey: dict          # echoes.hidden of every SURVEY_STRIDE-th pair's half-sweeps
    clipped_codes: int = 0  # beat codes at full scale in the chunk's core (to a block at its edges)


def _chunk_pairs(plan: Plan, chunk, backend) -> _Pairs | None:
    info = plan.info
    hp = info.samples_per_period / 2
    tp = backend.turning_points(chunk.sync, hp)
    hs = sync.half_sweeps(tp, plan.lag)
    fits = resample.inside(hs.start, hs.length, plan.lut, chunk.beat.size)
    r = np.flatnonzero(hs.rising[:-1] & ~hs.rising[1:] & (hs.segment[:-1] == hs.segment[1:])
                       & fits[:-1] & fits[1:])
    if r.size == 0:
        return None
    f = r + 1
    xr, xf = backend.resample_each(chunk.beat, [(hs.start[r], hs.length[r], plan.lut.u_rise),
                                                (hs.start[f], hs.length[f], plan.lut.u_fall)], plan.window)
    fs = info.sample_rate_hz
    t_r = (chunk.start + hs.centre[r]) / fs
    t_f = (chunk.start + hs.centre[f]) / fs
    res = pairing.track_pairs(xr, xf, t_r, t_f, plan.model, plan.search, plan.options.iterations,
                              plan.options.dechirp, backend, plan.options.integrate)
    first = chunk.start + hs.start[r] + plan.lag      # sync time of the pair's first turn
    own = (first >= chunk.core_start) & (first < chunk.core_stop)
    sel = res.take(own)
    r, f = r[own], f[own]
    # the falling half-sweep starts where the rising one ends: one span per pair
    counts = backend.clip_counts(chunk.beat, faults.CLIP_BLOCK, info.full_scale + 1)     # 2^(bits-1)
    span = hs.start[f] + hs.length[f] - hs.start[r]
    share = faults.clipped_share(hs.start[r], span, counts, chunk.beat.size)
    clip = share >= faults.CLIP_SHARE
    # the core's clipped codes, counted once over the capture
    core = slice((chunk.core_start - chunk.start) // faults.CLIP_BLOCK,
                 -(-(chunk.core_stop - chunk.start) // faults.CLIP_BLOCK))
    clipped_codes = int(counts[core].sum(dtype=np.int64))
    alias = np.zeros(r.size, bool)
    if plan.check is not None and r.size:
        alias = _beyond_range(plan, chunk.beat, hs, r, f, sel, backend)
    reason = faults.reasons(sel.valid, sel.heard, clip, alias, sel.continuous)
    sel.valid[:] = reason == faults.OK
    survey = _survey(plan, backend, (xr, xf), (t_r, t_f), res, np.flatnonzero(own))
    return _Pairs(t_r[own], t_f[own], sel, reason, survey, clipped_codes)


SURVEY_KEYS = ("time_s", "ratio", "distance_m", "found")


def _survey(plan: Plan, backend, rows: tuple, times: tuple, res: pairing.PairResult,
            own: np.ndarray) -> dict:
    """The energy no sharp echo explains (echoes.hidden) in both half-sweeps of every
    SURVEY_STRIDE-th owned pair: their plain spectra and those de-chirped at the pair's
    velocity."""
    m = plan.model
    idx = own[:: echoes.SURVEY_STRIDE]
    dets = (res.echoes_rise, res.echoes_fall)
    if idx.size == 0 or dets[0] is None:
        return {k: np.zeros(0, bool if k == "found" else float) for k in SURVEY_KEYS}
    dists, others = (res.dist_rise, res.dist_fall), []
    for dist, det in zip(dists, dets, strict=True):
        o = det.take(idx).bin.copy()
        o[echoes.is_tracked(o * m.metres_per_bin, dist[idx, None])] = np.nan
        others.append(o)
    got = backend.survey_each(rows, (m.beta_rise, m.beta_fall), res.velocity[idx], m.nfft, idx,
                              plan.search.lo,
                              [d[idx] / m.metres_per_bin for d in (res.dechirped_rise, res.dechirped_fall)],
                              [d[idx] / m.metres_per_bin for d in dists], others)
    return {"time_s": np.concatenate([t[idx] for t in times]),
            "ratio": np.concatenate([g[0] for g in got]),
            "distance_m": np.concatenate([g[1] * m.metres_per_bin for g in got]),
            "found": np.concatenate([g[2] for g in got])}


def _beyond_range(plan: Plan, beat: np.ndarray, hs, r: np.ndarray, f: np.ndarray,
                  res: pairing.PairResult, backend) -> np.ndarray:
    """The 2N-point range check of pairs (r, f) with the tracker's results `res`, on
    the plain spectra (a target whose Doppler-shifted plain peak folds is flagged too:
    the plain pass that starts the tracker cannot measure it), run on every
    CHECK_STRIDE-th pair; a pair is flagged when a checked pair on either side of it
    is (a target crosses the range limit within a few pairs, where the N-point
    distance is ambiguous anyway). A target only crosses the limit through N-point
    distances near it: in a chunk whose plain and Doppler-free distances all stay below
    CHECK_NEAR of it, every CHECK_STRIDE_FAR-th pair is checked (a target beyond the
    range from the start is still found)."""
    lut2, win2, model2 = plan.check
    seen = np.concatenate([res.dist_rise, res.dist_fall, res.dechirped_rise, res.dechirped_fall,
                           res.distance])
    stride = CHECK_STRIDE if np.any(seen > CHECK_NEAR * plan.lut.unambiguous_range_m) else CHECK_STRIDE_FAR
    checked = np.unique(np.r_[np.arange(0, r.size, stride), r.size - 1])
    sides = ((r[checked], lut2.u_rise), (f[checked], lut2.u_fall))
    xs = backend.resample_each(beat, [(hs.start[idx], hs.length[idx], u) for idx, u in sides], win2)
    got = backend.measure_each(xs, (None, None), None, model2, Search(plan.search.lo, model2.nfft // 2))
    beyond = np.zeros(checked.size, bool)
    for (d2, s2), dn in zip(got, (res.dist_rise[checked], res.dist_fall[checked]), strict=True):
        beyond |= faults.beyond_range(d2, s2, plan.lut.unambiguous_range_m, pairing.SNR_MIN_DB, dn)
    right = np.searchsorted(checked, np.arange(r.size))          # first checked pair >= i
    left = np.searchsorted(checked, np.arange(r.size), side="right") - 1
    return beyond[right] | beyond[np.maximum(left, 0)]


def _fill_gaps(t_mid: np.ndarray, period: float) -> np.ndarray:
    """Times of whole periods missing between consecutive pairs (dropped sync)."""
    gaps = np.diff(t_mid)
    fill = [t_mid[i] + period * np.arange(1, int(round(gaps[i] / period)))
            for i in np.flatnonzero(gaps > 1.5 * period)]
    return np.concatenate(fill) if fill else np.zeros(0)


def core_samples(info: CaptureInfo, options: Options) -> int:
    """Samples in the core of one chunk (chunks start at multiples of this)."""
    return max(1, round(options.chunk_periods * info.samples_per_period))


def split_ranges(info: CaptureInfo, options: Options, seconds: float) -> list[tuple[int, int]]:
    """The capture cut into ranges of about `seconds` made of whole chunks, so that
    processing them apart gives exactly the chunks (and the track) of one pass."""
    core = core_samples(info, options)
    per = max(1, round(seconds * info.sample_rate_hz / core)) * core
    return [(a, min(a + per, info.samples)) for a in range(0, info.samples, per)]


class ReadAhead:
    """The items of `chunks`, the next one read by a thread while this one is processed
    (HDF5 reads and the kernels' waits release the GIL). The first read starts at once:
    a capture's first chunk is read while its plan is made. `close` (or leaving the
    `with`) waits for a read in flight, so that its slot is not handed on mid-read."""

    def __init__(self, chunks: Iterator) -> None:
        self._chunks, self._pool = chunks, ThreadPoolExecutor(1)
        self._ahead = self._pool.submit(next, chunks, None)

    def __iter__(self) -> Iterator:
        while (item := self._ahead.result()) is not None:
            self._ahead = self._pool.submit(next, self._chunks, None)
            yield item

    def close(self) -> None:
        self._pool.shutdown(wait=True, cancel_futures=True)

    def __enter__(self) -> ReadAhead:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def read_chunks(cap: Capture, options: Options, start: int = 0, stop: int | None = None) -> ReadAhead:
    """The chunks of `options` whose cores lie in samples [start, stop), read ahead into
    the capture's slots 0 and 1: a chunk's results keep none of its samples, and its
    kernels are done when the next one starts."""
    info = cap.info
    margin = int((options.context_periods + 1) * info.samples_per_period + sync.MAX_DELAY_SAMPLES + 8)
    return ReadAhead(cap.chunks(options.chunk_periods, margin, start, stop, slots=2))


def capture_parts(cap: Capture, plan: Plan, backend, start: int = 0, stop: int | None = None,
                  progress: Callable[[int, int, float], None] | None = None) -> list[_Pairs]:
    """The owned pairs of every chunk whose core lies in samples [start, stop)
    (`start` a multiple of `core_samples`), read ahead (`read_chunks`)."""
    parts: list[_Pairs] = []
    with read_chunks(cap, plan.options, start, stop) as ahead:
        for chunk in ahead:
            got = _chunk_pairs(plan, chunk, backend)
            if got is not None:
                parts.append(got)
            if progress:
                progress(chunk.core_stop, cap.info.samples, cap.info.sample_rate_hz)
    return parts


def process(path, options: Options | None = None, backend=None,
            progress: Callable[[int, int, float], None] | None = None) -> Track:
    """Convert one capture file into a Track (not yet written).

    Parameters
    ----------
    path : the capture file.
    options : processing parameters.
    backend : stage implementation (default NumpyBackend).
    progress : callable(samples_done, samples_total, sample_rate_hz), optional.
    """
    options = options or Options()
    backend = backend or NumpyBackend()
    started = time.perf_counter()
    with Capture(path) as cap:
        # the plan converts stretches itself (the delay's refinement), in the chunks' slots
        plan = make_plan(cap, options, backend=backend)
        parts = capture_parts(cap, plan, backend, progress=progress)
        track = assemble(plan, parts, backend, time.perf_counter() - started)
        choice = choose_target(plan, track)
        if choice.band_m != band_of(plan.options):          # the target alone in its band: again
            plan = with_band(plan, choice.band_m)
            parts = capture_parts(cap, plan, backend, progress=progress)
            track = assemble(plan, parts, backend, time.perf_counter() - started, choice)
        else:
            track = with_choice(plan, parts, backend, time.perf_counter() - started, track, choice)
        check_tuning(cap, plan, track, backend)
    return track


def with_choice(plan: Plan, parts: list[_Pairs], backend, seconds: float, track: Track,
                choice: target.Choice) -> Track:
    """The first conversion's `track` with a target `choice` that kept its band: made
    again where the choice makes pairs ambiguous, else its attributes added."""
    if choice.undecided:
        return assemble(plan, parts, backend, seconds, choice)
    track.attrs.update(choice.attrs())
    return track


def band_of(options: Options) -> tuple[float, float | None]:
    return options.min_range_m, options.max_range_m


def with_band(plan: Plan, band: tuple[float, float | None]) -> Plan:
    """The plan with the peak search in `band` (m)."""
    options = replace(plan.options, min_range_m=band[0], max_range_m=band[1])
    return replace(plan, options=options, search=make_search(options, plan.lut, plan.model))


def choose_target(plan: Plan, track: Track) -> target.Choice:
    """The target of a first conversion (fmcw_cl.target.choose)."""
    e = track.echoes
    level = median(e.snr_db[e.tracked]) if e.tracked.any() else median(track.sweep_snr_db)
    try:
        return target.choose(plan.options.target, plan.options.target_near_m, track.time_s, track.distance_m,
                             track.velocity_mps, track.valid, e, level, band_of(plan.options))
    except ValueError as exc:
        raise CaptureError(plan.info.path, str(exc)) from None


class _Stopped(Exception):
    """A capture of `process_each` abandoned because the batch stopped."""


def process_each(paths, options: Options | None = None, backend=None, workers: int | None = None,
                 progress: Callable[[int, int, int, float], None] | None = None
                 ) -> Iterator[tuple[Path, Track | FmcwError]]:
    """`process` of each capture of `paths`, `workers` at a time, the results in order.

    While one capture's kernels run, the next one is opened, planned and read and its
    host steps run (a device waits on the host for about a fifth of a capture's time
    on PoCL, most of it on a GPU). Each worker has its own `backend.fork()` (queue,
    kernels and buffers); at most `workers` captures are in flight or done and not
    yet yielded.

    Parameters
    ----------
    paths : the capture files.
    options, backend : as for `process` (the backend itself serves the first worker).
    workers : captures converted at once (1: one after the other, in this thread);
        None: the backend's `batch_workers`.
    progress : callable(index, samples_done, samples_total, sample_rate_hz), optional:
        the progress of capture `paths[index]`, called from its worker's thread, first
        with zeros when the capture starts.

    Yields
    ------
    (path, Track), or (path, FmcwError) for a capture that cannot be converted (the
    others still are). Any other exception stops the batch: captures in flight stop at
    their next chunk.
    """
    import queue
    import threading

    options = options or Options()
    backend = backend or NumpyBackend()
    workers = getattr(backend, "batch_workers", 1) if workers is None else workers
    paths = [Path(p) for p in paths]
    stop = threading.Event()
    free: queue.SimpleQueue = queue.SimpleQueue()
    for i in range(max(1, min(workers, len(paths)))):
        free.put(backend if i == 0 else backend.fork())

    def convert(i: int) -> Track | FmcwError:
        def tick(done: int, total: int, fs: float) -> None:
            if stop.is_set():
                raise _Stopped
            if progress:
                progress(i, done, total, fs)

        stages = free.get()
        try:
            if progress:
                progress(i, 0, 0, 0.0)          # started (its rate counts from here)
            return process(paths[i], options, stages, tick)
        except FmcwError as exc:
            return exc
        finally:
            free.put(stages)

    if workers <= 1:
        for i, path in enumerate(paths):
            yield path, convert(i)
        return
    pool = ThreadPoolExecutor(workers)
    try:
        running = {i: pool.submit(convert, i) for i in range(min(workers, len(paths)))}
        for i, path in enumerate(paths):
            got = running.pop(i).result()          # a yielded track is the caller's alone
            if i + workers < len(paths):
                running[i + workers] = pool.submit(convert, i + workers)
            yield path, got
    finally:
        stop.set()
        pool.shutdown(wait=True, cancel_futures=True)


# peaks this much wider than the window's own: the chirp is so far from its table that no
# distance is vouched for (a jump under 5 us of thermal lag: 2.24, distances to 96 mm off;
# under 2 us: 1.26 once the delay is refined, 0.72 mm at worst; a matching table: 1.02)
UNCALIBRATED_RATIO = 1.5
DELAY_BOUND_MPS = 0.002   # a refined delay whose velocity uncertainty is beyond this is warned of


def delay_reliable(plan: Plan) -> bool:
    """Whether the sync delay biases velocities by less than DELAY_BOUND_MPS (1 sigma):
    refined on the target and that certain, or, where no target run allowed it, a clean
    intensity triangle."""
    if plan.lag_refined:
        return bool(plan.lag_sigma_mps <= DELAY_BOUND_MPS)
    return bool(plan.lag_misfit <= sync.CLEAN_MISFIT)


def check_tuning(cap: Capture, plan: Plan, track: Track, backend) -> None:
    """Record how much wider than the window's own the peaks of the stillest stretch
    are (`tuning_peak_width_ratio`; `tuning_matches` is false beyond WIDTH_LIMIT): the
    sign that the laser's real chirp has left its G(I) table or its calibration."""
    ratio = peak_width_ratio(cap, plan, stillest(track.time_s, track.velocity_mps),
                             track.time_s, track.velocity_mps, backend)
    track.attrs["tuning_peak_width_ratio"] = ratio
    track.attrs["tuning_matches"] = bool(not ratio > WIDTH_LIMIT)
    track.attrs["uncalibrated_ratio"] = UNCALIBRATED_RATIO
    if ratio > UNCALIBRATED_RATIO and plan.options.dechirp:
        # distances cm off pass every neighbour test when all are off alike: none is valid
        track.reason[track.reason == faults.OK] = faults.UNCALIBRATED
        track.sweep_reason[track.sweep_reason == faults.OK] = faults.UNCALIBRATED
        track.valid[:] = False
        # the tracked span assemble took from the valid pairs: none is left
        track.attrs.update(invalid_uncalibrated=int(np.sum(track.reason == faults.UNCALIBRATED)),
                           target_tracked_m=np.full(2, np.nan))


def assemble(plan: Plan, parts: list[_Pairs], backend, seconds: float,
             choice: target.Choice | None = None) -> Track:
    """The track from the owned pairs of all chunks, in capture order: missing periods
    filled as invalid, pairs on an echo the target cannot be told from (`choice`)
    ambiguous, validity verified (faults.verified), acceleration, attributes.
    `seconds`: the processing time."""
    info, options = plan.info, plan.options
    if not parts:
        raise CaptureError(info.path, "no complete modulation period found in the sync channel")
    t_r = np.concatenate([p.t_rise for p in parts])
    t_f = np.concatenate([p.t_fall for p in parts])
    res = vars(pairing.PairResult.concat([p.result for p in parts]))
    t_mid = 0.5 * (t_r + t_f)
    period_s = info.modulation.period_s
    missing = _fill_gaps(t_mid, period_s)
    n_missing = missing.size
    times = np.concatenate([t_mid, missing])
    order = np.argsort(times, kind="stable")

    def with_gaps(x, fill):
        return np.concatenate([x, np.full(n_missing, fill, dtype=np.asarray(x).dtype)])[order]

    reason_owned = np.concatenate([p.reason for p in parts])
    if choice is not None:
        reason_owned = target.ambiguous(reason_owned, res["distance"], choice)
    if options.dechirp:         # the paper's method (--no-dechirp) is reported as the paper did
        reason_owned = faults.verified(t_mid, res["distance"], res["velocity"], reason_owned)
    res["valid"] = reason_owned == faults.OK
    valid = with_gaps(res["valid"], False)
    reason = with_gaps(reason_owned, faults.SYNC_GAP)
    dist = with_gaps(res["distance"], np.nan)
    vel = with_gaps(res["velocity"], np.nan)
    dist[~valid] = np.nan
    vel[~valid] = np.nan
    acc = kinematics.acceleration(vel, valid, period_s)
    integrated = with_gaps(res["integrated"], 0)
    varies = np.unique(integrated[valid]).size > 1

    def interleave(rise, fall):
        return np.stack([res[rise], res[fall]], axis=1).ravel()

    sweep_t = np.stack([t_r, t_f], axis=1).ravel()
    sweep_rising = np.tile([True, False], t_r.size)
    seen = echoes.table(sweep_t, sweep_rising, interleave("dist_rise", "dist_fall"),
                        interleave("dechirped_snr_rise", "dechirped_snr_fall"),
                        Detections.interleave(res["echoes_rise"], res["echoes_fall"]),
                        plan.model.metres_per_bin,
                        np.inf if options.max_range_m is None else options.max_range_m,
                        {k: np.concatenate([p.survey[k] for p in parts]) for k in SURVEY_KEYS})
    lut = plan.lut
    attrs = {
        "points": options.points,
        "fft_length": plan.model.nfft,
        "window": "hann",
        "dechirp": bool(options.dechirp),
        "dechirp_iterations": options.iterations if options.dechirp else 0,
        "min_range_m": options.min_range_m,
        "max_range_m": float("nan") if options.max_range_m is None else options.max_range_m,
        "cfar": f"cell-averaging, guard {cfar.GUARD} and {cfar.TRAIN} training bins a side, "
                f"false-alarm probability {cfar.PFA:g} per cell",
        **seen.attrs(),
        **(choice.attrs() if choice is not None else {}),
        "target_tracked_m": np.percentile(dist[valid], [1, 99]) if valid.any() else np.full(2, np.nan),
        "bandwidth_hz": lut.bandwidth_hz,
        "tuning": "chirp calibration" if options.chirp else "static G(I) table",
        "range_resolution_m": lut.range_resolution_m,
        # the distance scale is as good as the bandwidth: its uncertainty from the G(I)
        # table's scatter (NaN with a chirp calibration: as good as its distance)
        "tuning_fit_degree": int(lut.fit_degree),
        "tuning_table_scatter_hz": float(lut.table_scatter_hz),
        "scale_uncertainty_ppm": float(lut.scale_ppm),
        "scale_uncertainty_m": float(lut.scale_ppm * 1e-6 * np.median(dist[valid])) if valid.any()
        else float("nan"),
        "unambiguous_range_m": lut.unambiguous_range_m,
        "near_range_limit_pairs": int(np.sum(dist[valid] > NEAR_LIMIT * lut.unambiguous_range_m)),
        "range_check": bool(options.range_check),
        "chunk_periods": int(options.chunk_periods),
        # integration of weak echoes (stages.integrate): K half-sweeps of a direction per
        # output, an output every period all the same; its time resolution is K periods
        "modulation_period_s": period_s,
        "integration": "auto" if options.integrate is None else str(options.integrate),
        "integrated_sweeps_max": int(integrated.max(initial=1)),
        "time_resolution_s": period_s * float(integrated[valid].max(initial=1)),
        "reason_codes": ", ".join(f"{k} {v}" for k, v in faults.REASONS.items()),
        **{f"invalid_{name}": int(np.sum(reason == code)) for code, name in faults.REASONS.items() if code},
        "refractive_index": info.refractive_index,
        "clipped_codes": int(sum(p.clipped_codes for p in parts)),
        "clip_share_limit": faults.CLIP_SHARE,
        "sync_delay_samples": plan.lag,
        "sync_delay_periods_used": plan.lag_periods,
        "sync_delay_misfit": plan.lag_misfit,
        "sync_delay_reliable": delay_reliable(plan),
        "sync_delay_refined": bool(plan.lag_refined),
        "sync_delay_mismatch_mps": float(plan.lag_mismatch_mps),
        "sync_delay_intensity_samples": float(plan.lag_intensity),
        "sync_delay_uncertainty_samples": float(plan.lag_sigma_samples),
        "sync_delay_velocity_uncertainty_mps": float(plan.lag_sigma_mps),
        "sync_delay_distance_uncertainty_m": float(plan.lag_sigma_m),
        "sync_delay_refined_at_m": float(plan.lag_at_m),
        "sync_delay_velocity_bound_mps": DELAY_BOUND_MPS,
        "chirp": str(Path(options.chirp).resolve()) if options.chirp else "",
        "acceleration_smoothing": f"Savitzky-Golay derivative, order {kinematics.POLYORDER}, "
                                  f"{kinematics.WINDOW_PAIRS} pairs",
        "backend": backend.name,
        "device": backend.device,
        "software": f"fmcw-cl {__version__}",
        "source": str(Path(info.path).resolve()),
        "capture_duration_s": info.duration_s,
        "processing_time_s": seconds,
    }
    return Track(
        sweep_time_s=sweep_t,
        sweep_rising=sweep_rising, echoes=seen,
        sweep_distance_m=interleave("dist_rise", "dist_fall"),
        sweep_snr_db=interleave("snr_rise", "snr_fall"),
        sweep_distance_dechirped_m=interleave("dechirped_rise", "dechirped_fall"),
        sweep_snr_dechirped_db=interleave("dechirped_snr_rise", "dechirped_snr_fall"),
        time_s=times[order], distance_m=dist, velocity_mps=vel, acceleration_mps2=acc,
        valid=valid, attrs=attrs, reason=reason, sweep_reason=np.repeat(reason_owned, 2),
        integrated=integrated if varies else None, period_s=period_s)
