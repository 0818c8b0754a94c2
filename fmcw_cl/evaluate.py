"""Accuracy of a track against a capture's /truth (used by tests and benchmarks)."""

from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicSpline

from .capture import Truth
from .stages import faults
from .track import Track
from .uncertainty import crb_m, peak_eta


def truth_at(truth: Truth, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """True distance, velocity and acceleration at times t (cubic interpolation)."""
    return tuple(CubicSpline(truth.time_s, y)(t) for y in
                 (truth.distance_m, truth.velocity_mps, truth.acceleration_mps2))


def valid_errors(track: Track, truth: Truth) -> np.ndarray:
    """|distance - true distance| (m) of each valid pair."""
    r, _, _ = truth_at(truth, track.time_s[track.valid])
    return np.abs(track.distance_m[track.valid] - r)


def covered(track: Track, errors: np.ndarray) -> str:
    """The share (%) of valid pairs whose distance error (`valid_errors`) lies within
    their expanded uncertainty, as printed in a benchmark's row ("-" without pairs)."""
    if not errors.size or track.distance_uncertainty_m is None:
        return "-"
    return f"{100 * np.mean(errors <= track.distance_uncertainty_m[track.valid]):.1f}"


def invalid_reasons(track: Track) -> str:
    """The invalid pairs' count by reason ("no_echo 12, unstable 3"; empty when none)."""
    return ", ".join(f"{faults.REASONS[k]} {int(np.sum(track.reason == k))}"
                     for k in np.unique(track.reason) if k)


def accuracy(track: Track, truth: Truth) -> dict:
    """Error figures of the valid pairs (SI units).

    Returns valid share, distance bias/std/p95/max, velocity p95/max, acceleration
    p95/max (acceleration where defined).
    """
    v = track.valid
    r, vel, acc = truth_at(truth, track.time_s[v])
    ed = track.distance_m[v] - r
    ev = track.velocity_mps[v] - vel
    ea = track.acceleration_mps2[v] - acc
    ea = ea[np.isfinite(ea)]

    def p95(x):
        return float(np.percentile(np.abs(x), 95)) if x.size else float("nan")

    def mx(x):
        return float(np.max(np.abs(x))) if x.size else float("nan")

    return {
        "pairs": int(track.pairs),
        "valid_share": float(np.mean(v)) if track.pairs else 0.0,
        "distance_bias_m": float(np.mean(ed)) if ed.size else float("nan"),
        "distance_std_m": float(np.std(ed)) if ed.size else float("nan"),
        "distance_p95_m": p95(ed), "distance_max_m": mx(ed),
        "velocity_p95_mps": p95(ev), "velocity_max_mps": mx(ev),
        "acceleration_p95_mps2": p95(ea), "acceleration_max_mps2": mx(ea),
    }


def crb_pair_m(eta: float, points: int, bandwidth_hz: float, refractive_index: float = 1.0) -> float:
    """Cramer-Rao bound (m, standard deviation) of one pair's distance from the N resampled
    points of per-point SNR eta (`uncertainty.crb_m`): a pair averages two half-sweeps."""
    return float(crb_m(eta, points, bandwidth_hz, refractive_index) / np.sqrt(2))


def eta_from_peak_snr(snr_db, points: int) -> float:
    """Per-point SNR eta of the resampled half-sweeps from their peaks' median SNR (dB;
    `uncertainty.peak_eta`)."""
    return float(peak_eta(np.median(np.asarray(snr_db, float)), points))
