"""The plan of one capture: everything fixed before its samples are converted.

The G(I) table's fit (or a chirp calibration) gives the LUT and the Doppler model; the
options give the peak search's band and the chunk size; the sync's period is checked;
the sync delay is estimated from the intensity triangle and refined on the target's own
kinematics (`refine`).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, replace

import numpy as np

from .capture import Capture
from .capture_format import CaptureInfo
from .chirp import Chirp, check_chirp, chirp_lut, read_chirp
from .course import Course, searched
from .errors import CaptureError, FmcwError
from .motion import SMOOTH, Motion
from .options import Options, said
from .processor import ChunkProcessor, NumpyProcessor
from .refine import refine_lag
from .stages import delay, doppler, resample, spectrum, sync
from .stages.lut import Lut, build_lut
from .stages.spectrum import Search

DELAY_STRETCHES = 6           # stretches of the capture used to estimate the sync delay
DELAY_STRETCH_PERIODS = 200
PERIOD_TOLERANCE = 0.03      # sync period against /modulation frequency_hz: refused beyond
PERIOD_WARN = 1e-3           # ... stated beyond (the measurement's own scatter: 3e-6)
SWAPPED_ROUGHNESS = 0.05     # a sync this rough, and rougher than the beat: the channels swapped
DELAY_BOUND_MPS = 0.002   # a refined delay whose velocity uncertainty is beyond this is warned of
TABLE, CALIBRATION, OWN_REST = "static G(I) table", "chirp calibration", "chirp calibrated on its own rest"


@dataclass(frozen=True)
class Plan:
    """Everything fixed for one capture before its samples are touched."""

    info: CaptureInfo
    options: Options
    lut: Lut
    window: np.ndarray
    model: doppler.DopplerModel
    search: Search      # the band and rule of the tracked peak
    lag: float          # samples the sync lags the optics
    lag_periods: int    # periods that voted for it
    lag_misfit: float   # rms misfit of those periods' triangles (clean: < 0.2)
    check: tuple | None = None   # (LUT, window, model) at 2N points for the range check
    survey: bool = True          # survey hidden echoes (a trial conversion of `refine` does not)
    bank: bool = False           # ... and the fast movers (stages.bank): the first conversion's
    lag_refined: bool = False    # moved to kinematic consistency (refine)
    lag_mismatch_mps: float = float("nan")   # what remains of the inconsistency there
    lag_sigma_samples: float = float("nan")  # the refined delay's standard uncertainty
    lag_sigma_mps: float = float("nan")      # ... as a velocity bias (m/s)
    lag_sigma_m: float = float("nan")        # ... as a distance bias (m)
    lag_intensity: float = float("nan")      # the first estimate, from the intensity triangle
    lag_intensity_sigma: float = float("nan")   # ... its standard error (the periods' spread)
    lag_at_m: float = float("nan")           # the target's mean distance where it was refined
    tuning: str = TABLE                      # where the LUT comes from: TABLE, CALIBRATION or OWN_REST
    chirp: Chirp | None = None               # the chirp of CALIBRATION or OWN_REST
    period_ratio: float = 1.0    # the sync's measured period over the attributes' (check_sync_period)
    motion: Motion = SMOOTH      # the windows the pairs are fitted over (fmcw_cl.motion; `refine` chooses)
    still_half: int = 0          # pairs each side of the running mean taken from the rows (stages.clutter;
                                 # 0: none): an object that moves among fixed ones (fmcw_cl.scene)
    course: Course | None = None  # each pair's own band along an object's course (None: `search`'s)

    def searched(self, times) -> Search:
        """The search of the pairs of `times` (stages.pairing.Times): each pair's band
        along the plan's course, where it has one."""
        return searched(self.search, self.course, times.rise, times.fall, self.model.metres_per_bin)

    def with_band(self, band: tuple[float, float | None]) -> Plan:
        """The plan with the peak search in `band` (m), the same for every pair (no course)."""
        options = replace(self.options, min_range=band[0], max_range=band[1])
        search = replace(make_search(options, self.lut, self.model), reach=self.motion.reach)
        return replace(self, options=options, search=search, course=None)

    def with_motion(self, motion: Motion) -> Plan:
        """The plan fitting its pairs over `motion`'s windows (the tracker's among them)."""
        return replace(self, motion=motion, search=replace(self.search, reach=motion.reach))

    def with_chirp(self, chirp: Chirp, tuning: str, scale_std: float = float("nan")) -> Plan:
        """The plan resampled on `chirp` (its sync delay kept: a chirp is measured
        against half-sweeps at a delay), the distance scale's relative uncertainty
        `scale_std` (1 sigma). A band whose top lies beyond the chirp's unambiguous
        range ends with the range: it was checked against the tuning it had, and a
        wider bandwidth ends the range sooner (a rest calibration's chirp: 0.335 m
        against a band to 0.3353 m)."""
        options = self.options
        top = options.band_m[1]
        if top is not None and top > make_lut(self.info, options.points, chirp).unambiguous_range_m:
            options = replace(options, max_range=None)
        parts = tuned(self.info, options, chirp)
        parts["lut"] = replace(parts["lut"], scale_std=scale_std)
        parts["search"] = replace(parts["search"], reach=self.motion.reach)
        return replace(self, **parts, options=options, tuning=tuning)


def estimate_capture_delay(cap: Capture, processor: ChunkProcessor | None = None
                           ) -> tuple[float, int, float, float]:
    """Sync lag (samples) pooled over stretches spread through the capture.

    Returns (lag, periods used, misfit, standard error); see `delay.combine_delays`. `processor` runs the
    low-pass and the per-period fit (default numpy).
    """
    processor = processor or NumpyProcessor()
    info = cap.info
    hp = info.samples_per_period / 2
    length = int(DELAY_STRETCH_PERIODS * info.samples_per_period)
    starts = np.unique(np.linspace(0, max(0, info.samples - length), DELAY_STRETCHES).astype(np.int64))
    length = min(length, info.samples)
    # the stretches as rows (in a chunk slot, free until the chunks are read), low-passed
    # by one launch a channel
    beat, sy = (x.reshape(starts.size, length) for x in cap.slot(1, starts.size * length))
    cap.read_spans([(a, a + length) for a in starts], list(beat), list(sy))
    return delay.combine_delays(*processor.period_delays(beat, sy, info.sample_rate_hz, hp))


def make_lut(info: CaptureInfo, points: int, chirp=None) -> Lut:
    """The LUT at `points`: from the capture's G(I), or from a chirp calibration."""
    lut = build_lut(info.tuning_current_a, info.tuning_frequency_hz, info.modulation.current_min_a,
                    info.modulation.current_max_a, points, info.refractive_index)
    if chirp is None:
        return lut
    return chirp_lut(chirp, points, float(np.mean(lut.nu_hz)), info.refractive_index)


def make_plan(cap: Capture, options: Options, lag: float | None = None,
              processor: ChunkProcessor | None = None) -> Plan:
    """Fit G(I) (or read the chirp calibration), build the LUT and the Doppler model,
    estimate the sync delay (from the intensity triangle, refined on the target: `refine`).

    A known `lag` (samples the sync lags the optics, e.g. from a track) skips the
    estimate; `processor` runs the delay's stages and trial conversions (default numpy).
    """
    processor = processor or NumpyProcessor()
    info = cap.info
    chirp = None
    if options.chirp:
        chirp = read_chirp(options.chirp)
        check_chirp(chirp, info, options.chirp)
    parts = tuned(info, options, chirp)
    period_ratio = check_sync_period(cap)
    options = fit_chunks(options, info, processor)
    known = lag is not None
    lag, votes, misfit, spread = (estimate_capture_delay(cap, processor) if lag is None
                                  else (lag, 0, 0.0, float("nan")))
    if not np.isfinite(lag):
        raise CaptureError(info.path, "no laser intensity triangle in the beat channel: "
                                      "cannot align the sync to the optics")
    plan = Plan(info, options, lag=lag, lag_periods=votes, lag_misfit=misfit, lag_intensity=lag,
                lag_intensity_sigma=spread,
                tuning=TABLE if chirp is None else CALIBRATION, period_ratio=period_ratio, **parts)
    if not known and options.dechirp:          # the paper's method (--no-dechirp) as published
        plan = refine_lag(cap, plan, processor)
    return plan


def tuned(info: CaptureInfo, options: Options, chirp: Chirp | None) -> dict:
    """The Plan's fields that follow from the tuning (the G(I) table, or `chirp`): the
    LUT, window, Doppler model, peak search, the range check's 2N-point versions and the
    chirp itself."""
    half_sweep_s = info.modulation.period_s / 2
    lut = make_lut(info, options.points, chirp)
    win, model = shaped(lut, half_sweep_s)
    check = None
    if options.range_check:
        lut2 = make_lut(info, 2 * options.points, chirp)
        check = (lut2, *shaped(lut2, half_sweep_s))
    return {"lut": lut, "window": win, "model": model, "search": make_search(options, lut, model),
            "check": check, "chirp": chirp}


@functools.lru_cache(maxsize=16)
def shaped(lut: Lut, half_sweep_s: float) -> tuple[np.ndarray, doppler.DopplerModel]:
    """The window and the Doppler model of `lut` (half-sweeps of `half_sweep_s` s), made
    once per LUT object (build_lut caches those): capture after capture the same
    read-only arrays, which a device keeps from its first upload (Buffers.constant)."""
    win = resample.window(lut.points)
    return win, doppler.doppler_model(lut, half_sweep_s, spectrum.fft_length(lut.points), win)


MIN_RANGE_SHARE = 0.9   # a band starts below this share of the unambiguous range


def make_search(options: Options, lut: Lut, model: doppler.DopplerModel) -> Search:
    """The band [min_range, max_range) in padded bins (the tracked peak is its
    strongest); the plain pass lists every echo of the band. The band must lie inside
    the unambiguous range of this capture's bandwidth."""
    unamb = lut.unambiguous_range_m
    lo, top = options.band_m
    if not lo < MIN_RANGE_SHARE * unamb:
        raise FmcwError(f"{said('min_range', lo)} m is not below the unambiguous range "
                        f"{unamb:.3f} m of {said('points', options.points)}")
    if top is not None and top > unamb:
        raise FmcwError(f"{said('max_range', top)} m lies beyond the unambiguous range {unamb:.3f} m of "
                        f"{said('points', options.points)}: a target there would alias (raise "
                        f"{said('points')})")
    near = options.target_near
    if near is not None and not lo <= near < (unamb if top is None else top):
        where = f"beyond the unambiguous range {unamb:.3f} m of {said('points', options.points)}" \
            if near >= unamb else "outside the band [" + said("min_range", lo) + (
                f" m, {said('max_range', top)} m)" if top is not None else " m, ...)")
        raise FmcwError(f"{said('target_near', near)} m lies {where}: no echo there can be the target")
    half = model.nfft // 2
    lo = max(1, int(np.ceil(lo / model.metres_per_bin)))
    hi = half if top is None else min(half, int(np.floor(top / model.metres_per_bin)) + 1)
    return Search(lo, hi, echoes=True)


def fit_chunks(options: Options, info: CaptureInfo, processor: ChunkProcessor) -> Options:
    """The options with chunks of the processor's size unless given (`chunk_default`:
    per-chunk costs are fixed, so a device wants large ones), no larger than the
    processor's device holds (`chunk_limit`)."""
    wanted = options.chunk_periods or processor.chunk_default
    limit = processor.chunk_limit(info.samples_per_period, options.points)
    if limit is not None:
        wanted = min(wanted, max(16, limit - 2 * options.context_periods - 2))
    return replace(options, chunk_periods=wanted)


def check_sync_period(cap: Capture, periods: int = 40) -> float:
    """The sync must be a triangle at the modulation frequency: a flat or saturated
    channel, channels swapped (a beat in /adc/sync), or a period off `frequency_hz` by
    more than PERIOD_TOLERANCE, is refused. Returns the measured period over the one
    the attributes give (sample_rate_hz / frequency_hz): a ratio off 1 by more than
    PERIOD_WARN says one of them is wrong (times and velocities scale with the sample
    rate), which a track states (`sync_period_ratio`)."""
    info = cap.info
    hp = info.samples_per_period / 2
    a = max(0, info.samples // 2 - int(periods * hp))
    beat, sy = cap.read(a, min(info.samples, a + int(2 * periods * hp)))
    rough_sync, rough_beat = roughness(sy), roughness(beat)
    if rough_sync > SWAPPED_ROUGHNESS and rough_sync > 3 * rough_beat:
        raise CaptureError(info.path, f"the channels look swapped: /adc/sync changes from sample to sample "
                                      f"like a beat (roughness {rough_sync:.3f}) and /adc/beat is as smooth "
                                      f"as a sync triangle ({rough_beat:.3f}); import again with --order "
                                      "beat,sync (or swap the two datasets)")
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
    return measured / nominal


def roughness(codes: np.ndarray) -> float:
    """rms of the sample-to-sample steps over the rms of the centred ADC codes (integers,
    as a capture holds them): a sync triangle's is about 0.004, a beat's 0.1-1.4 (its
    tones, its noise). Exact integer sums: a fifth of float64 passes' time, which were 10
    ms of a capture's fixed cost."""
    if codes.size < 2:
        return 0.0
    n = codes.size
    x = codes.astype(np.int64)
    s1, s2 = int(x.sum()), int(np.dot(x, x))
    steps = np.diff(x)
    var = (n * s2 - s1 * s1) / (n * n)
    return float(np.sqrt(int(np.dot(steps, steps)) / (n - 1) / var)) if var > 0 else 0.0


def delay_reliable(plan: Plan) -> bool:
    """Whether the sync delay biases velocities by less than DELAY_BOUND_MPS (1 sigma):
    refined on the target and that certain, or, where no target run allowed it, a clean
    intensity triangle."""
    if plan.lag_refined:
        return bool(plan.lag_sigma_mps <= DELAY_BOUND_MPS)
    return bool(plan.lag_misfit <= delay.CLEAN_MISFIT)
