"""Stage 6f: the surveyed half-sweeps de-chirped at a bank of trial velocities.

A half-sweep resampled at uniform optical frequency carries a mover's Doppler term as a
chirp (the term is linear in time, the points are not): its plain peak loses 6.6 dB at
1 m/s and 9.6 dB at 2 m/s with the paper's DFB, and a mover faster than about 1 m/s
leaves no CFAR echo in the plain spectra. De-chirped at a trial velocity within 0.25 m/s
of its own it loses at most 1.3 dB, its peak moved by k (v - trial) (k: the Doppler
model's metres per m/s, opposite in the two directions). `TRIALS_MPS` covers 0.75-6.75
m/s each way, 0.5 m/s apart; the slower movers' plain peaks stay echoes (fmcw_cl.
moving_echoes). Each picked row is transformed once per trial velocity and its CFAR
echoes listed (stages.cfar): `detect` is the numpy twin of the device's launch of
kernels/fft.cl's spectrum_peak on the same picks (opencl.processor.bank_each).

At trial u a mover at v shows at d_r = R + k_r (v - u) rising and d_f = R + k_f (v - u)
falling: each rising echo with each falling echo of a pair at u solves for R and v
(doppler.solve_pair), a point where v lies within ACCEPT_MPS of u (further off, the echo
is smeared there and a nearer trial shows it sharper) and is MIN_MPS or faster (a still
wall solves to 0 m/s at every trial); of a pair's points within SAME_M (neighbouring
trials) the strongest stands (`points`). fmcw_cl.fast_echoes links them into bodies.
"""

from __future__ import annotations

import numpy as np

from .cfar import Detections
from .cfar import detect as cfar_detect
from .doppler import DopplerModel, power, solve_pair

STEP_MPS = 0.5
TRIALS_MPS = np.r_[-np.arange(0.75, 7.0, STEP_MPS)[::-1], np.arange(0.75, 7.0, STEP_MPS)]
BANK_STRIDE = 2            # every 2nd surveyed pair (echoes.SURVEY_STRIDE) goes through the bank
ACCEPT_MPS = 0.5 * STEP_MPS + 0.1   # a point's velocity this close to its trial's (the bank's step)
MIN_MPS = 0.5              # ... and this fast
SAME_M = 0.003             # a pair's points this close are one echo (adjacent trials), the strongest kept
POINT_KEYS = ("fast_time_s", "fast_distance_m", "fast_velocity_mps", "fast_snr_db")


def picks(rows: np.ndarray, trials: np.ndarray = TRIALS_MPS) -> tuple[np.ndarray, np.ndarray]:
    """Each of `rows` once per velocity of `trials` (m/s): the rows (int32) and their
    velocities (float32), row by row."""
    rows = np.asarray(rows)
    return (np.repeat(rows, trials.size).astype(np.int32),
            np.tile(np.asarray(trials, np.float32), rows.size))


def detect(x: np.ndarray, beta: np.ndarray, rows: np.ndarray, nfft: int, lo: int,
           trials: np.ndarray = TRIALS_MPS) -> Detections:
    """The CFAR echoes (from bin `lo`) of the rows `rows` of half-sweeps `x` de-chirped
    by the Doppler basis `beta` at each velocity of `trials` (m/s): one row of
    Detections per (row, trial), in `picks`' order."""
    idx, v = picks(rows, trials)
    return cfar_detect(power(x, beta, v.astype(np.float64), nfft, idx), lo)


def points(dets: tuple[Detections, Detections], t_rise: np.ndarray, t_fall: np.ndarray, model: DopplerModel,
           trials: np.ndarray = TRIALS_MPS) -> dict:
    """The bodies' points (POINT_KEYS: the pair's centre time s, distance m, velocity
    m/s, the weaker direction's CFAR SNR dB) of picked pairs whose half-sweeps' centres
    are `t_rise`, `t_fall` (s), from the bank's echoes `dets` (rising, falling; a row per
    pair and trial, stages.bank.picks' order)."""
    m = trials.size
    rise, fall = dets
    slot = np.arange(rise.bin.shape[1])
    keep = ((np.minimum(rise.count, slot.size)[:, None, None] > slot[None, :, None])
            & (np.minimum(fall.count, slot.size)[:, None, None] > slot[None, None, :]))
    row, a, b = np.nonzero(keep)                  # every rising echo with every falling one of a row
    pair, u = row // m, trials[row % m]
    d_r, d_f = rise.bin[row, a] * model.metres_per_bin, fall.bin[row, b] * model.metres_per_bin
    half_gap = 0.5 * (t_fall - t_rise)[pair]
    dist, v, _ = solve_pair(d_r, d_f, u, half_gap, model)
    snr = np.minimum(rise.snr_db[row, a], fall.snr_db[row, b])
    ok = (np.abs(v - u) <= ACCEPT_MPS) & (np.abs(v) >= MIN_MPS)
    pair, dist, v, snr = pair[ok], dist[ok], v[ok], snr[ok]
    order = np.lexsort((-snr, pair))
    pair, dist, v, snr = pair[order], dist[order], v[order], snr[order]
    kept = np.zeros(pair.size, bool)
    for p in np.unique(pair):
        at = np.flatnonzero(pair == p)
        for i in at:                                # strongest first
            if not np.any(kept[at] & (np.abs(dist[at] - dist[i]) <= SAME_M)):
                kept[i] = True
    t = 0.5 * (t_rise + t_fall)[pair[kept]]
    return dict(zip(POINT_KEYS, (t, dist[kept], v[kept], snr[kept].astype(np.float64)), strict=True))


def no_points() -> dict:
    """The points of a chunk that went through no bank."""
    return {k: np.zeros(0) for k in POINT_KEYS}
