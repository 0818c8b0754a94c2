"""Pairs -> track: the owned pairs of all chunks in capture order, missing periods
filled, validity verified, acceleration, and the attributes that say how the track was
made."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from . import __version__, displacement, echoes, target, uncertainty, wall_images
from .chunk_checks import SURVEY_KEYS
from .errors import CaptureError
from .plan import DELAY_BOUND_MPS, PERIOD_WARN, Plan, delay_reliable
from .processor import ChunkMeasurements, ChunkProcessor
from .refine import DISAGREE_SIGMAS, disagreement
from .stages import cfar, doppler, faults, kinematics, pairing, phase
from .stages.cfar import Detections
from .track import Track

EDGE_BINS = 1.0               # a half-sweep's peak this close (padded bins) to a band's edge: its slope
NEAR_LIMIT = 0.95             # distances beyond this share of the unambiguous range may be aliased


def _fill_gaps(t_mid: np.ndarray, period: float) -> np.ndarray:
    """Times of whole periods missing between consecutive pairs (dropped sync)."""
    gaps = np.diff(t_mid)
    fill = [t_mid[i] + period * np.arange(1, int(round(gaps[i] / period)))
            for i in np.flatnonzero(gaps > 1.5 * period)]
    return np.concatenate(fill) if fill else np.zeros(0)


def _spectrum(parts: list[ChunkMeasurements]) -> tuple[np.ndarray, int] | None:
    """The chunks' surveyed plain power summed per direction, and the half-sweeps of a
    direction summed (None: no chunk surveyed)."""
    got = [p for p in parts if p.spectrum is not None]
    return (sum(p.spectrum for p in got), sum(p.spectrum_rows for p in got)) if got else None


def _displacement(res: dict, with_gaps, times: tuple, dist: np.ndarray, vel: np.ndarray, ok: np.ndarray,
                  rad_per_m: float, dist_u: np.ndarray, moments: tuple[float, float], bias_mps: float,
                  curved: bool) -> displacement.Displacement:
    """The displacement from the half-sweeps' phases (none measured: not valid)."""
    if res.get("phasor_rise") is None:
        return displacement.Displacement.none(dist.size)
    t_r, t_f = (with_gaps(t, np.nan) for t in times)
    return displacement.displacement(t_r, t_f, with_gaps(res["phasor_rise"], np.nan),
                                     with_gaps(res["phasor_fall"], np.nan),
                                     with_gaps(res["dechirped_snr_rise"], np.nan),
                                     with_gaps(res["dechirped_snr_fall"], np.nan), dist, vel, ok, rad_per_m,
                                     dist_u, moments, bias_mps, curved)


def assemble(plan: Plan, parts: list[ChunkMeasurements], processor: ChunkProcessor, seconds: float,
             choice: target.Choice | None = None, seen: echoes.Echoes | None = None) -> Track:
    """The track from the owned pairs of all chunks, in capture order: missing periods
    filled as invalid, pairs on an echo the target cannot be told from (`choice`)
    ambiguous, validity verified (faults.verified, its tests by `processor`, whose name
    and device the track records), acceleration, attributes. `seconds`: the processing
    time; `seen`: the echo table of these `parts` where already made (a track of them
    assembled before), whatever the choice."""
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
        dechirped_at = res["velocity"] if options.dechirp else np.zeros(t_mid.size)
        imaged = wall_images.confused(dechirped_at, (res["dechirped_rise"], res["dechirped_fall"]),
                                      (res["dechirped_snr_rise"], res["dechirped_snr_fall"]), choice.walls_m,
                                      choice.walls_db, plan.model, plan.window, reason_owned == faults.OK)
        imaged |= at_band_edge((res["dechirped_rise"], res["dechirped_fall"]), plan, (t_r, t_f))
        snr = (res["dechirped_snr_rise"], res["dechirped_snr_fall"])
        sigma_v = uncertainty.velocity_crb(snr, options.points, plan.lut.bandwidth_hz, info.refractive_index,
                                           t_f - t_r + plan.model.k_fall - plan.model.k_rise)
        # the velocity bias the sync delay's uncertainty allows (unknown without a refined delay)
        bias_v = uncertainty.COVERAGE * plan.lag_sigma_mps if np.isfinite(plan.lag_sigma_mps) else np.inf
        reason_owned = target.ambiguous(reason_owned, t_mid, res["distance"], res["velocity"], choice, imaged,
                                        sigma_v, bias_v)
    if options.dechirp:         # the paper's method (--no-dechirp) is reported as the paper did
        reason_owned = faults.verified(t_mid, res["distance"], res["velocity"], reason_owned, processor,
                                       res["integrated"])
    res["valid"] = reason_owned == faults.OK
    valid = with_gaps(res["valid"], False)
    reason = with_gaps(reason_owned, faults.SYNC_GAP)
    dist = with_gaps(res["distance"], np.nan)
    vel = with_gaps(res["velocity"], np.nan)
    dist[~valid] = np.nan
    vel[~valid] = np.nan
    motion = plan.motion         # the windows the target's motion calls for (fmcw_cl.motion)
    held = kinematics.held_acceleration(vel, valid, period_s, motion.window, motion.hold)
    bias = np.zeros(dist.size)
    if options.dechirp:         # the paper's method (--no-dechirp) is reported as the paper did
        bias = doppler.acceleration_bias(held, with_gaps(0.5 * (t_f - t_r), 0.0), plan.model)
        dist -= bias
    integrated = with_gaps(res["integrated"], 0)
    varies = np.unique(integrated[valid]).size > 1
    # validity per quantity: the velocity verified against the distances' course, the
    # acceleration where its window lies whole on verified velocities
    lut = plan.lut
    crb = uncertainty.pair_crb((with_gaps(res["dechirped_snr_rise"], np.nan),
                                with_gaps(res["dechirped_snr_fall"], np.nan)),
                               options.points, lut.bandwidth_hz, info.refractive_index)
    weak = uncertainty.weakness(crb, valid)
    noise_m = uncertainty.local_scatter(dist, valid) * weak
    noise_mps = uncertainty.local_scatter(vel, valid) * weak
    vel_valid = uncertainty.velocity_verified(dist, vel, valid, period_s, noise_m, noise_mps, motion.slope)
    acc = kinematics.acceleration(vel, vel_valid, period_s, motion.window)
    acc_valid = kinematics.centred(vel_valid, motion.window)
    u_acc = uncertainty.acceleration_uncertainty(
        acc, acc_valid, noise_mps, period_s, motion.window, plan.period_ratio,
        uncertainty.derivative_scatter(vel, vel_valid, period_s, motion.window))
    # the distances' errors correlated over a few pairs too (an anti-correlated noise
    # reads higher on neighbours: the larger)
    noise_d = np.fmax(noise_m, uncertainty.correlated_scatter(dist, valid, held, period_s) * weak)
    # a delay refined on another echo passes that echo's errors on: these pairs' own mismatch
    moved_mps = (uncertainty.transferred_mps(times[order], dist, vel, valid, plan.lag_at_m)
                 if plan.lag_refined else 0.0)
    # the velocities' errors that wander over tens of pairs too (speckle decorrelating)
    noise_v = np.fmax(noise_mps, uncertainty.course_scatter(vel, vel_valid, motion.window) * weak)
    u = uncertainty.pair_uncertainty(
        dist, vel, valid, vel_valid, noise_d, noise_v, crb, held, bias, np.maximum(integrated, 1),
        period_s=period_s, scale_ppm=lut.scale_ppm, delay_m=plan.lag_sigma_m,
        delay_mps=float(np.hypot(uncertainty.finite_or_zero(plan.lag_sigma_mps), moved_mps)),
        period_ratio=plan.period_ratio, resolution_m=lut.range_resolution_m,
        # the beat's cycles per sample per metre: 2 n B / (c x the half-sweep's samples)
        cycles_per_sample_per_m=1.0 / (lut.range_resolution_m * 0.5 * info.samples_per_period))

    # the unverified velocities of valid pairs still predict the phase's steps
    rad_per_m = phase.radians_per_metre(lut.nu_hz, info.refractive_index)
    # the velocities share the sync delay's bias: as much as its expanded uncertainty allows
    moved = _displacement(res, with_gaps, (t_r, t_f), dist, vel, valid, rad_per_m, u.distance_m,
                          phase.centre_moments(lut.u_rise, 0.5 * period_s, plan.window),
                          uncertainty.COVERAGE * uncertainty.finite_or_zero(plan.lag_sigma_mps),
                          motion.curved)

    def interleave(rise, fall):
        return np.stack([res[rise], res[fall]], axis=1).ravel()

    sweep_t = np.stack([t_r, t_f], axis=1).ravel()
    sweep_rising = np.tile([True, False], t_r.size)
    if seen is None:
        seen = echoes.table(sweep_t, sweep_rising, interleave("dist_rise", "dist_fall"),
                            interleave("dechirped_snr_rise", "dechirped_snr_fall"),
                            Detections.interleave(res["echoes_rise"], res["echoes_fall"]),
                            plan.model.metres_per_bin,
                            np.inf if options.max_range is None else options.max_range,
                            {k: np.concatenate([p.survey[k] for p in parts]) for k in SURVEY_KEYS},
                            _spectrum(parts))
    attrs = {
        "points": options.points,
        "fft_length": plan.model.nfft,
        "window": "hann",
        "dechirp": bool(options.dechirp),
        "dechirp_iterations": options.iterations if options.dechirp else 0,
        "min_range_m": options.min_range,
        "max_range_m": float("nan") if options.max_range is None else options.max_range,
        "cfar": f"cell-averaging, guard {cfar.GUARD} and {cfar.TRAIN} training bins a side, "
                f"false-alarm probability {cfar.PFA:g} per cell",
        **seen.attrs(),
        **(choice.attrs() if choice is not None else {}),
        "target_tracked_m": np.percentile(dist[valid], [1, 99]) if valid.any() else np.full(2, np.nan),
        "bandwidth_hz": lut.bandwidth_hz,
        "tuning": plan.tuning,
        "range_resolution_m": lut.range_resolution_m,
        # the distance scale is as good as the bandwidth: its uncertainty from the G(I)
        # table's fit, or from the motion that scaled a chirp calibrated on the capture's
        # own rest (NaN with a given chirp calibration: as good as its distance)
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
        "sync_period_ratio": float(plan.period_ratio),
        "sync_period_warn": PERIOD_WARN,
        "sync_delay_samples": plan.lag,
        "sync_delay_periods_used": plan.lag_periods,
        "sync_delay_misfit": plan.lag_misfit,
        "sync_delay_reliable": delay_reliable(plan),
        "sync_delay_refined": bool(plan.lag_refined),
        "sync_delay_mismatch_mps": float(plan.lag_mismatch_mps),
        "sync_delay_intensity_samples": float(plan.lag_intensity),
        "sync_delay_intensity_uncertainty_samples": float(plan.lag_intensity_sigma),
        "sync_delay_disagreement_sigmas": float(disagreement(plan)),
        "sync_delay_uncertainty_samples": float(plan.lag_sigma_samples),
        "sync_delay_velocity_uncertainty_mps": float(plan.lag_sigma_mps),
        "sync_delay_distance_uncertainty_m": float(plan.lag_sigma_m),
        "sync_delay_refined_at_m": float(plan.lag_at_m),
        "sync_delay_velocity_bound_mps": DELAY_BOUND_MPS,
        "sync_delay_disagreement_limit": DISAGREE_SIGMAS,
        "chirp": str(Path(options.chirp).resolve()) if options.chirp else "",
        "acceleration_smoothing": f"Savitzky-Golay derivative, order {kinematics.POLYORDER}, "
                                  f"{motion.window} pairs",
        "velocity_check": uncertainty.check_said(motion.slope),
        "motion": motion.name,
        "velocity_unverified_pairs": int(np.sum(valid & ~vel_valid)),
        "uncertainty_coverage_factor": uncertainty.COVERAGE,
        **uncertainty.budget_attrs(u),
        **moved.attrs(),
        "displacement_rad_per_m": rad_per_m,
        "backend": processor.name,
        "device": processor.device,
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
        sweep_phase_rad=None if res.get("phasor_rise") is None else np.angle(interleave("phasor_rise",
                                                                                         "phasor_fall")),
        time_s=times[order], distance_m=dist, velocity_mps=vel, acceleration_mps2=acc,
        valid=valid, velocity_valid=vel_valid, acceleration_valid=acc_valid,
        distance_uncertainty_m=u.distance_m, velocity_uncertainty_mps=u.velocity_mps,
        acceleration_uncertainty_mps2=u_acc, displacement_m=moved.metres, displacement_valid=moved.valid,
        displacement_uncertainty_m=moved.uncertainty_m, displacement_stretch=moved.stretch,
        attrs=attrs, reason=reason, sweep_reason=np.repeat(reason_owned, 2),
        integrated=integrated if varies else None, period_s=period_s, chirp=plan.chirp)


def at_band_edge(peaks_m: tuple, plan: Plan, times: tuple) -> np.ndarray:
    """Which pairs have a half-sweep whose de-chirped peak (`peaks_m`: rising, falling;
    m) lies within EDGE_BINS of an edge of the pair's band (the plan's, or its own along
    the plan's course at its half-sweeps' `times`, s; not the spectrum's end): the
    band's strongest bin there may be the slope of an echo beyond the edge (a band cut
    beside a window held the slope of a pane's two surfaces at its first bin for 2.5 ms,
    the pairs 10-13 mm off the foot beneath it)."""
    mpb, half = plan.model.metres_per_bin, plan.model.nfft // 2
    search = plan.searched(pairing.Times(*times))
    out = np.zeros(np.size(peaks_m[0]), bool)
    for j, p in enumerate(peaks_m):
        lo, hi = search.band(j)
        top = np.where(np.asarray(hi) < half, (np.asarray(hi) - 1 - EDGE_BINS) * mpb, np.inf)
        out |= (p < (np.asarray(lo) + EDGE_BINS) * mpb) | (p > top)          # NaN: False
    return out
